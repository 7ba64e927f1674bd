#include "uplvsm/train/structural_dissimilarity_loss.h"

#include "uplvsm/core/ssim_window.h"

namespace uplvsm::train {

namespace {

constexpr int64_t kTaps = 2 * ssim::kRadius + 1;
using ssim::kC1;
using ssim::kC2;
using ssim::kCovNorm;

// The five local means SSIM needs (x, y, xx, yy, xy), each filtered by the separable window without padding.
torch::Tensor local_means(const torch::Tensor& x, const torch::Tensor& y) {
  auto taps = torch::tensor(ssim::window_values(), torch::kFloat64).to(x.options());
  namespace F = torch::nn::functional;
  auto stacked = torch::cat({x, y, x * x, y * y, x * y}, 1);  // [n, 5, H, W]
  auto rows =
      F::conv2d(stacked, taps.view({1, 1, 1, kTaps}).expand({5, 1, 1, kTaps}), F::Conv2dFuncOptions().groups(5));
  return F::conv2d(rows, taps.view({1, 1, kTaps, 1}).expand({5, 1, kTaps, 1}), F::Conv2dFuncOptions().groups(5));
}

}  // namespace

torch::Tensor structural_dissimilarity_loss(const torch::Tensor& pred, const torch::Tensor& target) {
  TORCH_CHECK(pred.sizes() == target.sizes() && pred.dim() >= 3,
              "structural_dissimilarity_loss: expected pred and target of one shape [..., C, H, W], got ", pred.sizes(),
              " and ", target.sizes());
  const int64_t H = pred.size(-2), W = pred.size(-1);
  TORCH_CHECK(H >= kTaps && W >= kTaps, "structural_dissimilarity_loss: images of ", H, "x", W,
              " are smaller than the 11x11 window");
  auto y = pred.to(torch::kFloat32).reshape({-1, 1, H, W});
  auto x = target.to(torch::kFloat32).reshape({-1, 1, H, W});
  auto m = local_means(x, y);
  auto ux = m.select(1, 0), uy = m.select(1, 1);
  auto vx = kCovNorm * (m.select(1, 2) - ux * ux), vy = kCovNorm * (m.select(1, 3) - uy * uy);
  auto vxy = kCovNorm * (m.select(1, 4) - ux * uy);
  auto s = ((2 * ux * uy + kC1) * (2 * vxy + kC2)) / ((ux * ux + uy * uy + kC1) * (vx + vy + kC2));
  return 1 - s.mean();
}

}  // namespace uplvsm::train
