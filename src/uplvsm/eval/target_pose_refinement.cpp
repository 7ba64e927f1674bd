#include "uplvsm/eval/target_pose_refinement.h"

namespace uplvsm::eval {

torch::Tensor per_view_mse(const torch::Tensor& render, const torch::Tensor& target) {
  TORCH_CHECK(render.sizes() == target.sizes() && render.dim() == 5,
              "per_view_mse: render and target must be the same [b, v, 3, H, W], got ", render.sizes(), " and ",
              target.sizes());
  return (render.to(torch::kFloat32) - target.to(torch::kFloat32)).pow(2).mean({2, 3, 4});
}

namespace {

// Adam on the poses alone: each view's error depends on its own pose only, so the summed error gives every pose
// its own gradient. torch::autograd::grad, not backward(), so the frozen weights collect no gradient.
torch::Tensor refine(model::UPLVSMImpl& model, const torch::Tensor& latents, const torch::Tensor& start,
                     const model::Views& targets, const PoseRefinement& refinement) {
  torch::AutoGradMode with_grad(true);
  const int64_t H = targets.images.size(3), W = targets.images.size(4);
  auto poses = start.detach().clone().set_requires_grad(true);
  torch::optim::Adam adam({poses}, torch::optim::AdamOptions(refinement.lr));
  for (int64_t step = 0; step < refinement.steps; ++step) {
    auto render = model.render_views(latents, poses, targets.fxfycxcy, H, W);
    auto loss = per_view_mse(render, targets.images).sum();
    poses.mutable_grad() = torch::autograd::grad({loss}, {poses})[0];
    adam.step();
  }
  return poses.detach();
}

}  // namespace

model::Rendered render_at_refined_poses(model::UPLVSMImpl& model, const model::Views& inputs,
                                        const model::Views& targets, const PoseRefinement& refinement) {
  TORCH_CHECK(refinement.steps >= 0 && refinement.lr > 0,
              "pose refinement: steps must be >= 0 and the learning rate > 0, got steps ", refinement.steps, ", lr ",
              refinement.lr);
  auto latents = model.encode(inputs);
  auto poses = model.target_latent_poses(inputs, targets, latents, model::TargetPoses::Estimator);
  if (refinement.steps > 0) poses = refine(model, latents.detach(), poses.to(torch::kFloat32), targets, refinement);
  auto render = model.render_views(latents, poses, targets.fxfycxcy, targets.images.size(3), targets.images.size(4));
  return {render, poses, latents};
}

}  // namespace uplvsm::eval
