// Training checkpoints: model + AdamW state + training state in one safetensors file (io/checkpoint_io.h),
// written atomically as <run>/checkpoints/ckpt_<step:016>.safetensors, the oldest beyond `keep` deleted. No "best"
// checkpoint: the periodic evaluation scores the test split, and weights chosen on it would leak it into the result
// (the official keeps none either).
#pragma once
#include <torch/torch.h>

#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "uplvsm/core/config.h"
#include "uplvsm/io/checkpoint_io.h"

namespace uplvsm::train {

struct TrainState {
  int64_t step = 0;               // forward/backward passes done (the next step to run)
  int64_t scheduler_step = 0;     // drives the learning rate; not advanced on a non-finite loss
  int64_t param_update_step = 0;  // optimiser steps taken
  int64_t skipped_nonfinite = 0, skipped_gradnorm = 0;
  double train_seconds = 0;  // wall time spent training, over all resumes
  nlohmann::json to_json() const;
  static TrainState from_json(const nlohmann::json& j);
};

std::string checkpoint_name(int64_t step);

// The module's parameters that train (requires_grad), by name: what the optimiser state covers.
std::map<std::string, torch::Tensor> named_trainable_parameters(const torch::nn::Module& module);

// Optimiser state as named tensors "<kind>/<param name>" (kind: exp_avg, exp_avg_sq, step) and back.
io::NamedTensors optimizer_state(torch::optim::AdamW& opt, const torch::nn::Module& module);
void restore_optimizer_state(torch::optim::AdamW& opt, const torch::nn::Module& module, const io::NamedTensors& state,
                             const std::string& source);

// The ckpt_*.safetensors files of a checkpoint directory, oldest (lowest step) first; none when it does not exist.
std::vector<std::string> training_checkpoints(const std::string& checkpoint_dir);

// What `--resume auto` resumes from: the newest checkpoint that reads in full (every tensor, the embedded config and
// training state). Each newer one that does not (truncated by a full disk, a copy or a crash of the storage) is
// skipped with a warning naming it and why. None when the directory holds no checkpoint; an error when it holds
// some and none reads.
std::optional<io::CheckpointFile> read_newest_valid_checkpoint(const std::string& checkpoint_dir);

// Writes the checkpoint and prunes old ones; returns its path.
std::string save_training_checkpoint(const std::string& checkpoint_dir, const Config& config, const TrainState& state,
                                     torch::nn::Module& module, torch::optim::AdamW& opt, int64_t keep);

}  // namespace uplvsm::train
