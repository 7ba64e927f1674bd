#include "uplvsm/geometry/plucker.h"

namespace uplvsm::geometry {

using torch::indexing::Ellipsis;
using torch::indexing::Slice;

std::pair<torch::Tensor, torch::Tensor> compute_rays(const torch::Tensor& c2w, const torch::Tensor& fxfycxcy,
                                                     int64_t height, int64_t width) {
  TORCH_CHECK(c2w.size(-1) == 4 && c2w.size(-2) == 4, "compute_rays: c2w must be [..., 4, 4], got ", c2w.sizes());
  TORCH_CHECK(fxfycxcy.size(-1) == 4, "compute_rays: intrinsics must be [..., 4], got ", fxfycxcy.sizes());
  auto batch = c2w.sizes().slice(0, c2w.dim() - 2).vec();
  auto cam = c2w.reshape({-1, 4, 4});
  // The camera-frame directions in fp32 (at least) whatever the cameras' dtype, as the official rays_from_c2w
  // (data_utils.py:46-54 at d490397): only the rotation below follows the cameras' precision. In bf16 the pixel
  // centres themselves would round (from 128 on, neighbouring columns share a ray).
  const auto dtype = torch::promote_types(fxfycxcy.scalar_type(), torch::kFloat32);
  auto k = fxfycxcy.reshape({-1, 4}).to(dtype);
  TORCH_CHECK(cam.size(0) == k.size(0), "compute_rays: ", cam.size(0), " cameras but ", k.size(0), " intrinsics");
  auto opts = k.options();
  auto xs = torch::arange(width, opts).add_(0.5);  // pixel centres
  auto ys = torch::arange(height, opts).add_(0.5);
  auto fx = k.select(1, 0).view({-1, 1, 1}), fy = k.select(1, 1).view({-1, 1, 1});
  auto cx = k.select(1, 2).view({-1, 1, 1}), cy = k.select(1, 3).view({-1, 1, 1});
  auto x = ((xs.view({1, 1, width}) - cx) / fx).expand({-1, height, width});
  auto y = ((ys.view({1, height, 1}) - cy) / fy).expand({-1, height, width});
  auto dirs_cam = torch::stack({x, y, torch::ones_like(x)}, 1).reshape({-1, 3, height * width});
  auto R = cam.index({Slice(), Slice(0, 3), Slice(0, 3)});
  // In the cameras' dtype (under bf16 autocast bmm rounds both to bf16 anyway); rays go back to the cameras' dtype
  // so o x d mixes no precisions.
  auto d32 = torch::bmm(R, dirs_cam.to(R.scalar_type())).to(torch::kFloat32);
  // |d| as a sum over the 3 channels: aten::norm over that strided dimension took 7-21 ms per call at 96x96.
  auto d = (d32 / d32.square().sum(1, true).sqrt().clamp_min(1e-3)).to(c2w.scalar_type());
  auto o = cam.index({Slice(), Slice(0, 3), Slice(3, 4)}).expand({-1, 3, height * width});
  auto shape = batch;
  shape.insert(shape.end(), {3, height, width});
  return {o.reshape(shape), d.reshape(shape)};
}

namespace {

// a x b over dimension `ch` (size 3), component by component: linalg_cross over a dimension that is not the innermost
// one, with broadcast origins, took ~50x longer (forward and backward) than these element-wise products.
torch::Tensor cross_over(const torch::Tensor& a, const torch::Tensor& b, int64_t ch) {
  auto a0 = a.narrow(ch, 0, 1), a1 = a.narrow(ch, 1, 1), a2 = a.narrow(ch, 2, 1);
  auto b0 = b.narrow(ch, 0, 1), b1 = b.narrow(ch, 1, 1), b2 = b.narrow(ch, 2, 1);
  return torch::cat({a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0}, ch);
}

}  // namespace

torch::Tensor plucker_rays(const torch::Tensor& c2w, const torch::Tensor& fxfycxcy, int64_t height, int64_t width) {
  auto [o, d] = compute_rays(c2w, fxfycxcy, height, width);
  int64_t ch = o.dim() - 3;
  return torch::cat({cross_over(o, d, ch), d}, ch);
}

}  // namespace uplvsm::geometry
