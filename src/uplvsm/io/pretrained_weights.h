// Weight files users bring, in any of their formats (official UP-LVSM .pt, Meta DINOv2 .pth, HuggingFace DINOv2
// safetensors, our own checkpoints), read and renamed to our module names. Our parameter names equal the official
// UP-LVSM state_dict names, so official checkpoints need no renaming; DINOv2 files map onto the image tokenizer's
// ViT. Building a model from them (inferring its dimensions) and loading DINOv2 into its tokenizer is
// model/model_factory.h's.
#pragma once
#include <torch/torch.h>

#include <string>

#include "uplvsm/core/config.h"
#include "uplvsm/io/state_dict.h"

namespace uplvsm::io {

enum class WeightSource { Uplvsm, Dinov2Meta, Dinov2HuggingFace };
std::string to_string(WeightSource source);

struct PretrainedWeights {
  std::string path;
  std::string container;  // "uplvsm checkpoint", "safetensors", "torch zip", "torch legacy"
  std::string found_at;   // where in the file the weights were ("model", "" for the top level)
  WeightSource source = WeightSource::Uplvsm;
  NamedTensors tensors;  // renamed: UP-LVSM names, or Meta DINOv2 names for DINOv2 sources
};

// The named tensors of a weight file as stored: safetensors (our checkpoints: the model part), or a torch.save file's
// state dict (io::read_torch_state_dict). `container` receives the format's name when given.
NamedTensors read_weight_file(const std::string& path, std::string* container = nullptr,
                              std::string* found_at = nullptr);

// Reads a .safetensors / .pt / .pth file and brings its tensors to our names: strips a DDP "module." prefix, turns
// HuggingFace DINOv2 names into Meta's (query/key/value rows concatenated into qkv). Throws for files that are
// neither, naming the keys seen.
PretrainedWeights read_pretrained_weights(const std::string& path);

// HuggingFace Dinov2Model names -> Meta names. Unknown keys are an error listing them.
NamedTensors dinov2_from_huggingface(const NamedTensors& hf, const std::string& source);

}  // namespace uplvsm::io
