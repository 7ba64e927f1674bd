#include "uplvsm/train/turned_view_loss.h"

#include <cmath>

#include "uplvsm/geometry/camera_rotation_warp.h"
#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::train {

torch::Tensor draw_turn_angles(int64_t count, const TrainingConfig& tc, int64_t step) {
  const double max_radians = tc.turned_view_degrees * M_PI / 180.0;
  // Its own stream (the equivariance term's seed is seed * 1000003 + step), so the two terms draw different yaws.
  auto generator = at::detail::createCPUGenerator(static_cast<uint64_t>(tc.seed) * 7919u + 1000000007u +
                                                  static_cast<uint64_t>(step));
  return (torch::rand({count}, generator, torch::kFloat32) * 2 - 1) * max_radians;
}

torch::Tensor turned_view_loss(model::UPLVSMImpl& net, const model::Views& targets, const torch::Tensor& pose_enc,
                               const torch::Tensor& scene_latents, const torch::Tensor& yaws) {
  const auto& images = targets.images;
  const int64_t b = images.size(0), v = images.size(1), C = images.size(2), H = images.size(3), W = images.size(4);
  TORCH_CHECK(yaws.numel() == b * v, "turned_view_loss: expected ", b * v, " yaws, got ", yaws.numel());
  auto angles = yaws.to(images.device(), torch::kFloat32).reshape({b * v});
  auto k = targets.fxfycxcy.flatten(0, 1);
  auto turn = geometry::yaw_rotation(angles);
  auto flat = images.flatten(0, 1).to(torch::kFloat32);
  auto truth = geometry::warp_to_rotated_camera(flat, k, turn);
  auto valid = geometry::pixels_kept_by_rotation(k, H, W, turn);
  // c2w' = c2w [turn 0; 0 1]: the same centre, the rotation composed on the right (q' = q ⊗ q_turn).
  auto half = angles * 0.5;
  auto zero = torch::zeros_like(half);
  auto q_turn = torch::stack({zero, half.sin(), zero, half.cos()}, -1);
  auto enc = pose_enc.to(torch::kFloat32).flatten(0, 1);
  using torch::indexing::Slice;
  auto q = geometry::quat_multiply(enc.index({Slice(), Slice(3, 7)}), q_turn);
  auto turned_enc = torch::cat({enc.index({Slice(), Slice(0, 3)}), q}, -1).view({b, v, 7});
  auto render = net.render_views(scene_latents, turned_enc, targets.fxfycxcy, H, W).flatten(0, 1).to(torch::kFloat32);
  auto squared = (render - truth).pow(2) * valid;
  return squared.sum() / (valid.sum() * static_cast<double>(C)).clamp_min(1.0);
}

}  // namespace uplvsm::train
