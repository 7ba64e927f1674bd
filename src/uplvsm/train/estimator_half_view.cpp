#include "uplvsm/train/estimator_half_view.h"

namespace uplvsm::train {

torch::Tensor draw_seen_halves(int64_t count, int64_t H, int64_t W, const TrainingConfig& tc, int64_t step) {
  // Its own stream (the equivariance and turned-view terms draw from seed * 1000003 and seed * 7919 + 1e9 + 7).
  auto generator = at::detail::createCPUGenerator(static_cast<uint64_t>(tc.seed) * 104729u + 2000000011u +
                                                  static_cast<uint64_t>(step));
  auto right = torch::rand({count, 1, 1, 1}, generator, torch::kFloat32) < 0.5;
  auto in_right_half = (torch::arange(W, torch::kInt64) >= W / 2).view({1, 1, 1, W}).expand({count, 1, H, W});
  return (in_right_half == right).to(torch::kFloat32);
}

torch::Tensor masked_mse(const torch::Tensor& render, const torch::Tensor& target, const torch::Tensor& scored) {
  auto mask = scored.to(render.device(), torch::kFloat32);
  auto squared = (render.to(torch::kFloat32) - target.to(torch::kFloat32)).pow(2) * mask;
  return squared.sum() / mask.expand_as(squared).sum().clamp_min(1.0);
}

}  // namespace uplvsm::train
