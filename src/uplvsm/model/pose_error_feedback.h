// Not in the paper (model.transformer.pose_error_feedback_steps): iterative error feedback (Carreira et al., CVPR
// 2016) for the latent camera. The estimator reads a target once and places its camera in one shot; the gap
// between that and a pose fitted to the target by gradient descent (`eval --refine-poses`) is its amortization gap.
// Here the render at the current pose is shown back to the estimator beside the target, with the pose's rays, and
// it reads a correction: what an optimizer would learn from the error, in one learned step. The render is evidence,
// not a path for gradients (it is made without them), so a step costs one decoder forward and one estimator pass.
#pragma once
#include <torch/torch.h>

#include "uplvsm/model/dinov2.h"
#include "uplvsm/model/pose_tokenizer.h"

namespace uplvsm::model {

struct PoseErrorFeedbackImpl : torch::nn::Module {
  PoseErrorFeedbackImpl(int64_t patch_size, int64_t d);
  // targets and renders [N, 3, H, W], the current pose's Plücker rays [N, 6, H, W] -> [N, n, d], added to the
  // target's image tokens: a patch embedding of (render, target - render, rays), patches row-major like the
  // tokenizer's.
  torch::Tensor embed(const torch::Tensor& targets, const torch::Tensor& renders, const torch::Tensor& rays);
  // poses [N, 7] (t, q_xyzw) and the estimator's pooled features of the fed-back target [N, d] -> corrected poses:
  // t + dt (t stays 0 for a rotation-only camera), q + dq renormalised. Its output layer starts at zero, so a model
  // starts as the one-shot estimator (and --init from one loads with this module at its initial values).
  torch::Tensor correct(const torch::Tensor& poses, const torch::Tensor& pooled, bool rotation_only);

  PoseTokenizer patch_embed{nullptr};  // the ray tokenizer's patch layout over 12 channels
  DinoMlp correction_head{nullptr};
};
TORCH_MODULE(PoseErrorFeedback);

}  // namespace uplvsm::model
