// validate_config: what a config may ask for, each field against its range and the fields it needs beside it,
// checked once when a config is read (config.cpp) so a bad one fails naming the field, before any work is done.
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/core/config.h"

namespace uplvsm {

namespace {

void require(bool ok, const std::string& source, const std::string& what) {
  if (!ok) throw std::runtime_error(fmt::format("{}: {}", source, what));
}

void validate_model(const ModelConfig& m, const std::string& s) {
  const auto& t = m.transformer;
  require(!m.pose_mapper || m.variant == Variant::UPLVSM, s,
          "model.pose_mapper: only the uplvsm variant has latent poses to map to");
  require(!m.keep_image_tokens || m.variant == Variant::UPLVSM, s,
          "model.keep_image_tokens: only the uplvsm variant has an encoder whose image tokens it could keep");
  require(m.patch_size > 0 && m.image_size > 0 && m.image_size % m.patch_size == 0, s,
          fmt::format("model.image_size ({}) must be a positive multiple of model.patch_size ({})", m.image_size,
                      m.patch_size));
  require(t.d > 0 && t.d_head > 0 && t.d % t.d_head == 0, s,
          fmt::format("model.transformer.d ({}) must be a multiple of d_head ({})", t.d, t.d_head));
  require(t.encoder_n_layer >= 1 && t.estimator_n_layer >= 1 && t.decoder_n_layer >= 1 && t.n_layer >= 1, s,
          "model.transformer: every stack needs at least one layer");
  require(t.n_latent_vectors >= 1, s, "model.transformer.n_latent_vectors must be >= 1");
  require(m.dinov2.embed_dim == t.d, s,
          fmt::format("model.dinov2.embed_dim ({}) must equal model.transformer.d ({}): DINOv2 tokens are used "
                      "directly as transformer tokens",
                      m.dinov2.embed_dim, t.d));
  require(m.dinov2.num_heads > 0 && m.dinov2.embed_dim % m.dinov2.num_heads == 0, s,
          "model.dinov2.embed_dim must be a multiple of num_heads");
  require(m.dinov2.pos_embed_init == "normal" || m.dinov2.pos_embed_init == "sincos", s,
          "model.dinov2.pos_embed_init must be 'normal' or 'sincos', got '" + m.dinov2.pos_embed_init + "'");
  require(m.dinov2.pos_embed_init != "sincos" || m.dinov2.embed_dim % 4 == 0, s,
          "model.dinov2.pos_embed_init 'sincos' needs embed_dim divisible by 4");
}

// Where the target cameras come from, against what the model can do with them.
void validate_target_poses(const ModelConfig& m, const TrainingConfig& tr, const std::string& s) {
  const auto tp = tr.target_poses;
  require(m.variant == Variant::UPLVSM || tp == TargetPoses::Auto || tp == TargetPoses::Dataset, s,
          "training.target_poses: the " + to_string(m.variant) +
              " variant renders from dataset cameras ('auto' or 'dataset')");
  require(tp != TargetPoses::Mapper || m.pose_mapper, s,
          "training.target_poses 'mapper' needs model.pose_mapper: true");
  require(!m.encoder_latent_cameras || m.variant == Variant::UPLVSM, s,
          "model.encoder_latent_cameras: only the uplvsm variant has latent cameras to give its encoder");
}

void validate_training(const Config& c, const std::string& s) {
  const auto& tr = c.training;
  require(tr.num_input_views >= 1 && tr.num_target_views >= 1, s, "training: need >= 1 input and target view");
  require(tr.num_views >= tr.num_input_views && tr.num_views >= 2, s,
          "training.num_views must be >= num_input_views and >= 2");
  require(tr.batch_size >= 1 && tr.grad_accum_steps >= 1, s, "training.batch_size and grad_accum_steps must be >= 1");
  require(tr.global_batch_size >= 0, s,
          "training.global_batch_size must be >= 0 (0: batch_size x grad_accum_steps on each process)");
  require(tr.grad_clip_norm >= 0 && std::isfinite(tr.grad_clip_norm), s,
          fmt::format("training.grad_clip_norm must be a finite number >= 0 (0: no clipping and no skipping of "
                      "large-norm steps, as the official), got {}",
                      tr.grad_clip_norm));
  require(tr.allowed_gradnorm_factor > 0 && std::isfinite(tr.allowed_gradnorm_factor), s,
          "training.allowed_gradnorm_factor must be a finite number > 0");
  require(tr.grad_checkpoint_every >= 0, s, "training.grad_checkpoint_every must be >= 0 (0: off)");
  require(tr.min_frame_dist >= 1, s, "training.min_frame_dist must be >= 1");
  // The official view selector skips a scene whose largest gap is not above the smallest
  // (dataset_scene.py:155-158 at d490397): with max == min it skips every scene and cannot train.
  require(tr.max_frame_dist > tr.min_frame_dist, s,
          "training.max_frame_dist must be greater than min_frame_dist (the official view selector skips every "
          "scene when they are equal)");
  require(tr.frame_dist_curriculum_steps >= 0, s, "training.frame_dist_curriculum_steps must be >= 0");
  require(tr.gradient_difference_weight >= 0 && std::isfinite(tr.gradient_difference_weight), s,
          "training.gradient_difference_weight must be a finite number >= 0 (0: off)");
  require(tr.max_train_scenes >= 0, s, "training.max_train_scenes must be >= 0 (0: every scene of the train split)");
  require(tr.chunks_per_shuffle >= 0, s, "training.chunks_per_shuffle must be >= 0 (0: the whole split)");
  require(tr.pose_noise_std >= 0 && std::isfinite(tr.pose_noise_std), s,
          "training.pose_noise_std must be a finite number >= 0");
  require(tr.train_steps >= 1 && tr.warmup >= 0, s, "training.train_steps must be >= 1 and warmup >= 0");
  require(c.dataset.frames_per_scene >= tr.num_views, s, "dataset.frames_per_scene must be >= training.num_views");
  require(c.dataset.texture_scale > 0, s, "dataset.texture_scale must be > 0");
  require(tr.view_sampler == "auto" || tr.view_sampler == "ordered" || tr.view_sampler == "unordered", s,
          "training.view_sampler must be 'auto', 'ordered' or 'unordered', got '" + tr.view_sampler + "'");
  require(c.dataset.kind == "rooms" || c.dataset.kind == "objects", s,
          "dataset.kind must be 'rooms' or 'objects', got '" + c.dataset.kind + "'");
}

}  // namespace

void validate_config(const Config& c, const std::string& s) {
  validate_model(c.model, s);
  validate_training(c, s);
  validate_target_poses(c.model, c.training, s);
}

}  // namespace uplvsm
