// Target-pose refinement, an evaluation protocol beside the paper's: the latent pose the estimator reads from each
// target is refined, the model frozen, by gradient descent on its render's photometric error against that target
// (eval/latent_pose_refinement). Pose-free view-synthesis evaluations align their target cameras this way (NoPoSplat,
// Ye et al. 2025); here it separates what the decoder can draw from how well the estimator places the camera.
#pragma once
#include <torch/torch.h>

#include "uplvsm/eval/latent_pose_refinement.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::eval {

// The targets rendered at their refined latent poses. With steps 0 the same as
// model.render(inputs, targets, TargetPoses::Estimator). Runs under the caller's grad mode for the scene and the
// final render; the refinement itself computes gradients for the poses only.
model::Rendered render_at_refined_poses(model::UPLVSMImpl& model, const model::Views& inputs,
                                        const model::Views& targets, const PoseRefinement& refinement);

}  // namespace uplvsm::eval
