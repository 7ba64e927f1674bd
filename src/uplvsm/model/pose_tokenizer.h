// Patch layouts and the Plücker-ray tokenizer. Patches are flattened channel-fastest, `(ph pw c)`, as the official
// Rearrange('b c (h ph) (w pw) -> b (h w) (ph pw c)'); the decoder head un-flattens `(p1 p2 c)` the same way.
#pragma once
#include <torch/torch.h>

#include "uplvsm/model/linear.h"

namespace uplvsm::model {

// [N, C, H, W] -> [N, (H/p)(W/p), p*p*C]
torch::Tensor patchify(const torch::Tensor& x, int64_t p);
// [N, h*w, p*p*C] -> [N, C, h*p, w*p]
torch::Tensor unpatchify(const torch::Tensor& tokens, int64_t p, int64_t height, int64_t width, int64_t channels);

// Linear(6 p^2 -> d, no bias) over Plücker patches. The Linear is child "1" because the official module is
// nn.Sequential(Rearrange, Linear): keys `target_pose_tokenizer.1.weight`, `canonical_pose_tokenizer.1.weight`.
struct PoseTokenizerImpl : torch::nn::Module {
  PoseTokenizerImpl(int64_t patch_size, int64_t d, int64_t channels = 6);
  // plucker [N, 6, H, W] -> tokens [N, n, d]
  torch::Tensor forward(const torch::Tensor& plucker);
  Linear linear{nullptr};
  int64_t patch_size;
};
TORCH_MODULE(PoseTokenizer);

}  // namespace uplvsm::model
