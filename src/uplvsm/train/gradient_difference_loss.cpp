#include "uplvsm/train/gradient_difference_loss.h"

namespace uplvsm::train {

namespace {

// |forward differences| along x and y of [..., C, H, W], flattened per image and concatenated.
torch::Tensor difference_magnitudes(const torch::Tensor& x) {
  const int64_t H = x.size(-2), W = x.size(-1);
  auto dx = (x.narrow(-1, 1, W - 1) - x.narrow(-1, 0, W - 1)).abs().flatten(-3);
  auto dy = (x.narrow(-2, 1, H - 1) - x.narrow(-2, 0, H - 1)).abs().flatten(-3);
  return torch::cat({dx, dy}, -1);
}

}  // namespace

torch::Tensor gradient_difference_loss(const torch::Tensor& pred, const torch::Tensor& target) {
  TORCH_CHECK(pred.sizes() == target.sizes() && pred.dim() >= 3,
              "gradient_difference_loss: expected pred and target of one shape [..., C, H, W], got ", pred.sizes(),
              " and ", target.sizes());
  TORCH_CHECK(pred.size(-2) >= 2 && pred.size(-1) >= 2, "gradient_difference_loss: images of ", pred.size(-2), "x",
              pred.size(-1), " have no pixel pairs along both axes");
  auto p = difference_magnitudes(pred.to(torch::kFloat32));
  auto t = difference_magnitudes(target.to(torch::kFloat32).detach());
  return (p - t).abs().mean();
}

}  // namespace uplvsm::train
