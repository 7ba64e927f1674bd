#include "uplvsm/train/masked_image_modeling.h"

#include <cmath>

#include "uplvsm/model/pose_tokenizer.h"

namespace uplvsm::train {

torch::Tensor random_patch_mask(int64_t images, int64_t patches, double ratio) {
  TORCH_CHECK(ratio > 0 && ratio < 1, "mask ratio must be in (0, 1), got ", ratio);
  const auto hidden = static_cast<int64_t>(std::lround(ratio * static_cast<double>(patches)));
  auto rank = std::get<1>(torch::rand({images, patches}).sort(1));  // a random permutation per image
  return rank < hidden;
}

torch::Tensor normalized_patches(const torch::Tensor& images01, int64_t patch_size) {
  // (row, column, channel) per patch, as the pose tokenizer flattens rays
  auto x = model::patchify(images01.to(torch::kFloat32), patch_size);
  auto mean = x.mean(-1, true);
  auto var = x.var(-1, /*unbiased=*/false, /*keepdim=*/true);
  return (x - mean) / (var + 1e-6).sqrt();
}

MaskedImageModelImpl::MaskedImageModelImpl(const ModelConfig& config) : patch_size(config.patch_size) {
  tokenizer = register_module("tokenizer", model::DinoTokenizer(config.dinov2, config.patch_size));
  const int64_t d = config.dinov2.embed_dim;
  mask_token = register_parameter("mask_token", torch::zeros({1, d}));
  head = register_module("head", torch::nn::Linear(d, patch_size * patch_size * 3));
  torch::NoGradGuard no_grad;
  torch::nn::init::normal_(mask_token, 0.0, 0.02);  // SimMIM / BEiT initialisation
  torch::nn::init::normal_(head->weight, 0.0, 0.02);
  torch::nn::init::zeros_(head->bias);
}

torch::Tensor MaskedImageModelImpl::predict(const torch::Tensor& images01, const torch::Tensor& mask) {
  return head(tokenizer->forward_masked(images01, mask, mask_token));
}

torch::Tensor MaskedImageModelImpl::forward(const torch::Tensor& images01, const torch::Tensor& mask) {
  auto error = (predict(images01, mask).to(torch::kFloat32) - normalized_patches(images01, patch_size)).pow(2).mean(-1);
  auto hidden = mask.to(error.dtype());
  return (error * hidden).sum() / hidden.sum().clamp_min(1);
}

}  // namespace uplvsm::train
