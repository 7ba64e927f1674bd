#include "uplvsm/model/uplvsm.h"

#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/plucker.h"

namespace uplvsm::model {

using torch::indexing::Slice;

UPLVSMImpl::UPLVSMImpl(const ModelConfig& c) : config(c) {
  const auto& t = c.transformer;
  const int64_t p = c.patch_size;
  n_light_field_latent =
      register_parameter("n_light_field_latent", torch::randn({t.n_latent_vectors, t.d}).clamp_(-2, 2).mul_(0.02));
  auto image_tokenizer = register_module("image_tokenizer", std::make_shared<torch::nn::Module>());
  tokenizer = image_tokenizer->register_module("1", DinoTokenizer(c.dinov2, p));
  target_pose_tokenizer = register_module("target_pose_tokenizer", PoseTokenizer(p, t.d));
  canonical_pose_tokenizer = register_module("canonical_pose_tokenizer", PoseTokenizer(p, t.d));
  const bool depth = t.special_init && t.depth_init;
  transformer_encoder = register_module(
      "transformer_encoder", make_transformer_stack(t.encoder_n_layer, t.d, t.d_head, t.qk_norm_eps, depth));
  transformer_decoder = register_module(
      "transformer_decoder", make_transformer_stack(t.decoder_n_layer, t.d, t.d_head, t.qk_norm_eps, depth));
  transformer_input_layernorm_decoder =
      register_module("transformer_input_layernorm_decoder", LayerNorm(t.d, 1e-5, false));
  estimator = register_module("estimator", LatentPluckerLearner(t));
  image_token_decoder = register_module(
      "image_token_decoder",
      torch::nn::Sequential(LayerNorm(t.d, 1e-5, false),
                            torch::nn::Linear(torch::nn::LinearOptions(t.d, p * p * 3).bias(false))));
  init_linear_weights(*target_pose_tokenizer, 0.02);
  init_linear_weights(*canonical_pose_tokenizer, 0.02);
  init_linear_weights(*image_token_decoder, 0.02);
}

torch::Tensor UPLVSMImpl::tokenize(const torch::Tensor& images) {
  const int64_t b = images.size(0), v = images.size(1);
  auto tokens = tokenizer(images.flatten(0, 1));
  return tokens.view({b, v, tokens.size(1), tokens.size(2)});
}

torch::Tensor UPLVSMImpl::repeat_per_view(const torch::Tensor& s, int64_t views) {
  // '(b v)' ordering: batch major, view minor.
  return s.unsqueeze(1).expand({-1, views, -1, -1}).reshape({s.size(0) * views, s.size(1), s.size(2)});
}

torch::Tensor UPLVSMImpl::encode_scene(const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                                       ForwardTrace* trace) {
  TORCH_CHECK(images.dim() == 5 && images.size(2) == 3, "encode_scene: input images must be [b, v, 3, H, W], got ",
              images.sizes());
  const int64_t b = images.size(0), v = images.size(1), H = images.size(3), W = images.size(4);
  auto tokens = tokenize(images);  // [b, v, n, d]
  const int64_t n = tokens.size(2), d = tokens.size(3);
  // The canonical marker: Plücker rays of an identity camera, added to view 0's tokens only.
  auto identity = geometry::identity_c2w({b, 1}, fxfycxcy.options());
  auto marker_rays = geometry::plucker_rays(identity, fxfycxcy.index({Slice(), Slice(0, 1)}), H, W);
  auto marker = canonical_pose_tokenizer(marker_rays.flatten(0, 1));  // [b, n, d]
  auto flat = tokens.reshape({b, v * n, d});
  auto x = torch::cat({flat.index({Slice(), Slice(0, n)}) + marker, flat.index({Slice(), Slice(n)})}, 1);
  const int64_t L = n_light_field_latent.size(0);
  auto z = run_stack(transformer_encoder, torch::cat({n_light_field_latent.unsqueeze(0).expand({b, L, d}), x}, 1));
  if (trace) {
    trace->input_dino_tokens = tokens;
    trace->canonical_plucker =
        geometry::plucker_rays(geometry::identity_c2w({b, v}, fxfycxcy.options()), fxfycxcy, H, W);
    trace->encoder_output = z;
  }
  return z.index({Slice(), Slice(0, L)});
}

torch::Tensor UPLVSMImpl::estimate_poses(const torch::Tensor& images, const torch::Tensor& scene_latents,
                                         ForwardTrace* trace) {
  TORCH_CHECK(images.dim() == 5 && images.size(2) == 3, "estimate_poses: target images must be [b, v, 3, H, W], got ",
              images.sizes());
  const int64_t b = images.size(0), v = images.size(1);
  auto tokens = tokenize(images);
  auto flat_tokens = tokens.flatten(0, 1);
  auto latents = repeat_per_view(scene_latents, v);
  auto pooled = estimator->pooled(flat_tokens, latents);
  if (trace) {
    trace->target_dino_tokens = tokens;
    trace->estimator_pooled = pooled.view({b, v, -1});
  }
  return estimator->heads(pooled).view({b, v, 7});
}

torch::Tensor UPLVSMImpl::render_views(const torch::Tensor& scene_latents, const torch::Tensor& pose_enc,
                                       const torch::Tensor& fxfycxcy, int64_t H, int64_t W, ForwardTrace* trace) {
  TORCH_CHECK(pose_enc.dim() == 3 && pose_enc.size(2) == 7, "render_views: poses must be [b, v, 7], got ",
              pose_enc.sizes());
  const int64_t b = pose_enc.size(0), v = pose_enc.size(1), p = config.patch_size;
  auto rays = geometry::plucker_rays(geometry::pose_encoding_to_c2w(pose_enc), fxfycxcy, H, W);  // [b, v, 6, H, W]
  auto q = target_pose_tokenizer(rays.flatten(0, 1));  // [b v, n, d]
  const int64_t n = q.size(1);
  auto x = transformer_input_layernorm_decoder(torch::cat({q, repeat_per_view(scene_latents, v)}, 1));
  auto y = run_stack(transformer_decoder, x).index({Slice(), Slice(0, n)});
  auto rgb = torch::sigmoid(image_token_decoder->forward(y));
  if (trace) trace->target_plucker = rays;
  return unpatchify(rgb, p, H, W, 3).view({b, v, 3, H, W});
}

UPLVSMOutput UPLVSMImpl::forward(const torch::Tensor& input_images, const torch::Tensor& input_fxfycxcy,
                                 const torch::Tensor& target_images, const torch::Tensor& target_fxfycxcy,
                                 ForwardTrace* trace) {
  auto latents = encode_scene(input_images, input_fxfycxcy, trace);
  auto poses = estimate_poses(target_images, latents, trace);
  auto render = render_views(latents, poses, target_fxfycxcy, target_images.size(3), target_images.size(4), trace);
  return {render, poses};
}

int64_t UPLVSMImpl::parameter_count() const {
  int64_t total = 0;
  for (const auto& p : parameters()) total += p.numel();
  return total;
}

}  // namespace uplvsm::model
