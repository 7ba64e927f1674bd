// The official optimiser recipe: AdamW with two parameter groups (every parameter with dim > 1 — matrices, but also
// cls/register tokens, pos_embed, the conv patch embed and the scene latents — gets weight decay; norms, biases and
// LayerScale gammas do not), linear warmup then cosine decay to zero, as transformers' get_cosine_schedule_with_warmup.
#pragma once
#include <torch/torch.h>

#include <memory>
#include <string>
#include <vector>

#include "uplvsm/core/config.h"

namespace uplvsm::train {

struct ParamGroups {
  std::vector<std::string> decay_names, no_decay_names;
  std::vector<torch::Tensor> decay, no_decay;
};
ParamGroups split_param_groups(const torch::nn::Module& module);

std::unique_ptr<torch::optim::AdamW> make_optimizer(const torch::nn::Module& module, const TrainingConfig& c);

// lr multiplier at scheduler step s: s / warmup during warmup, then 0.5 (1 + cos(pi * progress)).
double lr_lambda(int64_t step, int64_t warmup, int64_t total);
void set_learning_rate(torch::optim::Optimizer& opt, double lr);

}  // namespace uplvsm::train
