// Internal to the fused kernels' autograd functions (qk_norm, layer_norm_to_bf16, flash_attention): a weight's
// gradient from per-block partial sums, added in block order, so that it does not depend on the thread count.
#pragma once
#include <torch/torch.h>

namespace uplvsm::kernels {

// Sums partial [blocks, D] (fp32, contiguous) over its blocks in order: [D].
inline torch::Tensor sum_blocks_in_order(const torch::Tensor& partial) {
  const int64_t blocks = partial.size(0), D = partial.size(1);
  auto sum = torch::zeros({D}, partial.options());
  const float* p = partial.data_ptr<float>();
  float* s = sum.data_ptr<float>();
  for (int64_t b = 0; b < blocks; ++b)
    for (int64_t j = 0; j < D; ++j) s[j] += p[b * D + j];
  return sum;
}

}  // namespace uplvsm::kernels
