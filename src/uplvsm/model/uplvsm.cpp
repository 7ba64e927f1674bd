#include "uplvsm/model/uplvsm.h"

#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/geometry/plucker.h"

namespace uplvsm::model {

using torch::indexing::Slice;

UPLVSMImpl::UPLVSMImpl(const ModelConfig& c) : NovelViewModelImpl(c) {
  const auto& t = c.transformer;
  // Official trunc_normal_(std=0.02) with its default bounds, absolute -2 and 2 (100 std): in effect N(0, 0.02).
  n_light_field_latent = register_parameter(
      "n_light_field_latent", trunc_normal_(torch::empty({t.n_latent_vectors, t.d}), 0.0, 0.02, -2.0, 2.0));
  register_tokenizers();
  transformer_encoder = register_module(
      "transformer_encoder",
      make_transformer_stack(t.d, t.d_head, t.qk_norm_eps,
                             official_block_init_stds(t.encoder_n_layer, t.special_init, t.depth_init)));
  transformer_decoder = register_module(
      "transformer_decoder",
      make_transformer_stack(t.d, t.d_head, t.qk_norm_eps,
                             official_block_init_stds(t.decoder_n_layer, t.special_init, t.depth_init)));
  transformer_input_layernorm_decoder =
      register_module("transformer_input_layernorm_decoder", LayerNorm(t.d, 1e-5, false));
  estimator = register_module("estimator", LatentPluckerLearner(t));
  if (c.pose_mapper) pose_mapper = register_module("pose_mapper", PoseMapper());
  register_rgb_head();
}

torch::Tensor UPLVSMImpl::encode_scene(const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                                       ForwardTrace* trace) {
  TORCH_CHECK(images.dim() == 5 && images.size(2) == 3, "encode_scene: input images must be [b, v, 3, H, W], got ",
              images.sizes());
  const int64_t b = images.size(0), v = images.size(1), H = images.size(3), W = images.size(4);
  // The canonical marker: Plücker rays of an identity camera, added to view 0's tokens only.
  auto identity = geometry::identity_c2w({b, 1}, fxfycxcy.options());
  auto marker_rays = geometry::plucker_rays(identity, fxfycxcy.index({Slice(), Slice(0, 1)}), H, W);
  if (trace)  // every view's identity rays, for the parity fixtures
    keep(trace, {{&ForwardTrace::canonical_plucker,
                  geometry::plucker_rays(geometry::identity_c2w({b, v}, fxfycxcy.options()), fxfycxcy, H, W)}});
  auto tokens = tokenize(images);  // [b, v, n, d]
  const bool second_pass = config.encoder_latent_cameras && v > 1;
  auto scene = encode_tokens(tokens, marker_rays, second_pass ? nullptr : trace);
  if (!second_pass) return scene;
  // model.encoder_latent_cameras: a second pass (the one a trace keeps) in which every input view carries its latent
  // camera, view 0 the identity (the marker) and the others what the estimator reads from them in the first scene.
  // In fp32 like the identity and the intrinsics (autocast may hand the heads' output back in bf16).
  auto poses =
      estimate_poses_from_tokens(tokens.narrow(1, 1, v - 1), scene, nullptr).to(torch::kFloat32);  // [b, v - 1, 7]
  auto c2w = torch::cat({geometry::identity_c2w({b, 1}, poses.options()), geometry::pose_encoding_to_c2w(poses)}, 1);
  return encode_tokens(tokens, geometry::plucker_rays(c2w, fxfycxcy, H, W), trace);
}

torch::Tensor UPLVSMImpl::encode_scene_with_rays(const torch::Tensor& images, const torch::Tensor& rays,
                                                 ForwardTrace* trace) {
  TORCH_CHECK(images.dim() == 5 && images.size(2) == 3, "encode_scene: input images must be [b, v, 3, H, W], got ",
              images.sizes());
  return encode_tokens(tokenize(images), rays, trace);
}

torch::Tensor UPLVSMImpl::encode_tokens(const torch::Tensor& tokens, const torch::Tensor& rays, ForwardTrace* trace) {
  const int64_t b = tokens.size(0), v = tokens.size(1), n = tokens.size(2), d = tokens.size(3);
  auto x = with_camera_tokens(tokens, rays).reshape({b, v * n, d});
  const int64_t L = n_light_field_latent.size(0);
  auto encoder_input = torch::cat({n_light_field_latent.unsqueeze(0).expand({b, L, d}), x}, 1);  // [b, L + v n, d]
  // Without the image tokens only the latents are read on; a trace keeps every row for the parity fixtures.
  const bool all_rows = config.keep_image_tokens || trace;
  auto z = run_stack(transformer_encoder, encoder_input, grad_checkpoint_every, "uplvsm::encoder",
                     all_rows ? OutputRows{} : OutputRows{0, L});
  keep(trace, {{&ForwardTrace::input_dino_tokens, tokens},
               {&ForwardTrace::encoder_input, encoder_input},
               {&ForwardTrace::encoder_output, z}});
  return all_rows && !config.keep_image_tokens ? z.index({Slice(), Slice(0, L)}) : z;
}

torch::Tensor UPLVSMImpl::estimate_poses(const torch::Tensor& target_images, const torch::Tensor& scene_latents,
                                         ForwardTrace* trace) {
  TORCH_CHECK(target_images.dim() == 5 && target_images.size(2) == 3,
              "estimate_poses: target images must be [b, v, 3, H, W], got ", target_images.sizes());
  return estimate_poses_from_tokens(tokenize(target_images), scene_latents, trace);
}

torch::Tensor UPLVSMImpl::estimate_poses_from_tokens(const torch::Tensor& tokens, const torch::Tensor& scene_latents,
                                                     ForwardTrace* trace) {
  const int64_t b = tokens.size(0), v = tokens.size(1);
  auto pooled = estimator->pooled(tokens.flatten(0, 1), repeat_per_view(scene_latents, v));  // [b v, d]
  keep(trace,
       {{&ForwardTrace::target_dino_tokens, tokens}, {&ForwardTrace::estimator_pooled, pooled.view({b, v, -1})}});
  return estimator->heads(pooled).view({b, v, 7});
}

UPLVSMImpl::EncodedInputs UPLVSMImpl::encode_with_input_poses(const torch::Tensor& images,
                                                              const torch::Tensor& fxfycxcy) {
  auto latents = encode_scene(images, fxfycxcy);
  return {latents, estimate_poses(images, latents)};
}

torch::Tensor UPLVSMImpl::render_views(const torch::Tensor& scene_latents, const torch::Tensor& pose_enc,
                                       const torch::Tensor& fxfycxcy, int64_t H, int64_t W, ForwardTrace* trace) {
  TORCH_CHECK(pose_enc.dim() == 3 && pose_enc.size(2) == 7, "render_views: poses must be [b, v, 7], got ",
              pose_enc.sizes());
  return render_rays(scene_latents, geometry::plucker_rays(geometry::pose_encoding_to_c2w(pose_enc), fxfycxcy, H, W),
                     trace);
}

torch::Tensor UPLVSMImpl::render_rays(const torch::Tensor& scene_latents, const torch::Tensor& rays,
                                      ForwardTrace* trace) {
  TORCH_CHECK(rays.dim() == 5 && rays.size(2) == 6, "render_rays: rays must be [b, v, 6, H, W], got ", rays.sizes());
  const int64_t b = rays.size(0), v = rays.size(1), H = rays.size(3), W = rays.size(4);
  auto q = target_pose_tokenizer(rays.flatten(0, 1));  // [b v, n, d]
  const int64_t n = q.size(1);
  auto x = transformer_input_layernorm_decoder(torch::cat({q, repeat_per_view(scene_latents, v)}, 1));
  auto y = run_stack(transformer_decoder, x, grad_checkpoint_every, "uplvsm::decoder", OutputRows{0, n});
  keep(trace, {{&ForwardTrace::target_plucker, rays}});
  return image_token_decoder(y, b, v, H, W);
}

torch::Tensor UPLVSMImpl::target_latent_poses(const Views& inputs, const Views& targets,
                                              const torch::Tensor& scene_latents, TargetPoses source,
                                              ForwardTrace* trace) {
  switch (source) {
    case TargetPoses::Auto: return target_latent_poses(inputs, targets, scene_latents, default_target_poses(), trace);
    case TargetPoses::Estimator: return estimate_poses(targets.images, scene_latents, trace);
    case TargetPoses::Dataset:
      return geometry::camera_control_poses(require_c2w(inputs, "input", source),
                                            require_c2w(targets, "target", source));
    case TargetPoses::Mapper:
      return map_real_poses(
          geometry::camera_control_poses(require_c2w(inputs, "input", source), require_c2w(targets, "target", source)),
          scene_latents, inputs.images);
  }
  TORCH_CHECK(false, "unknown target pose source");
}

Rendered UPLVSMImpl::render(const Views& inputs, const Views& targets, TargetPoses source, ForwardTrace* trace) {
  auto latents = encode_scene(inputs.images, inputs.fxfycxcy, trace);
  auto poses = target_latent_poses(inputs, targets, latents, source, trace).to(latents.device());
  auto render = render_views(latents, poses, targets.fxfycxcy, targets.images.size(3), targets.images.size(4), trace);
  return {render, poses, latents};
}

Rendered UPLVSMImpl::forward(const torch::Tensor& input_images, const torch::Tensor& input_fxfycxcy,
                             const torch::Tensor& target_images, const torch::Tensor& target_fxfycxcy,
                             ForwardTrace* trace) {
  return render({input_images, input_fxfycxcy, {}}, {target_images, target_fxfycxcy, {}}, TargetPoses::Estimator,
                trace);
}

CameraRenderer UPLVSMImpl::camera_control(const Views& inputs) {
  TORCH_CHECK(pose_mapper,
              "rendering a camera path needs a camera mapper: fit one with `uplvsm fit-mapper` (minutes), fine-tune "
              "one with `uplvsm train --stage mapper`, or render the latent interpolation between the inputs");
  auto latents = encode_scene(inputs.images, inputs.fxfycxcy);
  torch::Tensor scene;  // what an MLP mapper reads of the scene, computed once
  if (pose_mapper->reads_scene()) scene = scene_conditioning(estimate_poses(inputs.images, latents));
  return [this, latents, scene](const torch::Tensor& poses, const torch::Tensor& fxfycxcy, int64_t H, int64_t W) {
    return render_views(latents, pose_mapper(poses.to(latents.device(), torch::kFloat32), scene), fxfycxcy, H, W);
  };
}

torch::Tensor UPLVSMImpl::map_real_poses(const torch::Tensor& real, const torch::Tensor& scene_latents,
                                         const torch::Tensor& input_images) {
  TORCH_CHECK(pose_mapper,
              "target poses 'mapper': this model has no pose mapper (fit one with `uplvsm fit-mapper`, "
              "or fine-tune one with `uplvsm train --stage mapper`)");
  torch::Tensor scene;
  if (pose_mapper->reads_scene()) scene = scene_conditioning(estimate_poses(input_images, scene_latents));
  return pose_mapper(real.to(scene_latents.device(), torch::kFloat32), scene);
}

void UPLVSMImpl::attach_pose_mapper(PoseMapper mapper) {
  auto device = n_light_field_latent.device();
  mapper->to(device);
  pose_mapper = pose_mapper ? replace_module("pose_mapper", mapper) : register_module("pose_mapper", mapper);
}

void UPLVSMImpl::set_grad_checkpoint_every(int64_t k) {
  NovelViewModelImpl::set_grad_checkpoint_every(k);
  estimator->grad_checkpoint_every = k;
}

UPLVSMImpl* as_uplvsm(NovelViewModelImpl& model) { return dynamic_cast<UPLVSMImpl*>(&model); }

UPLVSM require_uplvsm(const NovelViewModel& model, const std::string& what) {
  auto up = std::dynamic_pointer_cast<UPLVSMImpl>(model.ptr());
  TORCH_CHECK(up, what, ": only UP-LVSM has scene latents and latent poses; this is a ", model->name(),
              " model (model.variant '", to_string(model->config.variant), "')");
  return up;
}

}  // namespace uplvsm::model
