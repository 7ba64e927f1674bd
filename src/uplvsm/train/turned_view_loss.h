// training.turned_view_weight's term (not in the paper): a rendering signal for the latent camera's rotation. A pure
// turn of a camera is a homography, so each target is also known, exactly and without any ground-truth camera, as
// its camera turned in place by a random yaw (geometry/camera_rotation_warp.h). The decoder renders that turned view
// from the target's latent pose turned by the same yaw, and is scored on the pixels the warp keeps: a decoder that
// reads a turn of its rays as a turn of the image, so that turning is worth something to the estimator.
#pragma once
#include <torch/torch.h>

#include "uplvsm/core/config.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::train {

// `count` yaws [count] (radians, CPU fp32) uniform within ±training.turned_view_degrees, drawn from the seed and the
// step, so a resumed run draws the same.
torch::Tensor draw_turn_angles(int64_t count, const TrainingConfig& tc, int64_t step);

// The mean squared error of the turned renders over the valid pixels of the warped targets, target i of the flattened
// [b * v_t] turned by yaws[i]. `pose_enc` [b, v_t, 7] and `scene_latents` are what rendered the plain targets (the
// gradient flows through both).
torch::Tensor turned_view_loss(model::UPLVSMImpl& net, const model::Views& targets, const torch::Tensor& pose_enc,
                               const torch::Tensor& scene_latents, const torch::Tensor& yaws);

}  // namespace uplvsm::train
