#include "uplvsm/study/attention_map.h"

#include <algorithm>

#include <fmt/format.h>

#include "uplvsm/core/eval_mode.h"
#include "uplvsm/io/raster.h"

namespace uplvsm::study {

using torch::indexing::Slice;

CrossViewAttention cross_view_attention(model::UPLVSM& net, const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                                        int64_t row, int64_t col) {
  TORCH_CHECK(images.dim() == 4 && images.size(0) == 2 && images.size(1) == 3,
              "study attention: expected two input images [2, 3, H, W], got ", images.sizes());
  const int64_t p = net->config.patch_size, gh = images.size(2) / p, gw = images.size(3) / p;
  TORCH_CHECK(row >= 0 && row < gh && col >= 0 && col < gw, "study attention: patch (", row, ", ", col,
              ") is outside view 1's ", gh, "x", gw, " patch grid");
  torch::NoGradGuard no_grad;
  EvalModeGuard mode(*net);
  model::ForwardTrace trace;
  net->encode_scene(images.unsqueeze(0), fxfycxcy.unsqueeze(0), &trace);
  // Replay the encoder up to its last block, whose attention probabilities are the figure's.
  auto h = trace.encoder_input;
  auto stack = net->transformer_encoder;
  for (size_t i = 0; i + 1 < stack->size(); ++i) h = stack[i]->as<model::TransformerBlockImpl>()->forward(h);
  auto* last = stack[stack->size() - 1]->as<model::TransformerBlockImpl>();
  auto probs = last->attn->attention_map(last->norm1->forward(h))[0];  // [N, N], head-mean
  const int64_t L = net->n_light_field_latent.size(0), n = gh * gw;
  TORCH_CHECK(probs.size(0) == L + 2 * n, "study attention: token count ", probs.size(0), " != ", L + 2 * n);
  const int64_t query = L + row * gw + col;
  CrossViewAttention out;
  out.row = row;
  out.col = col;
  out.attention = probs[query].index({Slice(L + n, L + 2 * n)}).reshape({gh, gw}).to(torch::kFloat32).cpu();
  auto tokens = torch::nn::functional::normalize(trace.input_dino_tokens[0].to(torch::kFloat32),
                                                 torch::nn::functional::NormalizeFuncOptions().dim(-1));
  out.similarity = tokens[1].matmul(tokens[0][row * gw + col]).reshape({gh, gw}).cpu();
  return out;
}

torch::Tensor heat_colours(const torch::Tensor& values) {
  auto v = values.to(torch::kFloat32).clamp(0, 1);
  // Piecewise-linear ramp through (0,0,0.5) (0,1,1) (1,1,0) (1,0,0) at 0, 1/3, 2/3, 1.
  auto r = (v * 3 - 1).clamp(0, 1);
  auto g = torch::minimum((v * 3 - 0.0).clamp(0, 1) * 1.0, (3 - v * 3).clamp(0, 1));
  auto b = torch::where(v < 1.0 / 3, 0.5 + v * 1.5, (2 - v * 3).clamp(0, 1));
  return torch::stack({r, g, b});
}

namespace {

torch::Tensor upscale(const torch::Tensor& chw, int64_t height, int64_t width) {
  return torch::nn::functional::interpolate(chw.unsqueeze(0), torch::nn::functional::InterpolateFuncOptions()
                                                                  .size(std::vector<int64_t>{height, width})
                                                                  .mode(torch::kNearest))[0];
}

// The view under a heat map of `values`, stretched to their own range (the figure shows where, not how much), HWC.
torch::Tensor overlay(const torch::Tensor& image, const torch::Tensor& values, int64_t height, int64_t width) {
  auto lo = values.min(), hi = values.max();
  auto normalised = (values - lo) / (hi - lo).clamp_min(1e-12);
  auto heat = upscale(heat_colours(normalised), height, width);
  return io::to_hwc_u8(0.45 * upscale(image, height, width) + 0.55 * heat);
}

}  // namespace

torch::Tensor attention_figure(const torch::Tensor& images, const CrossViewAttention& result, int panel) {
  auto imgs = images.to(torch::kFloat32).cpu();
  const int64_t H = imgs.size(2), W = imgs.size(3);
  const int64_t scale = std::max<int64_t>(1, (panel + W - 1) / W);
  const int64_t h = H * scale, w = W * scale;
  auto view1 = io::to_hwc_u8(upscale(imgs[0], h, w));
  const int64_t gh = result.attention.size(0), gw = result.attention.size(1);
  const int box_w = static_cast<int>(w / gw), box_h = static_cast<int>(h / gh);
  io::draw_rect(view1, static_cast<int>(result.col * box_w), static_cast<int>(result.row * box_h), box_w, box_h,
                {255, 40, 40}, 3);
  auto attention = overlay(imgs[1], result.attention, h, w);
  auto similarity = overlay(imgs[1], result.similarity, h, w);
  return io::make_grid({{view1, attention, similarity}}, {},
                       {fmt::format("view 1, patch ({}, {})", result.row, result.col), "view 2: attention",
                        "view 2: feature similarity"});
}

}  // namespace uplvsm::study
