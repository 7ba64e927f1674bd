#include "uplvsm/model/uplvsm.h"

#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/plucker.h"

namespace uplvsm::model {

using torch::indexing::Slice;

TargetPoses parse_target_poses(const std::string& name, const ModelConfig& config) {
  if (name == "auto") return config.variant == "uplvsm" ? TargetPoses::Estimator : TargetPoses::Dataset;
  if (name == "estimator") return TargetPoses::Estimator;
  if (name == "mapper") return TargetPoses::Mapper;
  if (name == "dataset") return TargetPoses::Dataset;
  throw std::invalid_argument("target poses: expected auto, estimator, mapper or dataset, got '" + name + "'");
}

std::string to_string(TargetPoses source) {
  switch (source) {
    case TargetPoses::Estimator: return "estimator";
    case TargetPoses::Mapper: return "mapper";
    case TargetPoses::Dataset: return "dataset";
  }
  return "?";
}

bool reads_training_cameras(const ModelConfig& config, const std::string& target_poses) {
  return config.variant != "uplvsm" || parse_target_poses(target_poses, config) != TargetPoses::Estimator;
}

UPLVSMImpl::UPLVSMImpl(const ModelConfig& c) : config(c) {
  const auto& t = c.transformer;
  const int64_t p = c.patch_size;
  const bool depth = t.special_init && t.depth_init;
  if (!posed_variant()) {
    n_light_field_latent =
        register_parameter("n_light_field_latent", torch::randn({t.n_latent_vectors, t.d}).clamp_(-2, 2).mul_(0.02));
  }
  auto image_tokenizer = register_module("image_tokenizer", std::make_shared<torch::nn::Module>());
  tokenizer = image_tokenizer->register_module("1", DinoTokenizer(c.dinov2, p));
  target_pose_tokenizer = register_module("target_pose_tokenizer", PoseTokenizer(p, t.d));
  canonical_pose_tokenizer = register_module("canonical_pose_tokenizer", PoseTokenizer(p, t.d));
  if (posed_variant()) {
    transformer_blocks =
        register_module("transformer_blocks", make_transformer_stack(t.n_layer, t.d, t.d_head, t.qk_norm_eps, depth));
    transformer_input_layernorm = register_module("transformer_input_layernorm", LayerNorm(t.d, 1e-5, false));
  } else {
    transformer_encoder = register_module(
        "transformer_encoder", make_transformer_stack(t.encoder_n_layer, t.d, t.d_head, t.qk_norm_eps, depth));
    transformer_decoder = register_module(
        "transformer_decoder", make_transformer_stack(t.decoder_n_layer, t.d, t.d_head, t.qk_norm_eps, depth));
    transformer_input_layernorm_decoder =
        register_module("transformer_input_layernorm_decoder", LayerNorm(t.d, 1e-5, false));
    estimator = register_module("estimator", LatentPluckerLearner(t));
    if (c.pose_mapper) pose_mapper = register_module("pose_mapper", PoseMapper());
  }
  image_token_decoder = register_module(
      "image_token_decoder",
      torch::nn::Sequential(LayerNorm(t.d, 1e-5, false),
                            torch::nn::Linear(torch::nn::LinearOptions(t.d, p * p * 3).bias(false))));
  init_linear_weights(*target_pose_tokenizer, 0.02);
  init_linear_weights(*canonical_pose_tokenizer, 0.02);
  init_linear_weights(*image_token_decoder, 0.02);
}

torch::Tensor UPLVSMImpl::tokenize(const torch::Tensor& images) {
  RECORD_FUNCTION("uplvsm::dinov2_tokenizer", std::vector<c10::IValue>());  // profiler spans (bench UPLVSM_PROFILE)
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
  TORCH_CHECK(!posed_variant(), "encode_scene: the ", config.variant, " variant has no scene latents");
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
  auto encoder_input = torch::cat({n_light_field_latent.unsqueeze(0).expand({b, L, d}), x}, 1);
  torch::Tensor z;
  {
    RECORD_FUNCTION("uplvsm::encoder", std::vector<c10::IValue>());
    z = run_stack(transformer_encoder, encoder_input, grad_checkpoint_every);
  }
  if (trace) {
    trace->encoder_input = encoder_input;
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
  RECORD_FUNCTION("uplvsm::estimator", std::vector<c10::IValue>());
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
  const int64_t b = pose_enc.size(0), v = pose_enc.size(1);
  auto rays = geometry::plucker_rays(geometry::pose_encoding_to_c2w(pose_enc), fxfycxcy, H, W);  // [b, v, 6, H, W]
  auto q = target_pose_tokenizer(rays.flatten(0, 1));  // [b v, n, d]
  const int64_t n = q.size(1);
  auto x = transformer_input_layernorm_decoder(torch::cat({q, repeat_per_view(scene_latents, v)}, 1));
  torch::Tensor y;
  {
    RECORD_FUNCTION("uplvsm::decoder", std::vector<c10::IValue>());
    y = run_stack(transformer_decoder, x, grad_checkpoint_every).index({Slice(), Slice(0, n)});
  }
  if (trace) trace->target_plucker = rays;
  return decode_rgb(y, b, v, H, W);
}

torch::Tensor UPLVSMImpl::decode_rgb(const torch::Tensor& y, int64_t b, int64_t v, int64_t H, int64_t W) {
  auto rgb = torch::sigmoid(image_token_decoder->forward(y));
  return unpatchify(rgb, config.patch_size, H, W, 3).view({b, v, 3, H, W});
}

namespace {

const torch::Tensor& require_c2w(const Views& views, const char* which, TargetPoses source) {
  TORCH_CHECK(views.c2w.defined(), "target poses '", to_string(source), "' need the ", which,
              " views' cameras (c2w), which were not given");
  TORCH_CHECK(views.c2w.dim() == 4 && views.c2w.size(1) == views.images.size(1) && views.c2w.size(2) == 4 &&
                  views.c2w.size(3) == 4,
              which, " c2w must be [b, v, 4, 4] matching the images, got ", views.c2w.sizes());
  return views.c2w;
}

// The official posed-variant cameras: per sample, inputs and targets normalised together (training, evaluation),
// or by the inputs alone (a video path, whose frames must not move the frame).
std::pair<torch::Tensor, torch::Tensor> scene_normalised(const torch::Tensor& in_c2w, const torch::Tensor& tg_c2w,
                                                         bool with_targets) {
  TORCH_CHECK(torch::isfinite(in_c2w).all().item<bool>() && torch::isfinite(tg_c2w).all().item<bool>(),
              "posed variant: camera matrices contain NaN or Inf");
  const int64_t vi = in_c2w.size(1);
  std::vector<torch::Tensor> per_sample;
  auto all = torch::cat({in_c2w, tg_c2w}, 1);
  for (int64_t i = 0; i < all.size(0); ++i)
    per_sample.push_back(geometry::official_scene_normalize(all[i], with_targets ? all[i] : in_c2w[i]));
  auto normalised = torch::stack(per_sample).to(in_c2w.scalar_type());
  return {normalised.narrow(1, 0, vi), normalised.narrow(1, vi, tg_c2w.size(1))};
}

}  // namespace

torch::Tensor UPLVSMImpl::target_latent_poses(const Views& inputs, const Views& targets,
                                              const torch::Tensor& scene_latents, TargetPoses source,
                                              ForwardTrace* trace) {
  switch (source) {
    case TargetPoses::Estimator:
      return estimate_poses(targets.images, scene_latents, trace);
    case TargetPoses::Dataset:
      return camera_control_poses(require_c2w(inputs, "input", source), require_c2w(targets, "target", source));
    case TargetPoses::Mapper:
      TORCH_CHECK(pose_mapper, "target poses 'mapper': this model has no pose mapper (model.pose_mapper is false; "
                               "train one with `uplvsm train --stage mapper`)");
      return pose_mapper(
          camera_control_poses(require_c2w(inputs, "input", source), require_c2w(targets, "target", source)));
  }
  TORCH_CHECK(false, "unknown target pose source");
}

torch::Tensor UPLVSMImpl::render_posed(const Views& inputs, const Views& targets, ForwardTrace* trace,
                                       bool normalise_with_targets) {
  TORCH_CHECK(posed_variant(), "render_posed: the uplvsm variant renders through scene latents");
  const auto& images = inputs.images;
  TORCH_CHECK(images.dim() == 5 && images.size(2) == 3, "render_posed: input images must be [b, v, 3, H, W], got ",
              images.sizes());
  const int64_t b = images.size(0), vi = images.size(1), H = targets.images.size(3), W = targets.images.size(4);
  const int64_t vt = targets.fxfycxcy.size(1);
  auto [in_c2w, tg_c2w] = scene_normalised(require_c2w(inputs, "input", TargetPoses::Dataset),
                                           require_c2w(targets, "target", TargetPoses::Dataset), normalise_with_targets);
  auto tokens = tokenize(images);  // [b, vi, n, d]
  const int64_t n = tokens.size(2), d = tokens.size(3);
  // PT-LVSM marks view 0 with its camera's rays; LVSM poses every input view.
  const int64_t posed = config.variant == "lvsm" ? vi : 1;
  auto in_rays = geometry::plucker_rays(in_c2w.narrow(1, 0, posed), inputs.fxfycxcy.narrow(1, 0, posed),
                                        images.size(3), images.size(4));
  auto marker = canonical_pose_tokenizer(in_rays.flatten(0, 1)).view({b, posed, n, d});
  tokens = torch::cat({tokens.narrow(1, 0, posed) + marker, tokens.narrow(1, posed, vi - posed)}, 1);
  auto context = repeat_per_view(tokens.reshape({b, vi * n, d}), vt);  // [b vt, vi n, d]
  auto tg_rays = geometry::plucker_rays(tg_c2w, targets.fxfycxcy, H, W);
  auto q = target_pose_tokenizer(tg_rays.flatten(0, 1));
  auto x = transformer_input_layernorm(torch::cat({context, q}, 1));
  auto y = run_stack(transformer_blocks, x, grad_checkpoint_every).narrow(1, vi * n, q.size(1));
  if (trace) {
    trace->input_dino_tokens = tokens;
    trace->canonical_plucker = in_rays;
    trace->target_plucker = tg_rays;
  }
  return decode_rgb(y, b, vt, H, W);
}

UPLVSMOutput UPLVSMImpl::forward(const Views& inputs, const Views& targets, TargetPoses source,
                                 ForwardTrace* trace) {
  if (posed_variant()) {
    TORCH_CHECK(source == TargetPoses::Dataset, "the ", config.variant,
                " variant renders from dataset cameras only; target poses '", to_string(source), "' do not apply");
    return {render_posed(inputs, targets, trace), {}};
  }
  auto latents = encode_scene(inputs.images, inputs.fxfycxcy, trace);
  auto poses = target_latent_poses(inputs, targets, latents, source, trace).to(latents.device());
  auto render =
      render_views(latents, poses, targets.fxfycxcy, targets.images.size(3), targets.images.size(4), trace);
  return {render, poses};
}

UPLVSMOutput UPLVSMImpl::forward(const torch::Tensor& input_images, const torch::Tensor& input_fxfycxcy,
                                 const torch::Tensor& target_images, const torch::Tensor& target_fxfycxcy,
                                 ForwardTrace* trace) {
  return forward({input_images, input_fxfycxcy, {}}, {target_images, target_fxfycxcy, {}}, TargetPoses::Estimator,
                 trace);
}

void UPLVSMImpl::set_grad_checkpoint_every(int64_t k) {
  TORCH_CHECK(k >= 0, "grad_checkpoint_every must be >= 0, got ", k);
  grad_checkpoint_every = k;
  tokenizer->dino_vit->grad_checkpoint_every = k;
  if (estimator) estimator->grad_checkpoint_every = k;
}

int64_t UPLVSMImpl::parameter_count() const {
  int64_t total = 0;
  for (const auto& p : parameters()) total += p.numel();
  return total;
}

}  // namespace uplvsm::model
