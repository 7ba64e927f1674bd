#include "uplvsm/model/latent_plucker_learner.h"

#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::model {

LatentPluckerLearnerImpl::LatentPluckerLearnerImpl(const TransformerConfig& c) {
  // The official init uses std 0.02 for the whole estimator, whatever special_init and depth_init
  // (uplvsm.py `_init_estimator`: estimator.apply(init_weights)).
  transformer_estimator =
      register_module("transformer_estimator",
                      make_transformer_stack(c.d, c.d_head, c.qk_norm_eps, BlockInitStds(c.estimator_n_layer, 0.02)));
  absT_head = register_module("absT_head", DinoMlp(c.d, c.d / 2, 3));
  quaR_head = register_module("quaR_head", DinoMlp(c.d, c.d / 2, 4));
  init_linear_weights(*absT_head, 0.02);
  init_linear_weights(*quaR_head, 0.02);
  rotation_only = c.rotation_only_latent_camera;
}

torch::Tensor LatentPluckerLearnerImpl::pooled(const torch::Tensor& image_tokens, const torch::Tensor& scene_latents) {
  const int64_t n = image_tokens.size(1);
  auto tokens = run_stack(transformer_estimator, torch::cat({image_tokens, scene_latents}, 1), grad_checkpoint_every,
                          "uplvsm::estimator", OutputRows{0, n});
  return tokens.mean(1);
}

torch::Tensor LatentPluckerLearnerImpl::heads(const torch::Tensor& pooled) {
  auto t = rotation_only ? torch::zeros({pooled.size(0), 3}, pooled.options()) : absT_head(pooled);
  return torch::cat({t, geometry::normalize_quat(quaR_head(pooled), 1e-3)}, -1);
}

torch::Tensor LatentPluckerLearnerImpl::forward(const torch::Tensor& image_tokens, const torch::Tensor& scene_latents) {
  return heads(pooled(image_tokens, scene_latents));
}

}  // namespace uplvsm::model
