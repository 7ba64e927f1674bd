#include "uplvsm/model/pose_mapper.h"

#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::model {

using torch::indexing::Slice;

torch::Tensor camera_control_poses(const torch::Tensor& input_c2w, const torch::Tensor& c2w) {
  TORCH_CHECK(input_c2w.dim() == 4 && input_c2w.size(-1) == 4 && input_c2w.size(-2) == 4 && c2w.dim() == 4 &&
                  c2w.size(-1) == 4 && c2w.size(-2) == 4 && input_c2w.size(0) == c2w.size(0),
              "camera_control_poses: expected input c2w [b, vi, 4, 4] and c2w [b, v, 4, 4], got ", input_c2w.sizes(),
              " and ", c2w.sizes());
  TORCH_CHECK(torch::isfinite(input_c2w).all().item<bool>() && torch::isfinite(c2w).all().item<bool>(),
              "camera_control_poses: camera matrices contain NaN or Inf");
  auto first_inv = torch::linalg_inv(input_c2w.select(1, 0).to(torch::kFloat64)).unsqueeze(1);  // [b, 1, 4, 4]
  auto rel = torch::matmul(first_inv, c2w.to(torch::kFloat64));
  auto scale = torch::ones({c2w.size(0), 1, 1}, rel.options());
  if (input_c2w.size(1) >= 2) {
    auto t = input_c2w.index({Slice(), Slice(0, 2), Slice(0, 3), 3}).to(torch::kFloat64);
    auto baseline = (t.select(1, 1) - t.select(1, 0)).norm(2, -1);  // [b]
    scale = torch::where(baseline > 1e-9, baseline, torch::ones_like(baseline)).view({-1, 1, 1});
  }
  auto enc = geometry::c2w_to_pose_encoding(rel);
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
  auto scale = torch::ones({c2w.size(0), 1, 1}, c2w.options());
  if (c2w.size(1) >= 2) {
    auto t = c2w.index({Slice(), Slice(0, 2), Slice(0, 3), 3});
    auto baseline = (t.select(1, 1) - t.select(1, 0)).norm(2, -1);  // [b]
    scale = torch::where(baseline > 1e-9, baseline, torch::ones_like(baseline)).view({-1, 1, 1});
  }
  p = torch::cat({p.index({"...", Slice(0, 3)}) * scale, p.index({"...", Slice(3, 7)})}, -1);
  return torch::matmul(c2w.select(1, 0).unsqueeze(1), geometry::pose_encoding_to_c2w(p)).to(torch::kFloat32);
}

PoseMapperImpl::PoseMapperImpl() {
  A = register_parameter("A", torch::eye(7));
  b = register_parameter("b", torch::zeros({7}));
}

torch::Tensor PoseMapperImpl::forward(const torch::Tensor& real) {
  TORCH_CHECK(real.size(-1) == 7, "pose mapper: poses must be [..., 7] (t, q_xyzw), got ", real.sizes());
  auto latent = torch::matmul(real.to(A.scalar_type()), A.t()) + b;
  auto q = geometry::normalize_quat(latent.index({"...", Slice(3, 7)}), 1e-3);
  return torch::cat({latent.index({"...", Slice(0, 3)}), q}, -1);
}

double fit_pose_mapper(PoseMapperImpl& mapper, const torch::Tensor& real, const torch::Tensor& latent, double ridge) {
  TORCH_CHECK(real.dim() == 2 && real.size(1) == 7 && latent.sizes() == real.sizes() && real.size(0) >= 1,
              "fit_pose_mapper: expected two [N, 7] tensors, got ", real.sizes(), " and ", latent.sizes());
  auto x = torch::cat({real.to(torch::kFloat64).cpu(), torch::ones({real.size(0), 1}, torch::kFloat64)}, 1);
  auto y = latent.to(torch::kFloat64).cpu();
  // Normal equations with a small ridge: (X^T X + λ I) W = X^T Y, λ relative to the mean diagonal.
  auto xtx = torch::matmul(x.t(), x);
  const double lambda = ridge * xtx.diagonal().mean().item<double>();
  auto w = torch::linalg_solve(xtx + lambda * torch::eye(8, torch::kFloat64), torch::matmul(x.t(), y));  // [8, 7]
  torch::NoGradGuard no_grad;
  mapper.A.copy_(w.index({Slice(0, 7)}).t().to(mapper.A.options()));
  mapper.b.copy_(w.index({7}).to(mapper.b.options()));
  auto residual = torch::matmul(x, w) - y;
  return std::sqrt(residual.pow(2).mean().item<double>());
}

}  // namespace uplvsm::model
