// The DINOv2 of ../shared/fixtures/dinov2: Meta's plain ViT-S/14 (no registers, no QK-norm, 0.1-offset bicubic
// pos-embed interpolation), shared by the tokenizer's forward test and the weight-file readers' tests.
#pragma once
#include "uplvsm/core/config.h"

namespace uplvsm::test {

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
