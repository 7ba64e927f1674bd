// Forward differences of images, one definition for the edge measure of the evaluation (eval::gradient_energy) and
// the gradient difference training loss (train/gradient_difference_loss.h), sibling layers that may not include
// each other.
#pragma once
#include <torch/torch.h>

namespace uplvsm {

// |x(i+1) - x(i)| along x, then along y, of [..., C, H, W] (H, W >= 2), flattened per image into
// [..., C H (W-1) + C (H-1) W], in x's dtype.
inline torch::Tensor absolute_forward_differences(const torch::Tensor& x) {
  const int64_t H = x.size(-2), W = x.size(-1);
  auto dx = (x.narrow(-1, 1, W - 1) - x.narrow(-1, 0, W - 1)).abs().flatten(-3);
  auto dy = (x.narrow(-2, 1, H - 1) - x.narrow(-2, 0, H - 1)).abs().flatten(-3);
  return torch::cat({dx, dy}, -1);
}

}  // namespace uplvsm
