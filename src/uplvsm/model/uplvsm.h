// UP-LVSM (official `unposedLVSM`): unposed input views -> scene latents -> for each target view a latent pose from
// the Latent Plücker Learner -> Plücker rays with the target's intrinsics -> decoder -> RGB. Read top to bottom:
//   T  = DINOv2(inputs); T[view 0] += canonical_pose_tokenizer(Plücker of the identity camera)
//   S  = Encoder([latents ; T])[:L]                              scene latents
//   e  = Estimator(DINOv2(target), S)                            7-D latent pose per target
//   Q  = target_pose_tokenizer(Plücker(pose(e), intrinsics))
//   img = sigmoid(head(Decoder(LN([Q ; S]))[:n]))
// Where a target's pose comes from (estimator, a camera mapper, dataset cameras) is one seam: `render_views`
// takes the 7-D poses, whoever supplies them.
#pragma once
#include <torch/torch.h>

#include "uplvsm/core/config.h"
#include "uplvsm/model/dinov2.h"
#include "uplvsm/model/latent_plucker_learner.h"
#include "uplvsm/model/pose_tokenizer.h"
#include "uplvsm/model/transformer.h"

namespace uplvsm::model {

// Intermediates of one forward, filled when a trace is passed (parity tests, analysis tools).
struct ForwardTrace {
  torch::Tensor input_dino_tokens;   // [b, v_in, n, d]
  torch::Tensor canonical_plucker;   // [b, v_in, 6, H, W] identity camera with the inputs' intrinsics
  torch::Tensor encoder_output;      // [b, L + v_in n, d]
  torch::Tensor target_dino_tokens;  // [b, v_t, n, d]
  torch::Tensor estimator_pooled;    // [b, v_t, d]
  torch::Tensor target_plucker;      // [b, v_t, 6, H, W]
};

struct UPLVSMOutput {
  torch::Tensor render;    // [b, v_t, 3, H, W] in [0, 1]
  torch::Tensor pose_enc;  // [b, v_t, 7] latent poses (t, q_xyzw)
};

struct UPLVSMImpl : torch::nn::Module {
  explicit UPLVSMImpl(const ModelConfig& config);

  // images [b, v, 3, H, W] in [0, 1] -> DINOv2 tokens [b, v, n, d]
  torch::Tensor tokenize(const torch::Tensor& images);
  // Scene latents [b, L, d] from unposed input views and their intrinsics (pixels) [b, v_in, 4].
  torch::Tensor encode_scene(const torch::Tensor& input_images, const torch::Tensor& input_fxfycxcy,
                             ForwardTrace* trace = nullptr);
  // Latent poses [b, v_t, 7] of target images given the scene latents (the Latent Plücker Learner).
  torch::Tensor estimate_poses(const torch::Tensor& target_images, const torch::Tensor& scene_latents,
                               ForwardTrace* trace = nullptr);
  // Renders [b, v_t, 3, H, W] from latent poses [b, v_t, 7] and target intrinsics [b, v_t, 4].
  torch::Tensor render_views(const torch::Tensor& scene_latents, const torch::Tensor& pose_enc,
                             const torch::Tensor& target_fxfycxcy, int64_t height, int64_t width,
                             ForwardTrace* trace = nullptr);
  // The training/evaluation forward: the estimator sees the target images (the paper's protocol).
  UPLVSMOutput forward(const torch::Tensor& input_images, const torch::Tensor& input_fxfycxcy,
                       const torch::Tensor& target_images, const torch::Tensor& target_fxfycxcy,
                       ForwardTrace* trace = nullptr);

  int64_t parameter_count() const;

  ModelConfig config;
  torch::Tensor n_light_field_latent;  // [L, d] learnable scene-latent queries
  DinoTokenizer tokenizer{nullptr};    // registered as image_tokenizer.1 (official key prefix)
  PoseTokenizer target_pose_tokenizer{nullptr}, canonical_pose_tokenizer{nullptr};
  torch::nn::ModuleList transformer_encoder{nullptr}, transformer_decoder{nullptr};
  LayerNorm transformer_input_layernorm_decoder{nullptr};
  LatentPluckerLearner estimator{nullptr};
  torch::nn::Sequential image_token_decoder{nullptr};  // 0: LayerNorm (no bias), 1: Linear(d -> p^2 3)

 private:
  torch::Tensor repeat_per_view(const torch::Tensor& scene_latents, int64_t views);
};
TORCH_MODULE(UPLVSM);

}  // namespace uplvsm::model
