// UP-LVSM (official `unposedLVSM`): unposed input views -> scene latents -> for each target view a latent pose from
// the Latent Plücker Learner -> Plücker rays with the target's intrinsics -> decoder -> RGB. Read top to bottom:
//   T  = DINOv2(inputs); T[view 0] += canonical_pose_tokenizer(Plücker of the identity camera)
//   S  = Encoder([latents ; T])[:L]                              scene latents
//        (model.encoder_latent_cameras, not official: T[view i>0] += tokenizer(Plücker(pose(Estimator(T_i, S))))
//        and S = Encoder([latents ; T])[:L] again: the inputs' latent cameras in the encoder, as RayZer)
//   e  = Estimator(DINOv2(target), S)                            7-D latent pose per target
//   Q  = target_pose_tokenizer(Plücker(pose(e), intrinsics))
//   img = sigmoid(head(Decoder(LN([Q ; S]))[:n]))
// Where a target's pose comes from (estimator, a camera mapper, dataset cameras) is one seam, TargetPoses:
// `render_views` takes the 7-D poses, whoever supplies them. Scene latents, latent poses and the mapper exist only
// here, so the code that needs them takes this type (require_uplvsm), not the family's interface.
#pragma once
#include <torch/torch.h>

#include "uplvsm/model/latent_plucker_learner.h"
#include "uplvsm/model/novel_view_model.h"
#include "uplvsm/model/pose_mapper.h"
#include "uplvsm/model/transformer.h"

namespace uplvsm::model {

struct UPLVSMImpl : NovelViewModelImpl {
  explicit UPLVSMImpl(const ModelConfig& config);

  // Scene latents [b, L, d] from unposed input views and their intrinsics (pixels) [b, v_in, 4]; with
  // model.keep_image_tokens [b, L + v_in n, d], the encoder's image-token outputs after the latents. With
  // model.encoder_latent_cameras, the encoder's second pass, whose views 1.. carry their latent cameras.
  torch::Tensor encode_scene(const torch::Tensor& input_images, const torch::Tensor& input_fxfycxcy,
                             ForwardTrace* trace = nullptr);
  // The same from input views whose first k views carry camera rays [b, k, 6, H, W] (encode_scene passes the
  // identity camera's rays for view 0, the canonical marker; encoder_latent_cameras every view's latent camera).
  torch::Tensor encode_scene_with_rays(const torch::Tensor& input_images, const torch::Tensor& rays,
                                       ForwardTrace* trace = nullptr);
  // Latent poses [b, v_t, 7] of target images given the scene latents (the Latent Plücker Learner).
  torch::Tensor estimate_poses(const torch::Tensor& target_images, const torch::Tensor& scene_latents,
                               ForwardTrace* trace = nullptr);
  // The scene latents of unposed inputs and the latent poses [b, v_in, 7] the estimator reads from those same
  // inputs: what rendering between (or around) the inputs starts from (model/encoded_scene.h).
  struct EncodedInputs {
    torch::Tensor latents, input_poses;
  };
  EncodedInputs encode_with_input_poses(const torch::Tensor& input_images, const torch::Tensor& input_fxfycxcy);
  // Renders [b, v_t, 3, H, W] from latent poses [b, v_t, 7] and target intrinsics [b, v_t, 4].
  torch::Tensor render_views(const torch::Tensor& scene_latents, const torch::Tensor& pose_enc,
                             const torch::Tensor& target_fxfycxcy, int64_t height, int64_t width,
                             ForwardTrace* trace = nullptr);
  // Latent poses [b, v_t, 7] of the targets from `source` (Estimator: needs the target images; Mapper, Dataset:
  // needs c2w of inputs and targets).
  torch::Tensor target_latent_poses(const Views& inputs, const Views& targets, const torch::Tensor& scene_latents,
                                    TargetPoses source, ForwardTrace* trace = nullptr);
  // Gives this model a pose mapper (fitted to it by `uplvsm fit-mapper`), replacing one it has.
  void attach_pose_mapper(PoseMapper mapper);

  // The model: scene latents, the targets' latent poses from `source`, the rendered targets.
  Rendered render(const Views& inputs, const Views& targets, TargetPoses source,
                  ForwardTrace* trace = nullptr) override;
  // UP-LVSM's own protocol: the estimator sees the target images.
  Rendered forward(const torch::Tensor& input_images, const torch::Tensor& input_fxfycxcy,
                   const torch::Tensor& target_images, const torch::Tensor& target_fxfycxcy,
                   ForwardTrace* trace = nullptr);
  TargetPoses default_target_poses() const override { return TargetPoses::Estimator; }
  bool has_camera_control() const override { return !pose_mapper.is_empty(); }
  // Encodes the scene once; real cameras go through the pose mapper to latent poses.
  CameraRenderer camera_control(const Views& inputs) override;
  std::string name() const override { return "UP-LVSM"; }
  void set_grad_checkpoint_every(int64_t k) override;

  torch::Tensor n_light_field_latent;  // [L, d] learnable scene-latent queries
  torch::nn::ModuleList transformer_encoder{nullptr}, transformer_decoder{nullptr};
  LayerNorm transformer_input_layernorm_decoder{nullptr};
  LatentPluckerLearner estimator{nullptr};
  PoseMapper pose_mapper{nullptr};  // camera control, an option of UP-LVSM: registered when config.pose_mapper

 private:
  // The encoder over [latents ; DINOv2 tokens [b, v, n, d] + the rays' tokens].
  torch::Tensor encode_tokens(const torch::Tensor& tokens, const torch::Tensor& rays, ForwardTrace* trace);
  // The estimator on the targets' DINOv2 tokens [b, v_t, n, d].
  torch::Tensor estimate_poses_from_tokens(const torch::Tensor& tokens, const torch::Tensor& scene_latents,
                                           ForwardTrace* trace);
  // The decoder from the targets' Plücker rays [b, v_t, 6, H, W].
  torch::Tensor render_rays(const torch::Tensor& scene_latents, const torch::Tensor& rays, ForwardTrace* trace);
  // Latent poses [b, n, 7] of real cameras [b, n, 7] (camera-control units) through the pose mapper; an MLP mapper
  // also reads the estimator's latent poses of the input views from `input_images` [b, vi, 3, H, W].
  torch::Tensor map_real_poses(const torch::Tensor& real_poses, const torch::Tensor& scene_latents,
                               const torch::Tensor& input_images);
};
TORCH_MODULE(UPLVSM);

// The UP-LVSM that `model` is, or null for another model of the family.
UPLVSMImpl* as_uplvsm(NovelViewModelImpl& model);
// `model` as an UP-LVSM, for a capability only it has (scene latents, latent poses); else an error naming `what`
// and the model given.
UPLVSM require_uplvsm(const NovelViewModel& model, const std::string& what);

}  // namespace uplvsm::model
