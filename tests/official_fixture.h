// The model config of the official-code fixtures (../shared/fixtures/official_uplvsm and official_uplvsm_train):
// d 64, 126x126, patch 14, DINOv2 reg4 with QK-norm, 24 scene latents.
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

}  // namespace uplvsm::test
