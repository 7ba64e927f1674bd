#include "uplvsm/geometry/camera_rotation_warp.h"

namespace uplvsm::geometry {

using torch::indexing::Slice;

torch::Tensor yaw_rotation(const torch::Tensor& radians) {
  auto c = radians.cos(), s = radians.sin(), zero = torch::zeros_like(radians), one = torch::ones_like(radians);
  return torch::stack({c, zero, s, zero, one, zero, -s, zero, c}, -1).view({-1, 3, 3});
}

torch::Tensor warp_to_rotated_camera(const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                                     const torch::Tensor& rotation) {
  TORCH_CHECK(images.dim() == 4 && fxfycxcy.dim() == 2 && fxfycxcy.size(1) == 4 && rotation.dim() == 3 &&
                  fxfycxcy.size(0) == images.size(0) && rotation.size(0) == images.size(0),
              "warp_to_rotated_camera: expected images [N, C, H, W], fxfycxcy [N, 4], rotation [N, 3, 3], got ",
              images.sizes(), ", ", fxfycxcy.sizes(), ", ", rotation.sizes());
  const int64_t N = images.size(0), H = images.size(2), W = images.size(3);
  auto opts = images.options().dtype(torch::kFloat32);
  auto k = fxfycxcy.to(opts).view({N, 1, 1, 4});
  auto ys = torch::arange(H, opts).add(0.5).view({1, H, 1}).expand({N, H, W});
  auto xs = torch::arange(W, opts).add(0.5).view({1, 1, W}).expand({N, H, W});
  // The output pixel's ray in the rotated camera, then in the original camera (R d'), projected back.
  auto ray = torch::stack(
      {(xs - k.select(-1, 2)) / k.select(-1, 0), (ys - k.select(-1, 3)) / k.select(-1, 1), torch::ones_like(xs)},
      -1);                                                                                         // [N, H, W, 3]
  auto d = torch::matmul(rotation.to(opts).view({N, 1, 1, 3, 3}), ray.unsqueeze(-1)).squeeze(-1);  // [N, H, W, 3]
  auto z = d.select(-1, 2);
  auto u = k.select(-1, 0) * d.select(-1, 0) / z + k.select(-1, 2);
  auto v = k.select(-1, 1) * d.select(-1, 1) / z + k.select(-1, 3);
  auto grid = torch::stack({u / W * 2 - 1, v / H * 2 - 1}, -1);
  grid = torch::where((z > 1e-6).unsqueeze(-1), grid, torch::full_like(grid, 2.0));  // behind: outside
  namespace F = torch::nn::functional;
  return F::grid_sample(
             images.to(torch::kFloat32), grid,
             F::GridSampleFuncOptions().mode(torch::kBilinear).padding_mode(torch::kZeros).align_corners(false))
      .to(images.scalar_type());
}

torch::Tensor pixels_kept_by_rotation(const torch::Tensor& fxfycxcy, int64_t height, int64_t width,
                                      const torch::Tensor& rotation) {
  auto ones = torch::ones({fxfycxcy.size(0), 1, height, width}, fxfycxcy.options().dtype(torch::kFloat32));
  return (warp_to_rotated_camera(ones, fxfycxcy, rotation) > 0.999).to(torch::kFloat32);
}

torch::Tensor yaw_safe_region(const torch::Tensor& fxfycxcy, int64_t height, int64_t width, double max_radians) {
  auto angle = torch::full({fxfycxcy.size(0)}, max_radians, fxfycxcy.options().dtype(torch::kFloat32));
  return pixels_kept_by_rotation(fxfycxcy, height, width, yaw_rotation(angle)) *
         pixels_kept_by_rotation(fxfycxcy, height, width, yaw_rotation(-angle));
}

}  // namespace uplvsm::geometry
