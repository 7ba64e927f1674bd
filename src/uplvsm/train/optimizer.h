// The official optimiser recipe: AdamW with two parameter groups (every parameter with dim > 1 — matrices, but also
// cls/register tokens, pos_embed, the conv patch embed and the scene latents — gets weight decay; norms, biases and
// LayerScale gammas do not), linear warmup then cosine decay to zero, as transformers' get_cosine_schedule_with_warmup.
#pragma once
#include <torch/torch.h>

#include <memory>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "uplvsm/core/config.h"

namespace uplvsm::train {

struct ParamGroups {
  std::vector<std::string> decay_names, no_decay_names;
  std::vector<torch::Tensor> decay, no_decay;
};
ParamGroups split_param_groups(const torch::nn::Module& module);

// The two AdamW parameter groups above with the config's learning rate, betas, eps and weight decay.
std::vector<torch::optim::OptimizerParamGroup> official_param_groups(const torch::nn::Module& module,
                                                                     const TrainingConfig& c);

// AdamW over `module`'s trainable parameters with its moments allocated now, next to the weights, as the zeros
// AdamW's first step would create: the same numbers, but the 2x-the-weights state no longer fills the heap's holes
// that the first step's activations leave, which raised the x224 training step's peak RSS by about 0.9 GiB.
std::unique_ptr<torch::optim::AdamW> make_optimizer(const torch::nn::Module& module, const TrainingConfig& c);

// One update of every parameter that has a gradient, the same arithmetic as LibTorch's AdamW::step (decoupled weight
// decay; m = b1 m + (1 - b1) g; v = b2 v + (1 - b2) g^2; p -= lr / (1 - b1^t) m / (sqrt(v) / sqrt(1 - b2^t) + eps)),
// each value rounded to fp32 where its nine tensor ops round it, but in one pass over a parameter's elements: at the
// demo size those ops are ~1000 small dispatches, ~5 % of a batch-8 step. Parameters that are not contiguous fp32
// CPU tensors (CUDA, another dtype), AMSGrad and CPUs without AVX-512 take LibTorch's own step.
void adamw_step(torch::optim::AdamW& optimizer);

// LibTorch keys optimiser state by the parameter's TensorImpl: a string in 1.x, a pointer in newer releases.
template <typename Map>
typename Map::key_type state_key(const Map&, const torch::Tensor& p) {
  if constexpr (std::is_same_v<typename Map::key_type, std::string>) {
    std::ostringstream key;  // what 1.x's c10::guts::to_string wrote (gone from 2.x)
    key << p.unsafeGetTensorImpl();
    return key.str();
  } else
    return static_cast<typename Map::key_type>(p.unsafeGetTensorImpl());
}

// lr multiplier at scheduler step s: s / warmup during warmup, then 0.5 (1 + cos(pi * progress)).
double lr_lambda(int64_t step, int64_t warmup, int64_t total);
void set_learning_rate(torch::optim::Optimizer& opt, double lr);

}  // namespace uplvsm::train
