// Weight files users bring, in any of their formats (official UP-LVSM .pt, Meta DINOv2 .pth, HuggingFace DINOv2
// safetensors, our own checkpoints), read and renamed to our module names. Our parameter names equal the official
// UP-LVSM state_dict names, so official checkpoints need no renaming; DINOv2 files map onto the image tokenizer's
// ViT. When a file does not carry our config, the model dimensions are inferred from the tensor shapes.
#pragma once
#include <torch/torch.h>

#include <string>

#include "uplvsm/core/config.h"
#include "uplvsm/model/state_dict.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::model {

enum class WeightSource { Uplvsm, Dinov2Meta, Dinov2HuggingFace };
std::string to_string(WeightSource source);

struct PretrainedWeights {
  std::string path;
  std::string container;  // "uplvsm checkpoint", "safetensors", "torch zip", "torch legacy"
  std::string found_at;   // where in the file the weights were ("model", "" for the top level)
  WeightSource source = WeightSource::Uplvsm;
  NamedTensors tensors;   // renamed: UP-LVSM names, or Meta DINOv2 names for DINOv2 sources
};

// The named tensors of a weight file as stored: safetensors (our checkpoints: the model part), or a torch.save file's
// state dict (io::read_torch_state_dict). `container` receives the format's name when given.
NamedTensors read_weight_file(const std::string& path, std::string* container = nullptr, std::string* found_at = nullptr);

// Reads a .safetensors / .pt / .pth file and brings its tensors to our names: strips a DDP "module." prefix, turns
// HuggingFace DINOv2 names into Meta's (query/key/value rows concatenated into qkv). Throws for files that are
// neither, naming the keys seen.
PretrainedWeights read_pretrained_weights(const std::string& path);

// HuggingFace Dinov2Model names -> Meta names. Unknown keys are an error listing them.
NamedTensors dinov2_from_huggingface(const NamedTensors& hf, const std::string& source);

// The UP-LVSM model dimensions implied by an official/our state_dict (variant: uplvsm, or ptlvsm for the official
// posedTargetLVSM layout unless `base` says lvsm; pose mapper; d, layer counts, latents, patch size, DINOv2
// width/depth/heads/registers/QK-norm/pos grid). Fields the shapes cannot tell (image_size, eps, interpolation
// mode) come from `base`. Throws naming the key when a required tensor is missing.
ModelConfig infer_model_config(const NamedTensors& weights, ModelConfig base);

// Loads Meta-named DINOv2 weights into a UP-LVSM model's image tokenizer (strict over the ViT): mask_token is
// dropped (the official model deletes it) and the QK-norm weights that Meta's files lack stay at ones — the report
// lists them so the user is told.
LoadReport load_dinov2_into_uplvsm(UPLVSMImpl& net, const NamedTensors& meta, const std::string& source);

// A ready UP-LVSM (eval mode, on `device`) from any weight file: our checkpoint (its embedded config), or an
// official UP-LVSM .pt/.pth/.safetensors — then the model section of `config_hint` when given (it must fit the
// weights; strict load), else the dimensions inferred from the shapes with the paper's other defaults. DINOv2-only
// files are refused with a pointer to `uplvsm convert --dinov2`. `config_out` receives the config used.
UPLVSM load_model(const std::string& path, const torch::Device& device, Config* config_out = nullptr,
                  const Config* config_hint = nullptr);

}  // namespace uplvsm::model
