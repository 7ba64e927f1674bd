#include "uplvsm/model/flops.h"

namespace uplvsm::model {

double transformer_block_flops(int64_t seq, int64_t d, int64_t mlp_hidden) {
  const double s = static_cast<double>(seq), dd = static_cast<double>(d);
  const double projections = 2.0 * s * 4.0 * dd * dd;  // q, k, v, out
  const double mlp = 2.0 * s * 2.0 * dd * static_cast<double>(mlp_hidden);
  const double attention = 2.0 * 2.0 * s * s * dd;  // QK^T and PV over all heads
  return projections + mlp + attention;
}

FlopCount forward_flops(const ModelConfig& c, int64_t batch, int64_t input_views, int64_t target_views) {
  const auto& t = c.transformer;
  const auto& dino = c.dinov2;
  const int64_t grid = c.image_size / c.patch_size, n = grid * grid, L = t.n_latent_vectors;
  const double b = static_cast<double>(batch), vi = static_cast<double>(input_views),
               vt = static_cast<double>(target_views), p2 = static_cast<double>(c.patch_size * c.patch_size);
  FlopCount f;
  // DINOv2 over every input image and (for the estimator) every target image.
  const double dino_image =
      2.0 * n * 3 * p2 * dino.embed_dim +
      dino.depth * transformer_block_flops(1 + dino.num_register_tokens + n, dino.embed_dim, dino.mlp_ratio * dino.embed_dim);
  const bool estimator = c.variant == "uplvsm";
  f.dinov2 = b * (vi + (estimator ? vt : 0)) * dino_image;
  if (c.variant == "ptlvsm" || c.variant == "lvsm") {
    // Decoder-only LVSM: every target attends to all input tokens and its own pose tokens.
    f.decoder = b * vt * t.n_layer * transformer_block_flops(static_cast<int64_t>(vi) * n + n, t.d, 4 * t.d);
  } else {
    f.encoder = b * t.encoder_n_layer * transformer_block_flops(L + static_cast<int64_t>(vi) * n, t.d, 4 * t.d);
    f.estimator = b * vt * t.estimator_n_layer * transformer_block_flops(n + L, t.d, 4 * t.d);
    f.decoder = b * vt * t.decoder_n_layer * transformer_block_flops(n + L, t.d, 4 * t.d);
  }
  const double plucker_tokens = 2.0 * n * 6 * p2 * t.d, rgb_head = 2.0 * n * t.d * 3 * p2;
  const double canonical_views = c.variant == "lvsm" ? vi : 1;  // views whose tokens get Plücker rays added
  const double pose_heads = estimator ? vt * 2.0 * 2 * (t.d * (t.d / 2.0) + (t.d / 2.0) * 3.5) : 0;
  f.other = b * (canonical_views * plucker_tokens + vt * (plucker_tokens + rgb_head) + pose_heads);
  return f;
}

}  // namespace uplvsm::model
