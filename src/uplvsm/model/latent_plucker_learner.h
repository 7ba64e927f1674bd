// The Latent Plücker Learner's estimator (official `ViTEstimator`): the target view's image tokens together with
// the scene latents go through a few transformer blocks; the image-token outputs are mean-pooled and two small MLP
// heads give a translation (3) and a quaternion (4, scalar-last, normalised in fp32): the 7-D latent pose (c2w in
// input view 0's frame).
// It never sees a ground-truth pose: the rendering loss is its only teacher.
#pragma once
#include <torch/torch.h>

#include "uplvsm/core/config.h"
#include "uplvsm/model/dinov2.h"
#include "uplvsm/model/transformer.h"

namespace uplvsm::model {

struct LatentPluckerLearnerImpl : torch::nn::Module {
  explicit LatentPluckerLearnerImpl(const TransformerConfig& c);
  // image_tokens [N, n, d], scene_latents [N, L, d] -> latent poses [N, 7] (t, q_xyzw).
  torch::Tensor forward(const torch::Tensor& image_tokens, const torch::Tensor& scene_latents);
  // The mean-pooled image-token features before the heads, [N, d] (for analysis and tests).
  torch::Tensor pooled(const torch::Tensor& image_tokens, const torch::Tensor& scene_latents);
  torch::Tensor heads(const torch::Tensor& pooled);

  torch::nn::ModuleList transformer_estimator{nullptr};
  DinoMlp absT_head{nullptr}, quaR_head{nullptr};
  int64_t grad_checkpoint_every = 0;  // see run_stack
  bool rotation_only = false;         // model.transformer.rotation_only_latent_camera
};
TORCH_MODULE(LatentPluckerLearner);

}  // namespace uplvsm::model
