// Target-pose refinement, an evaluation protocol beside the paper's: the latent pose the estimator reads from each
// target is refined, the model frozen, by gradient descent on its render's photometric error against that target.
// Pose-free view-synthesis evaluations align their target cameras this way (NoPoSplat, Ye et al. 2025); here it
// separates what the decoder can draw from how well the estimator places the camera. Only the 7 numbers of each
// target's pose move, so the refined render cannot copy the target's content.
#pragma once
#include <torch/torch.h>

#include <cstdint>

#include "uplvsm/model/uplvsm.h"

namespace uplvsm::eval {

struct PoseRefinement {
  int64_t steps = 0;  // Adam steps per batch of targets; 0: the estimator's poses as they are (the paper's protocol)
  double lr = 1e-2;   // on the latent translation and the (unnormalised) quaternion alike
};

// The targets rendered at their refined latent poses. With steps 0 the same as
// model.render(inputs, targets, TargetPoses::Estimator). Runs under the caller's grad mode for the scene and the
// final render; the refinement itself computes gradients for the poses only.
model::Rendered render_at_refined_poses(model::UPLVSMImpl& model, const model::Views& inputs,
                                        const model::Views& targets, const PoseRefinement& refinement);

// Mean squared error of each render against its target [b, v] (what the refinement lowers, one pose per view).
torch::Tensor per_view_mse(const torch::Tensor& render, const torch::Tensor& target);

}  // namespace uplvsm::eval
