#include "uplvsm/model/pose_mapper.h"

#include <stdexcept>

#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::model {

using torch::indexing::Slice;

std::string to_string(PoseMapperKind kind) { return kind == PoseMapperKind::Linear ? "linear" : "mlp"; }

PoseMapperKind parse_pose_mapper_kind(const std::string& name) {
  if (name == "linear") return PoseMapperKind::Linear;
  if (name == "mlp") return PoseMapperKind::Mlp;
  throw std::invalid_argument("pose mapper kind '" + name + "': expected linear or mlp");
}

PoseMapperImpl::PoseMapperImpl(PoseMapperOptions opt) : options(opt) {
  A = register_parameter("A", torch::eye(7));
  b = register_parameter("b", torch::zeros({7}));
  if (opt.kind != PoseMapperKind::Mlp) return;
  TORCH_CHECK(opt.hidden >= 1, "pose mapper: the MLP's width must be positive, got ", opt.hidden);
  auto out = torch::nn::Linear(opt.hidden, 7);
  mlp = register_module(
      "mlp", torch::nn::Sequential(torch::nn::Linear(7 + kSceneConditioningDims, opt.hidden), torch::nn::GELU(),
                                   torch::nn::Linear(opt.hidden, opt.hidden), torch::nn::GELU(), out));
  // The residual starts at zero: an MLP mapper begins as its linear fit.
  torch::NoGradGuard no_grad;
  out->weight.zero_();
  out->bias.zero_();
}

torch::Tensor PoseMapperImpl::forward(const torch::Tensor& real, const torch::Tensor& scene) {
  TORCH_CHECK(real.size(-1) == 7, "pose mapper: poses must be [..., 7] (t, q_xyzw), got ", real.sizes());
  auto x = real.to(A.scalar_type());
  auto latent = torch::matmul(x, A.t()) + b;
  if (mlp) {
    TORCH_CHECK(
        scene.defined() && scene.size(-1) == kSceneConditioningDims,
        "MLP pose mapper: needs the scene's conditioning [b, 14] (the estimator's latent poses of the input views)");
    auto s = scene.to(x.options());
    if (x.dim() == 3) s = s.unsqueeze(1).expand({x.size(0), x.size(1), kSceneConditioningDims});
    if (x.dim() == 2) s = s.reshape({-1, kSceneConditioningDims}).expand({x.size(0), kSceneConditioningDims});
    latent = latent + mlp->forward(torch::cat({x, s}, -1));
  }
  auto q = geometry::normalize_quat(latent.index({"...", Slice(3, 7)}), 1e-3);
  return torch::cat({latent.index({"...", Slice(0, 3)}), q}, -1);
}

torch::Tensor scene_conditioning(const torch::Tensor& input_latent_poses) {
  TORCH_CHECK(input_latent_poses.dim() == 3 && input_latent_poses.size(2) == 7 && input_latent_poses.size(1) >= 1,
              "scene_conditioning: expected the inputs' latent poses [b, vi, 7], got ", input_latent_poses.sizes());
  const int64_t second = input_latent_poses.size(1) > 1 ? 1 : 0;
  return torch::cat({input_latent_poses.select(1, 0), input_latent_poses.select(1, second)}, -1).to(torch::kFloat32);
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
