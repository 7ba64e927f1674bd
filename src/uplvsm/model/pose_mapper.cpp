#include "uplvsm/model/pose_mapper.h"

#include <cmath>
#include <stdexcept>
#include <vector>

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

namespace {

// Unconstrained parameters [..., 7] -> the pose (t / |t|, q / |q|): one baseline away, a unit quaternion.
torch::Tensor unit_pose(const torch::Tensor& x) {
  auto t = x.narrow(-1, 0, 3), q = x.narrow(-1, 3, 4);
  return torch::cat({t / t.norm(2, -1, true).clamp_min(1e-12), q / q.norm(2, -1, true).clamp_min(1e-12)}, -1);
}

// mapper(unit_pose(x)) - latent at x [7] float64 CPU, and its Jacobian [7, 7] (row i: d residual_i / dx) when asked.
struct Residual {
  torch::Tensor value, jacobian;
  double cost() const { return value.pow(2).sum().item<double>(); }
};
Residual residual_at(PoseMapperImpl& mapper, const torch::Tensor& x, const torch::Tensor& latent,
                     const torch::Tensor& scene, bool jacobian) {
  torch::AutoGradMode grad(jacobian);  // the viewer calls under NoGradGuard
  // Seven copies of x, one per output: the sum of the diagonal's gradient is the Jacobian, row by row.
  auto xs = x.to(mapper.A.device(), torch::kFloat32).unsqueeze(0).repeat({7, 1}).requires_grad_(jacobian);
  auto mapped = mapper.forward(unit_pose(xs), scene);  // [7, 7]
  Residual r;
  r.value = mapped[0].detach().to(torch::kCPU, torch::kFloat64) - latent;
  if (jacobian) r.jacobian = torch::autograd::grad({mapped.diagonal().sum()}, {xs})[0].to(torch::kCPU, torch::kFloat64);
  return r;
}

// Levenberg-Marquardt (Marquardt's scaling) from `x`: the end's normalised parameters and their cost.
std::pair<torch::Tensor, double> levenberg_marquardt(PoseMapperImpl& mapper, torch::Tensor x,
                                                     const torch::Tensor& latent, const torch::Tensor& scene) {
  auto r = residual_at(mapper, x, latent, scene, true);
  double cost = r.cost(), damping = 1e-3;
  for (int i = 0; i < 200 && damping < 1e10 && cost > 1e-20; ++i) {
    auto jtj = torch::matmul(r.jacobian.t(), r.jacobian);
    // The scales of t and q are free (unit_pose divides them out): the small constant keeps the system solvable.
    auto lhs = jtj + damping * torch::diag(jtj.diagonal() + 1e-9 * (jtj.trace().item<double>() + 1e-12));
    auto step = torch::linalg_solve(lhs, -torch::matmul(r.jacobian.t(), r.value));
    auto next = unit_pose(x + step);
    auto trial = residual_at(mapper, next, latent, scene, false);
    if (trial.cost() < cost) {
      const bool converged = cost - trial.cost() < 1e-12 * cost;
      x = next;
      r = residual_at(mapper, x, latent, scene, true);
      cost = r.cost();
      damping = std::max(damping / 3, 1e-12);
      if (converged) break;
    } else {
      damping *= 4;
    }
  }
  return {x, cost};  // every x held here is already normalised (unit_pose), so `cost` is the end's
}

// The mapper on the CPU: the solve runs a few hundred tiny forwards, each a kernel launch or more on a GPU.
PoseMapper cpu_copy(PoseMapperImpl& mapper) {
  PoseMapper copy(mapper.options);
  torch::NoGradGuard no_grad;
  const auto from = mapper.named_parameters(true);
  for (auto& p : copy->named_parameters(true)) p.value().copy_(from[p.key()]);
  return copy;
}

}  // namespace

MapperInverse invert_pose_mapper(PoseMapperImpl& mapper, const torch::Tensor& latent, const torch::Tensor& scene) {
  TORCH_CHECK(latent.numel() == 7, "invert_pose_mapper: expected one latent pose [7], got ", latent.sizes());
  TORCH_CHECK(!mapper.reads_scene() || (scene.defined() && scene.numel() == kSceneConditioningDims),
              "invert_pose_mapper: an MLP mapper needs the scene's conditioning [1, 14]");
  auto target = latent.reshape({7}).to(torch::kCPU, torch::kFloat64);
  auto s = mapper.reads_scene() ? scene.reshape({1, kSceneConditioningDims}) : torch::Tensor();
  torch::Tensor linear;
  {
    torch::NoGradGuard no_grad;
    auto A = mapper.A.detach().to(torch::kCPU, torch::kFloat64), b = mapper.b.detach().to(torch::kCPU, torch::kFloat64);
    // A singular linear part (a degenerate mapper file) has no linear inverse: the solve starts from the identity
    // rotation and the axis starts below instead of failing.
    auto [solution, info] = torch::linalg_solve_ex(A, target - b);
    linear = info.item<int64_t>() == 0 && torch::isfinite(solution).all().item<bool>() ? solution
                                                                                       : torch::zeros_like(target);
  }
  if (linear.narrow(0, 0, 3).norm().item<double>() < 1e-9) linear.narrow(0, 0, 3).fill_(1.0);
  if (linear.narrow(0, 3, 4).norm().item<double>() < 1e-9) linear[6].fill_(1.0);
  std::vector<torch::Tensor> starts = {linear};
  for (int64_t axis = 0; axis < 6; ++axis) {
    auto start = linear.clone();
    start.narrow(0, 0, 3).zero_();
    start[axis % 3].fill_(axis < 3 ? 1.0 : -1.0);
    starts.push_back(start);
  }
  const bool on_cpu = mapper.A.device().is_cpu();
  PoseMapper copy = on_cpu ? PoseMapper(nullptr) : cpu_copy(mapper);
  PoseMapperImpl& solver = on_cpu ? mapper : *copy;
  if (s.defined()) s = s.to(torch::kCPU);
  MapperInverse best;
  best.residual = INFINITY;
  for (const auto& start : starts) {
    auto [x, cost] = levenberg_marquardt(solver, unit_pose(start), target, s);
    const double rms = std::sqrt(cost / 7.0);
    if (rms < best.residual) best = {x, rms};
  }
  return best;
}

}  // namespace uplvsm::model
