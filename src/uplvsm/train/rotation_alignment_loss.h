// training.rotation_alignment_weight's term (not in the paper): a direct geometric teacher for the latent camera's
// rotation. Input view 0 is the canonical camera, so warping it by a target's latent rotation (a homography with the
// known intrinsics; geometry/camera_rotation_warp.h) shows what a camera turned that way would see from view 0's
// position. Where the real camera mostly turned, that must look like the target: the squared difference over the
// pixels the warp keeps is the loss (parallax from the camera's move is ignored). No ground-truth camera is read.
#pragma once
#include <torch/torch.h>

#include "uplvsm/model/novel_view_model.h"

namespace uplvsm::train {

// inputs: the scene's input views (view 0 is read); targets: their images and intrinsics; pose_enc [b, v_t, 7] the
// targets' latent poses (only the rotation is used; the gradient flows into it). blur_sigma > 0: both images are
// blurred by a Gaussian of that sigma (pixels) first, which widens the range of turns the term can find (a sharp
// comparison sees only a pixel or two of shift).
torch::Tensor rotation_alignment_loss(const model::Views& inputs, const model::Views& targets,
                                      const torch::Tensor& pose_enc, double blur_sigma = 0);

// images [n, C, H, W] blurred by a separable Gaussian of `sigma` pixels (taps to 3 sigma, borders replicated).
torch::Tensor gaussian_blur(const torch::Tensor& images, double sigma);

}  // namespace uplvsm::train
