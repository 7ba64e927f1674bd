// Loading named tensors into a module: strict by default, with a precise report of missing, unexpected and
// mis-shaped keys (the official loader's strict=False hides such mistakes). Known extras — the VGG19 perceptual-loss
// tensors (`loss_computer.*`) that official checkpoints carry — are skipped explicitly and counted.
#pragma once
#include <torch/torch.h>

#include <map>
#include <string>
#include <vector>

namespace uplvsm::io {

using NamedTensors = std::map<std::string, torch::Tensor>;

struct LoadReport {
  std::vector<std::string> missing, unexpected, mismatched;  // mismatched: "key: file [..] vs model [..]"
  std::vector<std::string> skipped;                          // known extras deliberately ignored
  std::vector<std::string> defaulted;  // allowed to be absent from the file: left at their initial values
  int64_t loaded = 0;
  bool ok() const { return missing.empty() && unexpected.empty() && mismatched.empty(); }
  std::string summary(const std::string& source) const;
};

struct LoadOptions {
  bool strict = true;
  std::vector<std::string> skip_prefixes = {"loss_computer."};
  // Keys allowed to be absent from the file (left at their initial values), e.g. QK-norm weights that Meta's DINOv2
  // files lack. Matched as substrings.
  std::vector<std::string> allow_missing_substrings;
};

// Copies matching tensors (cast to the parameter dtype/device) into module's parameters and buffers.
// Throws std::runtime_error with report.summary(source) when strict and anything does not match.
LoadReport load_state_dict(torch::nn::Module& module, const NamedTensors& tensors, const std::string& source,
                           const LoadOptions& options = {});

// Parameters and buffers, detached, on CPU, in registration order names.
NamedTensors state_dict(const torch::nn::Module& module);

// Queries over a state dict's names: a key; some key starting with `prefix`; the depth of a stack, i.e. how many of
// "<prefix>0.", "<prefix>1.", ... have keys.
bool has_key(const NamedTensors& tensors, const std::string& key);
bool any_prefix(const NamedTensors& tensors, const std::string& prefix);
int64_t count_indexed(const NamedTensors& tensors, const std::string& prefix);

}  // namespace uplvsm::io
