#include "uplvsm/render/trajectory.h"

#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::render {

namespace {
double fraction(int64_t i, int64_t n) { return n <= 1 ? 0.0 : static_cast<double>(i) / static_cast<double>(n - 1); }
}  // namespace

torch::Tensor interpolate_poses(const torch::Tensor& keys, int64_t n) {
  TORCH_CHECK(keys.dim() == 2 && keys.size(1) == 7 && keys.size(0) >= 2,
              "interpolate_poses: expected [K >= 2, 7] key poses, got ", keys.sizes());
  TORCH_CHECK(n >= 1, "interpolate_poses: frames per segment must be >= 1");
  auto k = keys.to(torch::kFloat64);
  std::vector<torch::Tensor> frames;
  for (int64_t s = 0; s + 1 < k.size(0); ++s) {
    auto t0 = k[s].slice(0, 0, 3), t1 = k[s + 1].slice(0, 0, 3);
    auto q0 = k[s].slice(0, 3, 7), q1 = k[s + 1].slice(0, 3, 7);
    q0 = q0 / q0.norm();
    q1 = q1 / q1.norm();
    for (int64_t i = 0; i < n; ++i) {
      double a = fraction(i, n);
      frames.push_back(torch::cat({t0 * (1 - a) + t1 * a, geometry::quat_slerp(q0, q1, a)}));
    }
  }
  return torch::stack(frames).to(keys.scalar_type());
}

torch::Tensor interpolate_intrinsics(const torch::Tensor& keys, int64_t n) {
  TORCH_CHECK(keys.dim() == 2 && keys.size(1) == 4 && keys.size(0) >= 2,
              "interpolate_intrinsics: expected [K >= 2, 4], got ", keys.sizes());
  std::vector<torch::Tensor> frames;
  for (int64_t s = 0; s + 1 < keys.size(0); ++s)
    for (int64_t i = 0; i < n; ++i) {
      double a = fraction(i, n);
      frames.push_back(keys[s] * (1 - a) + keys[s + 1] * a);
    }
  return torch::stack(frames);
}

}  // namespace uplvsm::render
