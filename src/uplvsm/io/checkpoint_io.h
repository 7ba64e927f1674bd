// Our checkpoint format: one safetensors file holding the model tensors under their state_dict names, the optimiser
// state under "__optimizer__/<kind>/<name>", and in the header metadata the run config (JSON) and training state.
// Any safetensors reader can open it; `uplvsm` rebuilds the model from the embedded config.
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>
#include <string>

#include "uplvsm/core/config.h"
#include "uplvsm/io/state_dict.h"

namespace uplvsm::io {

inline constexpr const char* kOptimizerPrefix = "__optimizer__/";
inline constexpr const char* kCheckpointFormat = "uplvsm-checkpoint-v1";

struct CheckpointFile {
  std::string path;
  Config config;
  nlohmann::json state;    // training state (step, scheduler step, ...)
  NamedTensors model;      // state_dict tensors
  NamedTensors optimizer;  // "<kind>/<param name>" without the prefix
};

// A file, or a directory: a run dir (uses <dir>/checkpoints) or a checkpoints dir -> its lexicographically last
// ckpt_*.safetensors. Clear error when nothing is found.
std::string resolve_checkpoint(const std::string& path);

CheckpointFile read_checkpoint(const std::string& path);
void write_checkpoint(const std::string& path, const Config& config, const nlohmann::json& state,
                      const NamedTensors& model, const NamedTensors& optimizer);

}  // namespace uplvsm::io
