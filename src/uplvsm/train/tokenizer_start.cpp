#include "uplvsm/train/tokenizer_start.h"

#include <stdexcept>

#include <fmt/format.h>

namespace uplvsm::train {

bool tokenizer_has_released_weights(const ModelConfig& m) {
  const auto& d = m.dinov2;
  return d.embed_dim == 768 && d.depth == 12 && d.num_heads == 12 && d.mlp_ratio == 4 && m.patch_size == 14;
}

namespace {
constexpr const char* kDinov2File = "dinov2_vitb14_reg4_pretrain.pth";
constexpr const char* kDinov2Source =
    "Meta's DINOv2 release, https://dl.fbaipublicfiles.com/dinov2/dinov2_vitb14/dinov2_vitb14_reg4_pretrain.pth";
}  // namespace

std::string describe_tokenizer_start(const Config& config, const std::string& init_weights, bool resuming) {
  if (resuming) return "the checkpoint it resumes";
  if (!init_weights.empty()) return fmt::format("--init {}", init_weights);
  if (!tokenizer_has_released_weights(config.model)) return "random (no released DINOv2 weights of this size)";
  if (config.training.random_tokenizer)
    return "random, by choice (training.random_tokenizer true; official: pretrained)";
  return fmt::format("MISSING: the run refuses to start (--init {})", kDinov2File);
}

void require_tokenizer_start(const Config& config, const std::string& init_weights, bool resuming) {
  if (resuming || !init_weights.empty() || config.training.random_tokenizer ||
      !tokenizer_has_released_weights(config.model))
    return;
  throw std::runtime_error(fmt::format(
      "config {}: its tokenizer is DINOv2 ViT-B/14, which the authors' code always starts from Meta's pretrained "
      "weights, and no --init was given. Give them with --init {} ({}), or train it from random weights, "
      "explicitly: --set training.random_tokenizer=true",
      config.name, kDinov2File, kDinov2Source));
}

}  // namespace uplvsm::train
