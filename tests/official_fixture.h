// The model configs of the reference fixtures: the official-code ones (../shared/fixtures/official_uplvsm and
// official_uplvsm_train: d 64, 126x126, patch 14, DINOv2 reg4 with QK-norm, 24 scene latents) and Meta's DINOv2
// (../shared/fixtures/dinov2).
#pragma once
#include "uplvsm/core/config.h"

namespace uplvsm::test {

inline ModelConfig official_fixture_model_config() {
  ModelConfig c;
  c.image_size = 126;
  c.patch_size = 14;
  c.transformer.d = 64;
  c.transformer.d_head = 32;
  c.transformer.encoder_n_layer = 2;
  c.transformer.estimator_n_layer = 1;
  c.transformer.decoder_n_layer = 2;
  c.transformer.n_latent_vectors = 24;
  c.dinov2.embed_dim = 64;
  c.dinov2.depth = 2;
  c.dinov2.num_heads = 4;
  c.dinov2.num_register_tokens = 4;
  return c;
}

// Meta's plain ViT-S/14: no registers, no QK-norm, 0.1-offset bicubic pos-embed interpolation.
inline Dinov2Config meta_fixture_dinov2() {
  Dinov2Config c;
  c.embed_dim = 384;
  c.depth = 2;
  c.num_heads = 6;
  c.num_register_tokens = 0;
  c.qk_norm = false;
  c.interpolate_antialias = false;
  c.interpolate_offset = 0.1;
  return c;
}

}  // namespace uplvsm::test
