#include "uplvsm/eval/target_pose_refinement.h"

namespace uplvsm::eval {

model::Rendered render_at_refined_poses(model::UPLVSMImpl& model, const model::Views& inputs,
                                        const model::Views& targets, const PoseRefinement& refinement) {
  TORCH_CHECK(refinement.steps >= 0 && refinement.lr > 0,
              "pose refinement: steps must be >= 0 and the learning rate > 0, got steps ", refinement.steps, ", lr ",
              refinement.lr);
  auto latents = model.encode_scene(inputs.images, inputs.fxfycxcy);
  auto poses = model.target_latent_poses(inputs, targets, latents, model::TargetPoses::Estimator);
  if (refinement.steps > 0) poses = refine_latent_poses(model, latents, poses, targets, refinement);
  auto render = model.render_views(latents, poses, targets.fxfycxcy, targets.images.size(3), targets.images.size(4));
  return {render, poses, latents};
}

}  // namespace uplvsm::eval
