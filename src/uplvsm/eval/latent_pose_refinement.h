// Refining latent poses against their targets: each target's 7-D latent pose is moved by Adam steps on its render's
// squared error against that target, the model's weights untouched. Used by evaluation (eval/target_pose_refinement,
// a protocol beside the paper's: `uplvsm eval --refine-poses`).
// Only the 7 numbers of each pose move, so a refined render cannot copy its target's content.
#pragma once
#include <torch/torch.h>

#include <cstdint>

#include "uplvsm/model/uplvsm.h"

namespace uplvsm::eval {

struct PoseRefinement {
  int64_t steps = 0;  // Adam steps per batch of targets; 0: the poses as they are
  double lr = 1e-2;   // on the latent translation and the (unnormalised) quaternion alike
};

// Mean squared error of each render against its target [b, v] (what the refinement lowers, one pose per view).
torch::Tensor per_view_mse(const torch::Tensor& render, const torch::Tensor& target);

// `start` [b, v_t, 7] refined for `targets` (their images and intrinsics) over `scene_latents`; returned detached, in
// fp32. Gradients are taken for the poses only (no weight collects one), under the caller's autocast.
torch::Tensor refine_latent_poses(model::UPLVSMImpl& model, const torch::Tensor& scene_latents,
                                  const torch::Tensor& start, const model::Views& targets,
                                  const PoseRefinement& refinement);

}  // namespace uplvsm::eval
