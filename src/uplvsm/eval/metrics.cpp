#include "uplvsm/eval/metrics.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "uplvsm/core/image_gradients.h"
#include "uplvsm/core/ssim_window.h"

namespace uplvsm::eval {
namespace {

using ssim::kC1;
using ssim::kC2;
using ssim::kCovNorm;
using ssim::kRadius;

void check_pair(const torch::Tensor& pred, const torch::Tensor& gt, const char* what) {
  if (!pred.defined() || !gt.defined()) throw std::runtime_error(std::string(what) + ": undefined tensor");
  if (pred.sizes() != gt.sizes())
    throw std::runtime_error(std::string(what) + ": pred " + c10::str(pred.sizes()) + " and gt " +
                             c10::str(gt.sizes()) + " differ in shape");
  if (pred.dim() < 3)
    throw std::runtime_error(std::string(what) + ": expected [..., C, H, W], got " + c10::str(pred.sizes()));
  if (!pred.is_floating_point() || !gt.is_floating_point())
    throw std::runtime_error(std::string(what) + ": expected floating-point images");
}

// Indices of scipy's 'reflect' extension of 0..n-1 by `pad` on each side (period 2n, edge sample repeated).
torch::Tensor reflect_indices(int64_t n, int64_t pad, const torch::Device& device) {
  std::vector<int64_t> idx;
  idx.reserve(n + 2 * pad);
  for (int64_t i = -pad; i < n + pad; ++i) {
    int64_t m = ((i % (2 * n)) + 2 * n) % (2 * n);
    idx.push_back(m >= n ? 2 * n - 1 - m : m);
  }
  return torch::tensor(idx, torch::kInt64).to(device);
}

// One scipy correlate1d pass of the Gaussian along `dim` of a float64 tensor, summed in scipy's order for
// symmetric kernels (centre tap first, then the outermost pair inwards) so the float64 result matches it.
torch::Tensor filter1d(const torch::Tensor& x, int64_t dim, const std::vector<double>& w) {
  const int64_t n = x.size(dim);
  auto xp = x.index_select(dim, reflect_indices(n, kRadius, x.device()));
  auto out = xp.narrow(dim, kRadius, n) * w[kRadius];
  for (int64_t j = -kRadius; j < 0; ++j)
    out = out + (xp.narrow(dim, kRadius + j, n) + xp.narrow(dim, kRadius - j, n)) * w[kRadius + j];
  return out;
}

// skimage's gaussian(): axis 0 (rows) then axis 1 (columns); each pass accumulates in float64 and stores in the
// array's dtype, so float32 inputs are rounded to float32 between and after the passes.
torch::Tensor gaussian_filter(const torch::Tensor& x, const std::vector<double>& w) {
  const auto dtype = x.scalar_type();
  auto rows = filter1d(x.to(torch::kFloat64), -2, w).to(dtype);
  return filter1d(rows.to(torch::kFloat64), -1, w).to(dtype);
}

}  // namespace

torch::Tensor gaussian_window() { return torch::tensor(ssim::window_values(), torch::kFloat64); }

torch::Tensor reflect_pad2d(const torch::Tensor& x, int64_t pad) {
  if (x.dim() < 2) throw std::runtime_error("reflect_pad2d: expected [..., H, W], got " + c10::str(x.sizes()));
  auto rows = x.index_select(-2, reflect_indices(x.size(-2), pad, x.device()));
  return rows.index_select(-1, reflect_indices(x.size(-1), pad, x.device()));
}

torch::Tensor psnr(const torch::Tensor& pred, const torch::Tensor& gt) {
  check_pair(pred, gt, "psnr");
  // Clamp in the input precision (as the reference clips the float32 arrays), then go to float64.
  auto p = pred.clamp(0, 1).to(torch::kFloat64);
  auto g = gt.clamp(0, 1).to(torch::kFloat64);
  auto mse = (p - g).pow(2).mean({-3, -2, -1}).clamp_min(kMinMse);
  return -10.0 * torch::log10(mse);
}

torch::Tensor ssim(const torch::Tensor& pred, const torch::Tensor& gt) {
  check_pair(pred, gt, "ssim");
  const int64_t C = pred.size(-3), H = pred.size(-2), W = pred.size(-1);
  if (H < 2 * kRadius + 1 || W < 2 * kRadius + 1)
    throw std::runtime_error("ssim: images of " + std::to_string(H) + "x" + std::to_string(W) +
                             " are smaller than the 11x11 window");
  const auto cd = pred.scalar_type() == torch::kFloat64 ? torch::kFloat64 : torch::kFloat32;
  const auto w = ssim::window_values();
  // skimage's argument order is (gt, pred): x = gt, y = pred. SSIM is symmetric, but rounding follows the order.
  auto x = gt.to(cd).reshape({-1, H, W});
  auto y = pred.to(cd).reshape({-1, H, W});
  auto ux = gaussian_filter(x, w), uy = gaussian_filter(y, w);
  auto uxx = gaussian_filter(x * x, w), uyy = gaussian_filter(y * y, w), uxy = gaussian_filter(x * y, w);
  auto vx = kCovNorm * (uxx - ux * ux);
  auto vy = kCovNorm * (uyy - uy * uy);
  auto vxy = kCovNorm * (uxy - ux * uy);
  auto a1 = 2 * ux * uy + kC1, a2 = 2 * vxy + kC2;
  auto b1 = ux * ux + uy * uy + kC1, b2 = vx + vy + kC2;
  auto s = (a1 * a2) / (b1 * b2);
  auto cropped = s.narrow(-2, kRadius, H - 2 * kRadius).narrow(-1, kRadius, W - 2 * kRadius);
  // Per channel: mean in float64 (skimage's crop(S).mean(dtype=float64)); the per-channel values are then stored
  // in an array of the working dtype and averaged there.
  auto per_channel = cropped.to(torch::kFloat64).mean({-2, -1}).to(cd);
  auto shape = pred.sizes().vec();
  shape.resize(shape.size() - 2);
  shape.back() = C;
  return per_channel.reshape(shape).mean(-1).to(torch::kFloat64);
}

torch::Tensor gradient_energy(const torch::Tensor& x) {
  if (x.dim() < 3 || x.size(-1) < 2 || x.size(-2) < 2)
    throw std::runtime_error("gradient_energy: expected [..., C, H, W] with H, W >= 2, got " + c10::str(x.sizes()));
  return absolute_forward_differences(x.to(torch::kFloat64).clamp(0.0, 1.0)).mean(-1);
}

torch::Tensor gradient_energy_ratio(const torch::Tensor& pred, const torch::Tensor& gt) {
  check_pair(pred, gt, "gradient_energy_ratio");
  return gradient_energy(pred) / gradient_energy(gt).clamp_min(kMinGradientEnergy);
}

}  // namespace uplvsm::eval
