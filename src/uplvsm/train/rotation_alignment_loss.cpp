#include "uplvsm/train/rotation_alignment_loss.h"

#include "uplvsm/geometry/camera_rotation_warp.h"
#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::train {

torch::Tensor rotation_alignment_loss(const model::Views& inputs, const model::Views& targets,
                                      const torch::Tensor& pose_enc) {
  const auto& images = targets.images;
  const int64_t b = images.size(0), v = images.size(1), C = images.size(2), H = images.size(3), W = images.size(4);
  TORCH_CHECK(pose_enc.dim() == 3 && pose_enc.size(0) == b && pose_enc.size(1) == v && pose_enc.size(2) == 7,
              "rotation_alignment_loss: expected latent poses [", b, ", ", v, ", 7], got ", pose_enc.sizes());
  using torch::indexing::Slice;
  auto rotation = geometry::quat_to_rotation(pose_enc.to(torch::kFloat32).index({Slice(), Slice(), Slice(3, 7)}))
                      .flatten(0, 1);                                                          // [b v, 3, 3]
  auto view0 = inputs.images.select(1, 0).unsqueeze(1).expand({b, v, C, H, W}).flatten(0, 1);  // [b v, C, H, W]
  auto k0 = inputs.fxfycxcy.select(1, 0).unsqueeze(1).expand({b, v, 4}).flatten(0, 1);
  auto seen = geometry::warp_to_rotated_camera(view0.to(torch::kFloat32), k0, rotation);
  auto valid = geometry::pixels_kept_by_rotation(k0, H, W, rotation.detach());
  auto squared = (seen - images.flatten(0, 1).to(torch::kFloat32)).pow(2) * valid;
  return squared.sum() / (valid.sum() * static_cast<double>(C)).clamp_min(1.0);
}

}  // namespace uplvsm::train
