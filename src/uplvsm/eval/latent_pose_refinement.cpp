#include "uplvsm/eval/latent_pose_refinement.h"

namespace uplvsm::eval {

torch::Tensor per_view_mse(const torch::Tensor& render, const torch::Tensor& target) {
  TORCH_CHECK(render.sizes() == target.sizes() && render.dim() == 5,
              "per_view_mse: render and target must be the same [b, v, 3, H, W], got ", render.sizes(), " and ",
              target.sizes());
  return (render.to(torch::kFloat32) - target.to(torch::kFloat32)).pow(2).mean({2, 3, 4});
}

// Each view's error depends on its own pose only, so the summed error gives every pose its own gradient.
// torch::autograd::grad, not backward(), so the frozen weights collect no gradient.
torch::Tensor refine_latent_poses(model::UPLVSMImpl& model, const torch::Tensor& scene_latents,
                                  const torch::Tensor& start, const model::Views& targets,
                                  const PoseRefinement& refinement) {
  TORCH_CHECK(refinement.steps >= 0 && refinement.lr > 0,
              "pose refinement: steps must be >= 0 and the learning rate > 0, got steps ", refinement.steps, ", lr ",
              refinement.lr);
  torch::AutoGradMode with_grad(true);
  const int64_t H = targets.images.size(3), W = targets.images.size(4);
  auto latents = scene_latents.detach();
  auto poses = start.detach().to(torch::kFloat32).clone().set_requires_grad(true);
  torch::optim::Adam adam({poses}, torch::optim::AdamOptions(refinement.lr));
  for (int64_t step = 0; step < refinement.steps; ++step) {
    auto render = model.render_views(latents, poses, targets.fxfycxcy, H, W);
    auto error = per_view_mse(render, targets.images);
    poses.mutable_grad() = torch::autograd::grad({error.sum()}, {poses})[0];
    adam.step();
  }
  return poses.detach();
}

}  // namespace uplvsm::eval
