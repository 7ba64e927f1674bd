#include "uplvsm/train/memory_estimate.h"

namespace uplvsm::train {
namespace {

// transformer.h: norm1, norm2 (LayerNorm without bias), to_qkv and fc (no bias), RMSNorm q/k, MLP d -> 4d -> d.
int64_t transformer_block_parameters(int64_t d, int64_t d_head) { return 12 * d * d + 2 * d + 2 * d_head; }

// dinov2.h: LayerNorms with bias, qkv/proj with bias, optional RMSNorm q/k, two LayerScales, MLP with biases.
int64_t dino_block_parameters(const Dinov2Config& c) {
  const int64_t D = c.embed_dim, hidden = D * c.mlp_ratio;
  const int64_t attention = 3 * D * D + 3 * D + D * D + D + (c.qk_norm ? 2 * (D / c.num_heads) : 0);
  const int64_t mlp = D * hidden + hidden + hidden * D + D;
  return 2 * D + attention + D + 2 * D + mlp + D;
}

int64_t dinov2_parameters(const Dinov2Config& c, int64_t patch) {
  const int64_t D = c.embed_dim;
  const int64_t embeddings =
      D + (1 + c.pos_grid * c.pos_grid) * D + c.num_register_tokens * D + 3 * patch * patch * D + D;
  return embeddings + c.depth * dino_block_parameters(c) + 2 * D;
}

// DinoMlp(d, hidden, out) with biases.
int64_t head_parameters(int64_t d, int64_t hidden, int64_t out) { return d * hidden + hidden + hidden * out + out; }

int64_t stack_parameters(int64_t layers, const TransformerConfig& t) {
  return layers * transformer_block_parameters(t.d, t.d_head);
}

}  // namespace

int64_t parameter_count(const ModelConfig& c) {
  const auto& t = c.transformer;
  const int64_t p = c.patch_size;
  int64_t n = dinov2_parameters(c.dinov2, p) + 2 * 6 * p * p * t.d;  // tokenizer, target + canonical pose tokenizers
  if (c.variant != Variant::UPLVSM) {
    n += stack_parameters(t.n_layer, t) + t.d;
  } else {
    n += t.n_latent_vectors * t.d + stack_parameters(t.encoder_n_layer, t) + stack_parameters(t.decoder_n_layer, t) +
         t.d;
    n += stack_parameters(t.estimator_n_layer, t) + head_parameters(t.d, t.d / 2, 3) + head_parameters(t.d, t.d / 2, 4);
    if (c.pose_mapper) n += 7 * 7 + 7;
  }
  return n + t.d + t.d * p * p * 3;  // image_token_decoder: LayerNorm, Linear
}

TrainingMemory training_memory(const Config& config) {
  const auto& c = config.model;
  const auto& t = c.transformer;
  const auto& tc = config.training;
  TrainingMemory m;
  m.parameters = parameter_count(c);
  m.state_bytes = 16.0 * static_cast<double>(m.parameters);
  const double b = static_cast<double>(tc.batch_size), vi = static_cast<double>(tc.num_input_views),
               vt = static_cast<double>(tc.num_target_views);
  const double grid = static_cast<double>(c.image_size / c.patch_size), n = grid * grid,
               L = static_cast<double>(t.n_latent_vectors);
  const double element = tc.amp == Amp::Bf16 ? 2.0 : 4.0;
  const int64_t k = tc.grad_checkpoint_every;
  // Values kept per token of a stack of `layers` blocks of width `d`.
  auto kept = [&](int64_t layers, int64_t d) {
    const double blocks = k > 0 ? static_cast<double>((layers + k - 1) / k) : 13.0 * static_cast<double>(layers);
    return blocks * static_cast<double>(d);
  };
  // The estimator (and DINOv2 over the targets) runs only where target poses come from it.
  const bool estimator = c.variant == Variant::UPLVSM &&
                         (tc.target_poses == TargetPoses::Auto || tc.target_poses == TargetPoses::Estimator);
  const double dino_tokens =
      b * (vi + (estimator ? vt : 0)) * (1 + static_cast<double>(c.dinov2.num_register_tokens) + n);
  double values = dino_tokens * kept(c.dinov2.depth, c.dinov2.embed_dim);
  if (c.variant == Variant::UPLVSM) {
    // model.encoder_latent_cameras: the estimator over input views 1.., then the encoder a second time.
    const double posed_inputs = c.encoder_latent_cameras && vi > 1 ? vi - 1 : 0.0;
    values += (posed_inputs > 0 ? 2.0 : 1.0) * b * (L + vi * n) * kept(t.encoder_n_layer, t.d);
    const double scene = L + (c.keep_image_tokens ? vi * n : 0.0);
    values += b * vt * (n + scene) * ((estimator ? kept(t.estimator_n_layer, t.d) : 0) + kept(t.decoder_n_layer, t.d));
    values += b * posed_inputs * (n + scene) * kept(t.estimator_n_layer, t.d);
  } else {
    values += b * vt * (vi * n + n) * kept(t.n_layer, t.d);
  }
  m.activation_bytes = values * element;
  return m;
}

}  // namespace uplvsm::train
