#include "uplvsm/train/flops.h"

#include "uplvsm/model/posed_lvsm.h"

namespace uplvsm::train {

double transformer_block_flops(int64_t seq, int64_t d, int64_t mlp_hidden) {
  const double s = static_cast<double>(seq), dd = static_cast<double>(d);
  const double projections = 2.0 * s * 4.0 * dd * dd;  // q, k, v, out
  const double mlp = 2.0 * s * 2.0 * dd * static_cast<double>(mlp_hidden);
  const double attention = 2.0 * 2.0 * s * s * dd;  // QK^T and PV over all heads
  return projections + mlp + attention;
}

double transformer_stack_flops(int64_t n_layer, int64_t seq, int64_t kept, int64_t d, int64_t mlp_hidden) {
  if (n_layer <= 0) return 0.0;
  const double s = static_cast<double>(seq), k = static_cast<double>(kept), dd = static_cast<double>(d);
  const double last = 2.0 * s * 3.0 * dd * dd + 2.0 * k * dd * dd +
                      2.0 * k * 2.0 * dd * static_cast<double>(mlp_hidden) + 2.0 * 2.0 * k * s * dd;
  return static_cast<double>(n_layer - 1) * transformer_block_flops(seq, d, mlp_hidden) + last;
}

namespace {

// The parts every model of the family has, per image: DINOv2, the Plücker ray tokens, the RGB head.
struct SharedFlops {
  int64_t n;  // tokens per image
  double dino_image, plucker_tokens, rgb_head;
};

SharedFlops shared_flops(const ModelConfig& c) {
  const auto& dino = c.dinov2;
  const int64_t grid = c.image_size / c.patch_size, n = grid * grid;
  const double p2 = static_cast<double>(c.patch_size * c.patch_size), d = static_cast<double>(c.transformer.d);
  const double dino_image = 2.0 * n * 3 * p2 * dino.embed_dim +
                            dino.depth * transformer_block_flops(1 + dino.num_register_tokens + n, dino.embed_dim,
                                                                 dino.mlp_ratio * dino.embed_dim);
  return {n, dino_image, 2.0 * n * 6 * p2 * d, 2.0 * n * d * 3 * p2};
}

}  // namespace

FlopCount uplvsm_forward_flops(const ModelConfig& c, int64_t batch, int64_t input_views, int64_t target_views) {
  const auto& t = c.transformer;
  const auto s = shared_flops(c);
  const int64_t n = s.n, L = t.n_latent_vectors;
  const double b = static_cast<double>(batch), vi = static_cast<double>(input_views),
               vt = static_cast<double>(target_views);
  FlopCount f;
  f.dinov2 = b * (vi + vt) * s.dino_image;                                // the estimator reads the target images too
  const int64_t scene = L + (c.keep_image_tokens ? input_views * n : 0);  // what estimator and decoder attend to
  f.encoder = b * transformer_stack_flops(t.encoder_n_layer, L + input_views * n, scene, t.d, 4 * t.d);
  f.estimator = b * vt * transformer_stack_flops(t.estimator_n_layer, n + scene, n, t.d, 4 * t.d);
  f.decoder = b * vt * transformer_stack_flops(t.decoder_n_layer, n + scene, n, t.d, 4 * t.d);
  const double pose_heads = 2.0 * 2 * (t.d * (t.d / 2.0) + (t.d / 2.0) * 3.5);
  f.other = b * (s.plucker_tokens + vt * (s.plucker_tokens + s.rgb_head + pose_heads));  // marker on view 0
  if (c.encoder_latent_cameras && input_views > 1) {  // the inputs' latent cameras, then the encoder again
    const double posed = vi - 1.0;
    f.encoder *= 2.0;
    f.estimator += b * posed * transformer_stack_flops(t.estimator_n_layer, n + scene, n, t.d, 4 * t.d);
    f.other += b * (vi * s.plucker_tokens + posed * pose_heads);
  }
  return f;
}

FlopCount posed_lvsm_forward_flops(const ModelConfig& c, int64_t batch, int64_t input_views, int64_t target_views,
                                   int64_t posed_input_views) {
  const auto& t = c.transformer;
  const auto s = shared_flops(c);
  const double b = static_cast<double>(batch), vt = static_cast<double>(target_views);
  FlopCount f;
  f.dinov2 = b * static_cast<double>(input_views) * s.dino_image;
  // Decoder-only: every target attends to all input tokens and its own pose tokens.
  f.decoder = b * vt * transformer_stack_flops(t.n_layer, input_views * s.n + s.n, s.n, t.d, 4 * t.d);
  f.other = b * (static_cast<double>(posed_input_views) * s.plucker_tokens + vt * (s.plucker_tokens + s.rgb_head));
  return f;
}

FlopCount forward_flops(const ModelConfig& config, int64_t batch, int64_t input_views, int64_t target_views) {
  if (config.variant == Variant::UPLVSM) return uplvsm_forward_flops(config, batch, input_views, target_views);
  const int64_t posed = model::posed_inputs(config.variant) == model::PosedInputs::All ? input_views : 1;
  return posed_lvsm_forward_flops(config, batch, input_views, target_views, posed);
}

}  // namespace uplvsm::train
