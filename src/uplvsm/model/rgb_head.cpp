#include "uplvsm/model/rgb_head.h"

#include "uplvsm/model/pose_tokenizer.h"

namespace uplvsm::model {

RgbHeadImpl::RgbHeadImpl(int64_t d, int64_t p) : patch_size(p) {
  norm = register_module("0", LayerNorm(d, 1e-5, false));
  linear = register_module("1", Linear(torch::nn::LinearOptions(d, p * p * 3).bias(false)));
}

torch::Tensor RgbHeadImpl::forward(const torch::Tensor& tokens, int64_t b, int64_t v, int64_t H, int64_t W) {
  auto rgb = torch::sigmoid(linear(norm->forward_into_linear(tokens)));
  return unpatchify(rgb, patch_size, H, W, 3).view({b, v, 3, H, W});
}

}  // namespace uplvsm::model
