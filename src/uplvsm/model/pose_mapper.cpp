#include "uplvsm/model/pose_mapper.h"

#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::model {

using torch::indexing::Slice;

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
