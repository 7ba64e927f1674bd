#include "uplvsm/model/pose_tokenizer.h"

namespace uplvsm::model {

torch::Tensor patchify(const torch::Tensor& x, int64_t p) {
  const int64_t N = x.size(0), C = x.size(1), H = x.size(2), W = x.size(3);
  TORCH_CHECK(H % p == 0 && W % p == 0, "patchify: ", H, "x", W, " is not a multiple of patch ", p);
  return x.reshape({N, C, H / p, p, W / p, p}).permute({0, 2, 4, 3, 5, 1}).reshape({N, (H / p) * (W / p), p * p * C});
}

torch::Tensor unpatchify(const torch::Tensor& t, int64_t p, int64_t H, int64_t W, int64_t C) {
  const int64_t N = t.size(0);
  return t.reshape({N, H / p, W / p, p, p, C}).permute({0, 5, 1, 3, 2, 4}).reshape({N, C, H, W});
}

PoseTokenizerImpl::PoseTokenizerImpl(int64_t p, int64_t d, int64_t channels) : patch_size(p) {
  linear = register_module("1", Linear(torch::nn::LinearOptions(channels * p * p, d).bias(false)));
}

torch::Tensor PoseTokenizerImpl::forward(const torch::Tensor& plucker) { return linear(patchify(plucker, patch_size)); }

}  // namespace uplvsm::model
