#include "uplvsm/train/rotation_alignment_loss.h"

#include <cmath>

#include "uplvsm/geometry/camera_rotation_warp.h"
#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::train {

torch::Tensor gaussian_blur(const torch::Tensor& images, double sigma) {
  TORCH_CHECK(images.dim() == 4, "gaussian_blur: expected images [n, C, H, W], got ", images.sizes());
  TORCH_CHECK(sigma > 0, "gaussian_blur: sigma must be > 0, got ", sigma);
  const int64_t C = images.size(1), radius = static_cast<int64_t>(std::ceil(3 * sigma));
  auto x = torch::arange(-radius, radius + 1, images.options().dtype(torch::kFloat64));
  auto taps = (-(x * x) / (2 * sigma * sigma)).exp();
  taps = (taps / taps.sum()).to(images.scalar_type());
  namespace F = torch::nn::functional;
  auto padded = F::pad(images, F::PadFuncOptions({radius, radius, radius, radius}).mode(torch::kReplicate));
  auto rows =
      F::conv2d(padded, taps.view({1, 1, 1, -1}).expand({C, 1, 1, 2 * radius + 1}), F::Conv2dFuncOptions().groups(C));
  return F::conv2d(rows, taps.view({1, 1, -1, 1}).expand({C, 1, 2 * radius + 1, 1}), F::Conv2dFuncOptions().groups(C));
}

torch::Tensor rotation_alignment_loss(const model::Views& inputs, const model::Views& targets,
                                      const torch::Tensor& pose_enc, double blur_sigma) {
  const auto& images = targets.images;
  const int64_t b = images.size(0), v = images.size(1), C = images.size(2), H = images.size(3), W = images.size(4);
  TORCH_CHECK(pose_enc.dim() == 3 && pose_enc.size(0) == b && pose_enc.size(1) == v && pose_enc.size(2) == 7,
              "rotation_alignment_loss: expected latent poses [", b, ", ", v, ", 7], got ", pose_enc.sizes());
  using torch::indexing::Slice;
  auto rotation = geometry::quat_to_rotation(pose_enc.to(torch::kFloat32).index({Slice(), Slice(), Slice(3, 7)}))
                      .flatten(0, 1);  // [b v, 3, 3]
  auto view0 = inputs.images.select(1, 0).to(torch::kFloat32), target = images.flatten(0, 1).to(torch::kFloat32);
  if (blur_sigma > 0) view0 = gaussian_blur(view0, blur_sigma), target = gaussian_blur(target, blur_sigma);
  auto source = view0.unsqueeze(1).expand({b, v, C, H, W}).flatten(0, 1);  // [b v, C, H, W]
  auto k0 = inputs.fxfycxcy.select(1, 0).unsqueeze(1).expand({b, v, 4}).flatten(0, 1);
  auto seen = geometry::warp_to_rotated_camera(source, k0, rotation);
  auto valid = geometry::pixels_kept_by_rotation(k0, H, W, rotation.detach());
  auto squared = (seen - target).pow(2) * valid;
  return squared.sum() / (valid.sum() * static_cast<double>(C)).clamp_min(1.0);
}

}  // namespace uplvsm::train
