#include "uplvsm/geometry/camera_control.h"

#include "uplvsm/geometry/camera.h"

namespace uplvsm::geometry {

using torch::indexing::Slice;

namespace {

// [b, 1, 1]: the distance between input views 0 and 1 of `input_c2w` [b, vi, 4, 4] (1 with one input view, or when
// the two coincide).
torch::Tensor baseline_scale(const torch::Tensor& input_c2w) {
  if (input_c2w.size(1) < 2) return torch::ones({input_c2w.size(0), 1, 1}, input_c2w.options());
  auto t = input_c2w.index({Slice(), Slice(0, 2), Slice(0, 3), 3});
  auto baseline = (t.select(1, 1) - t.select(1, 0)).norm(2, -1);  // [b]
  return torch::where(baseline > 1e-9, baseline, torch::ones_like(baseline)).view({-1, 1, 1});
}

}  // namespace

torch::Tensor camera_control_poses(const torch::Tensor& input_c2w, const torch::Tensor& c2w) {
  TORCH_CHECK(input_c2w.dim() == 4 && input_c2w.size(-1) == 4 && input_c2w.size(-2) == 4 && c2w.dim() == 4 &&
                  c2w.size(-1) == 4 && c2w.size(-2) == 4 && input_c2w.size(0) == c2w.size(0),
              "camera_control_poses: expected input c2w [b, vi, 4, 4] and c2w [b, v, 4, 4], got ", input_c2w.sizes(),
              " and ", c2w.sizes());
  TORCH_CHECK(torch::isfinite(input_c2w).all().item<bool>() && torch::isfinite(c2w).all().item<bool>(),
              "camera_control_poses: camera matrices contain NaN or Inf");
  auto first_inv = torch::linalg_inv(input_c2w.select(1, 0).to(torch::kFloat64)).unsqueeze(1);  // [b, 1, 4, 4]
  auto rel = torch::matmul(first_inv, c2w.to(torch::kFloat64));
  const auto scale = baseline_scale(input_c2w.to(torch::kFloat64));
  auto enc = c2w_to_pose_encoding(rel);
  enc = torch::cat({enc.index({"...", Slice(0, 3)}) / scale, enc.index({"...", Slice(3, 7)})}, -1);
  return enc.to(torch::kFloat32);
}

torch::Tensor camera_control_to_world(const torch::Tensor& input_c2w, const torch::Tensor& poses) {
  TORCH_CHECK(input_c2w.dim() == 4 && input_c2w.size(-1) == 4 && input_c2w.size(-2) == 4 && poses.dim() == 3 &&
                  poses.size(2) == 7 && poses.size(0) == input_c2w.size(0),
              "camera_control_to_world: expected input c2w [b, vi, 4, 4] and poses [b, v, 7], got ", input_c2w.sizes(),
              " and ", poses.sizes());
  auto c2w = input_c2w.to(torch::kFloat64);
  auto p = poses.to(c2w.device(), torch::kFloat64);
  const auto scale = baseline_scale(c2w);
  p = torch::cat({p.index({"...", Slice(0, 3)}) * scale, p.index({"...", Slice(3, 7)})}, -1);
  return torch::matmul(c2w.select(1, 0).unsqueeze(1), pose_encoding_to_c2w(p)).to(torch::kFloat32);
}

}  // namespace uplvsm::geometry
