// Masked image modelling for the image tokenizer (SimMIM, Xie et al. 2022): our own stand-in for the pretrained
// DINOv2 the paper starts from, trained on the same unlabelled images. The patch embeddings of a random subset of
// patches are replaced by a learned mask token (DINOv2's own masking), the tokenizer runs over every patch, and a
// linear head predicts the hidden patches' pixels, each patch normalised by its own mean and variance (MAE's
// norm_pix_loss). It reads images only: no camera, no pose, no weights of another model.
#pragma once
#include <torch/torch.h>

#include "uplvsm/core/config.h"
#include "uplvsm/model/dinov2.h"

namespace uplvsm::train {

// Exactly round(ratio * n) hidden patches per image, chosen uniformly: bool [N, n].
torch::Tensor random_patch_mask(int64_t images, int64_t patches, double ratio);

struct MaskedImageModelImpl : torch::nn::Module {
  // The tokenizer of `config` (its DINOv2 settings, patch size), a mask token and the pixel head.
  explicit MaskedImageModelImpl(const ModelConfig& config);
  // Predicted patches [N, n, p*p*3] (in per-patch normalised units) for images in [0, 1] with `mask` hidden.
  torch::Tensor predict(const torch::Tensor& images01, const torch::Tensor& mask);
  // Mean squared error over the hidden patches against their normalised pixels.
  torch::Tensor forward(const torch::Tensor& images01, const torch::Tensor& mask);

  model::DinoTokenizer tokenizer{nullptr};
  torch::Tensor mask_token;  // [1, D], Meta's name and shape
  torch::nn::Linear head{nullptr};
  int64_t patch_size;
};
TORCH_MODULE(MaskedImageModel);

// The patches' own normalisation, the regression target: (x - mean) / sqrt(var + 1e-6) over each patch's values.
torch::Tensor normalized_patches(const torch::Tensor& images01, int64_t patch_size);

}  // namespace uplvsm::train
