#include "uplvsm/model/latent_plucker_learner.h"

#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::model {

LatentPluckerLearnerImpl::LatentPluckerLearnerImpl(const TransformerConfig& c) {
  // The official init uses std 0.02 for the whole estimator (no depth scaling).
  transformer_estimator = register_module(
      "transformer_estimator", make_transformer_stack(c.estimator_n_layer, c.d, c.d_head, c.qk_norm_eps, false));
  absT_head = register_module("absT_head", DinoMlp(c.d, c.d / 2, 3));
  quaR_head = register_module("quaR_head", DinoMlp(c.d, c.d / 2, 4));
  init_linear_weights(*absT_head, 0.02);
  init_linear_weights(*quaR_head, 0.02);
  if (c.estimator_correspondence) {
    correspondence = register_module("correspondence", CorrespondenceReadout(c.d, c.d_head));
    n_latents = c.n_latent_vectors;
  }
  rotation_only = c.rotation_only_latent_camera;
  rotation_gain = c.latent_rotation_gain;
  pivot_depth = c.latent_pivot_depth;
  if (c.identity_rotation_init) {
    torch::NoGradGuard no_grad;
    quaR_head->fc2->bias.copy_(torch::tensor({0.0f, 0.0f, 0.0f, 1.0f}));  // q_xyzw = identity
  }
}

torch::Tensor LatentPluckerLearnerImpl::pooled(const torch::Tensor& image_tokens, const torch::Tensor& scene_latents) {
  const int64_t n = image_tokens.size(1);
  auto tokens = run_stack(transformer_estimator, torch::cat({image_tokens, scene_latents}, 1), grad_checkpoint_every,
                          "uplvsm::estimator", OutputRows{0, n});
  if (!correspondence) return tokens.mean(1);
  TORCH_CHECK(scene_latents.size(1) >= n_latents + n, "estimator_correspondence: the scene representation has ",
              scene_latents.size(1), " rows, not the ", n_latents, " latents and input view 0's ", n,
              " image tokens (model.keep_image_tokens)");
  return tokens.mean(1) + correspondence(tokens, scene_latents.narrow(1, n_latents, n));
}

torch::Tensor LatentPluckerLearnerImpl::heads(const torch::Tensor& pooled) {
  auto t = rotation_only              ? torch::zeros({pooled.size(0), 3}, pooled.options())
           : translation_scale == 1.0 ? absT_head(pooled)
                                      : absT_head(pooled) * translation_scale;
  auto q_raw = quaR_head(pooled);
  if (rotation_gain != 1.0) q_raw = torch::cat({q_raw.narrow(-1, 0, 3) * rotation_gain, q_raw.narrow(-1, 3, 1)}, -1);
  auto q = geometry::normalize_quat(q_raw, 1e-3);
  if (pivot_depth != 0.0) t = t + geometry::pivot_translation(q, pivot_depth);
  return torch::cat({t, q}, -1);
}

torch::Tensor LatentPluckerLearnerImpl::forward(const torch::Tensor& image_tokens, const torch::Tensor& scene_latents) {
  return heads(pooled(image_tokens, scene_latents));
}

}  // namespace uplvsm::model
