// Builds the model family from a config or a checkpoint; the one place that reads model.variant:
//   uplvsm -> UPLVSM;  ptlvsm -> PosedLVSM, input view 0 posed;  lvsm -> PosedLVSM, every input view posed.
// Everything above the model layer holds the NovelViewModel it returns (novel_view_model.h).
#pragma once
#include <torch/torch.h>

#include <string>

#include "uplvsm/core/config.h"
#include "uplvsm/io/state_dict.h"
#include "uplvsm/model/novel_view_model.h"

namespace uplvsm::model {

// A freshly initialised model of config.variant (its random initial weights come from the current seed).
NovelViewModel make_model(const ModelConfig& config);

// The model config implied by an official/our state_dict: the official posedTargetLVSM layout (decoder-only keys
// `transformer_blocks.*`) is ptlvsm unless `base` says lvsm (the keys cannot tell them apart), else uplvsm with or
// without a pose mapper; d, layer counts, latents, patch size, DINOv2 width/depth/heads/registers/QK-norm/pos grid.
// Fields the shapes cannot tell (image_size, eps, interpolation mode) come from `base`. Throws naming the key when
// a required tensor is missing.
ModelConfig infer_model_config(const io::NamedTensors& weights, ModelConfig base);

// A ready model (eval mode, on `device`) from any weight file: our checkpoint (its embedded config), or an official
// UP-LVSM / PT-LVSM .pt/.pth/.safetensors — then the model section of `config_hint` when given (it must fit the
// weights; strict load), else the dimensions inferred from the shapes with the paper's other defaults. DINOv2-only
// files are refused with a pointer to `uplvsm convert`. `config_out` receives the config used.
NovelViewModel load_model(const std::string& path, const torch::Device& device, Config* config_out = nullptr,
                          const Config* config_hint = nullptr);
// The same with the hint read from a config JSON file (the CLI's --config; empty: no hint).
NovelViewModel load_model_with_config_file(const std::string& path, const std::string& config_hint_path,
                                           const torch::Device& device, Config* config_out = nullptr);

// Loads Meta-named DINOv2 weights (io/pretrained_weights.h) into a model's image tokenizer (strict over the ViT):
// mask_token is dropped (the official model deletes it) and the QK-norm weights that Meta's files lack stay at ones —
// the report lists them so the user is told.
io::LoadReport load_dinov2_into_tokenizer(NovelViewModelImpl& net, const io::NamedTensors& meta,
                                          const std::string& source);

}  // namespace uplvsm::model
