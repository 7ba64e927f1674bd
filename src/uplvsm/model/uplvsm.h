// UP-LVSM (official `unposedLVSM`): unposed input views -> scene latents -> for each target view a latent pose from
// the Latent Plücker Learner -> Plücker rays with the target's intrinsics -> decoder -> RGB. Read top to bottom:
//   T  = DINOv2(inputs); T[view 0] += canonical_pose_tokenizer(Plücker of the identity camera)
//   S  = Encoder([latents ; T])[:L]                              scene latents
//   e  = Estimator(DINOv2(target), S)                            7-D latent pose per target
//   Q  = target_pose_tokenizer(Plücker(pose(e), intrinsics))
//   img = sigmoid(head(Decoder(LN([Q ; S]))[:n]))
// Where a target's pose comes from (estimator, a camera mapper, dataset cameras) is one seam, TargetPoses:
// `render_views` takes the 7-D poses, whoever supplies them.
// The same module holds the paper's posed baselines (model.variant), sharing the tokenizers and the RGB head:
//   ptlvsm (official `posedTargetLVSM`): T = DINOv2(inputs); T[view 0] += canonical_pose_tokenizer(Plücker of its
//          dataset camera); per target: img = head(Blocks(LN([T ; target_pose_tokenizer(Plücker)]))[last n])
//   lvsm:  the same with every input view's rays added to its tokens (inputs and targets posed).
// Their cameras are the official scene-normalised ones (official_scene_normalize over inputs and targets).
#pragma once
#include <torch/torch.h>

#include "uplvsm/core/config.h"
#include "uplvsm/model/dinov2.h"
#include "uplvsm/model/latent_plucker_learner.h"
#include "uplvsm/model/pose_mapper.h"
#include "uplvsm/model/pose_tokenizer.h"
#include "uplvsm/model/transformer.h"

namespace uplvsm::model {

// Intermediates of one forward, filled when a trace is passed (parity tests, analysis tools).
struct ForwardTrace {
  torch::Tensor input_dino_tokens;   // [b, v_in, n, d]
  torch::Tensor canonical_plucker;   // [b, v_in, 6, H, W] identity camera with the inputs' intrinsics
  torch::Tensor encoder_input;       // [b, L + v_in n, d] latents ; marked input tokens (analysis replays blocks)
  torch::Tensor encoder_output;      // [b, L + v_in n, d]
  torch::Tensor target_dino_tokens;  // [b, v_t, n, d]
  torch::Tensor estimator_pooled;    // [b, v_t, d]
  torch::Tensor target_plucker;      // [b, v_t, 6, H, W]
};

struct UPLVSMOutput {
  torch::Tensor render;    // [b, v_t, 3, H, W] in [0, 1]
  torch::Tensor pose_enc;  // [b, v_t, 7] latent poses (t, q_xyzw); undefined for the posed variants
};

// A set of views. c2w is needed only where a camera comes from the dataset; unposed photos leave it undefined.
struct Views {
  torch::Tensor images;    // [b, v, 3, H, W] in [0, 1]
  torch::Tensor fxfycxcy;  // [b, v, 4] pixels
  torch::Tensor c2w;       // [b, v, 4, 4] or undefined
};

// Where the target views' cameras come from.
enum class TargetPoses {
  Estimator,  // UP-LVSM: the Latent Plücker Learner reads the target image (the paper's protocol)
  Mapper,     // camera control: dataset cameras (camera_control_poses) through the linear pose mapper
  Dataset,    // dataset cameras directly: PT-LVSM and LVSM, and for UP-LVSM the "SfM target poses" ablation
};
// "estimator", "mapper", "dataset", or "auto" (the variant's own: estimator for uplvsm, dataset for the others).
TargetPoses parse_target_poses(const std::string& name, const ModelConfig& config);
std::string to_string(TargetPoses source);
// Whether training this model with these target poses (training.target_poses) reads the dataset's cameras.
bool reads_training_cameras(const ModelConfig& config, const std::string& target_poses);

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
  // Latent poses [b, v_t, 7] of the targets from `source` (Estimator: needs the target images; Mapper, Dataset:
  // needs c2w of inputs and targets).
  torch::Tensor target_latent_poses(const Views& inputs, const Views& targets, const torch::Tensor& scene_latents,
                                    TargetPoses source, ForwardTrace* trace = nullptr);
  // PT-LVSM / LVSM: renders the targets from posed inputs (both need c2w). The official scene normalisation runs
  // over inputs and targets; a video passes normalise_with_targets = false so every frame shares the inputs' frame.
  torch::Tensor render_posed(const Views& inputs, const Views& targets, ForwardTrace* trace = nullptr,
                             bool normalise_with_targets = true);
  // The training/evaluation forward of any variant; targets' images give the output size (and, for the estimator,
  // the image it reads).
  UPLVSMOutput forward(const Views& inputs, const Views& targets, TargetPoses source, ForwardTrace* trace = nullptr);
  // UP-LVSM's own protocol: the estimator sees the target images.
  UPLVSMOutput forward(const torch::Tensor& input_images, const torch::Tensor& input_fxfycxcy,
                       const torch::Tensor& target_images, const torch::Tensor& target_fxfycxcy,
                       ForwardTrace* trace = nullptr);
  bool posed_variant() const { return config.variant != "uplvsm"; }

  int64_t parameter_count() const;
  // Gradient checkpointing of the DINOv2 tokenizer, encoder, estimator and decoder stacks in groups of k blocks
  // (0: off).
  void set_grad_checkpoint_every(int64_t k);

  ModelConfig config;
  torch::Tensor n_light_field_latent;  // [L, d] learnable scene-latent queries
  DinoTokenizer tokenizer{nullptr};    // registered as image_tokenizer.1 (official key prefix)
  PoseTokenizer target_pose_tokenizer{nullptr}, canonical_pose_tokenizer{nullptr};
  torch::nn::ModuleList transformer_encoder{nullptr}, transformer_decoder{nullptr};
  LayerNorm transformer_input_layernorm_decoder{nullptr};
  LatentPluckerLearner estimator{nullptr};
  PoseMapper pose_mapper{nullptr};                  // registered when config.pose_mapper
  torch::nn::ModuleList transformer_blocks{nullptr};  // ptlvsm / lvsm only (official key names)
  LayerNorm transformer_input_layernorm{nullptr};
  torch::nn::Sequential image_token_decoder{nullptr};  // 0: LayerNorm (no bias), 1: Linear(d -> p^2 3)
  int64_t grad_checkpoint_every = 0;

 private:
  torch::Tensor repeat_per_view(const torch::Tensor& scene_latents, int64_t views);
  // Decoder outputs of the target tokens [b v, n, d] -> images [b, v, 3, H, W].
  torch::Tensor decode_rgb(const torch::Tensor& target_tokens, int64_t b, int64_t v, int64_t H, int64_t W);
};
TORCH_MODULE(UPLVSM);

}  // namespace uplvsm::model
