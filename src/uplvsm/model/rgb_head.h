// The RGB head shared by the model family (official `image_token_decoder`): each target token through LayerNorm (no
// bias) and Linear(d -> p^2 3, no bias), a sigmoid, and its patch put back in the image (`(p1 p2 c)`, as
// unpatchify). Children "0" and "1" keep the official nn.Sequential key names.
#pragma once
#include <torch/torch.h>

#include "uplvsm/model/transformer.h"

namespace uplvsm::model {

struct RgbHeadImpl : torch::nn::Module {
  RgbHeadImpl(int64_t d, int64_t patch_size);
  // target tokens [b v, n, d] -> images [b, v, 3, H, W] in [0, 1]
  torch::Tensor forward(const torch::Tensor& tokens, int64_t b, int64_t v, int64_t height, int64_t width);
  LayerNorm norm{nullptr};  // "0"
  Linear linear{nullptr};   // "1"
  int64_t patch_size;
};
TORCH_MODULE(RgbHead);

}  // namespace uplvsm::model
