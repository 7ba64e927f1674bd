#include "uplvsm/model/pose_error_feedback.h"

#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::model {

PoseErrorFeedbackImpl::PoseErrorFeedbackImpl(int64_t p, int64_t d) {
  patch_embed = register_module("patch_embed", PoseTokenizer(p, d, 12));
  correction_head = register_module("correction_head", DinoMlp(d, d / 2, 7));
  torch::NoGradGuard no_grad;
  patch_embed->linear->weight.normal_(0.0, 0.02);
  correction_head->fc1->weight.normal_(0.0, 0.02);
  correction_head->fc1->bias.zero_();
  correction_head->fc2->weight.zero_();
  correction_head->fc2->bias.zero_();
}

torch::Tensor PoseErrorFeedbackImpl::embed(const torch::Tensor& targets, const torch::Tensor& renders,
                                           const torch::Tensor& rays) {
  TORCH_CHECK(targets.dim() == 4 && targets.sizes() == renders.sizes() && rays.dim() == 4 && rays.size(1) == 6,
              "pose error feedback: targets and renders must be [N, 3, H, W] and rays [N, 6, H, W], got ",
              targets.sizes(), ", ", renders.sizes(), ", ", rays.sizes());
  const auto dtype = patch_embed->linear->weight.scalar_type();
  return patch_embed(torch::cat({renders.to(dtype), (targets - renders).to(dtype), rays.to(dtype)}, 1));
}

torch::Tensor PoseErrorFeedbackImpl::correct(const torch::Tensor& poses, const torch::Tensor& pooled,
                                             bool rotation_only) {
  auto delta = correction_head(pooled).to(torch::kFloat32);
  auto p = poses.to(torch::kFloat32);
  auto t = rotation_only ? p.narrow(-1, 0, 3) : p.narrow(-1, 0, 3) + delta.narrow(-1, 0, 3);
  auto q = geometry::normalize_quat(p.narrow(-1, 3, 4) + delta.narrow(-1, 3, 4), 1e-3);
  return torch::cat({t, q}, -1);
}

}  // namespace uplvsm::model
