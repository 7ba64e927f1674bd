#include "uplvsm/study/tsne.h"

#include <cmath>

#include "uplvsm/io/raster.h"

namespace uplvsm::study {

namespace {

torch::Tensor squared_distances(const torch::Tensor& x) {
  auto sq = x.pow(2).sum(1, true);
  return (sq + sq.t() - 2 * torch::matmul(x, x.t())).clamp_min(0);
}

io::Rgb hue(double h) {  // h in [0, 1): a saturated colour wheel
  const double r = 0.5 + 0.5 * std::cos(2 * M_PI * h), g = 0.5 + 0.5 * std::cos(2 * M_PI * (h - 1.0 / 3)),
               b = 0.5 + 0.5 * std::cos(2 * M_PI * (h - 2.0 / 3));
  auto u8 = [](double v) { return static_cast<uint8_t>(std::lround(40 + 180 * v)); };
  return {u8(r), u8(g), u8(b)};
}

}  // namespace

torch::Tensor conditional_affinities(const torch::Tensor& d2, double perplexity) {
  const int64_t n = d2.size(0);
  const double target = std::log(perplexity);
  auto beta = torch::ones({n, 1}, d2.options());
  auto lo = torch::full({n, 1}, 0.0, d2.options()), hi = torch::full({n, 1}, INFINITY, d2.options());
  auto off_diagonal = 1 - torch::eye(n, d2.options());
  // Distances relative to each row's nearest neighbour keep exp() in range whatever the scale.
  auto d = d2 - std::get<0>((d2 + torch::eye(n, d2.options()) * 1e300).min(1, true));
  torch::Tensor p;
  for (int it = 0; it < 100; ++it) {
    p = torch::exp(-d * beta) * off_diagonal;
    auto sum = p.sum(1, true).clamp_min(1e-300);
    auto entropy = torch::log(sum) + beta * (d * p).sum(1, true) / sum;
    auto too_flat = entropy > target;  // entropy too high: sharpen (raise beta)
    lo = torch::where(too_flat, beta, lo);
    hi = torch::where(too_flat, hi, beta);
    beta = torch::where(torch::isinf(hi), beta * 2, (lo + hi) / 2);
    if ((entropy - target).abs().max().item<double>() < 1e-6) break;
  }
  return p / p.sum(1, true).clamp_min(1e-300);
}

TsneResult tsne(const torch::Tensor& points, const TsneOptions& o) {
  TORCH_CHECK(points.dim() == 2 && points.size(0) >= 4, "t-SNE: need [N >= 4, D] points, got ", points.sizes());
  auto x = points.to(torch::kFloat64);
  TORCH_CHECK(torch::isfinite(x).all().item<bool>(), "t-SNE: the points contain NaN or Inf");
  const int64_t n = x.size(0);
  const double perplexity = std::min(o.perplexity, (static_cast<double>(n) - 1) / 3);
  auto p = conditional_affinities(squared_distances(x), perplexity);
  p = ((p + p.t()) / (2.0 * static_cast<double>(n))).clamp_min(1e-12);
  const double lr = o.learning_rate > 0 ? o.learning_rate : std::max(static_cast<double>(n) / o.exaggeration / 4, 50.0);
  torch::manual_seed(o.seed);
  auto y = torch::randn({n, 2}, torch::kFloat64) * 1e-4;
  auto update = torch::zeros_like(y), gains = torch::ones_like(y);
  auto off_diagonal = 1 - torch::eye(n, torch::kFloat64);
  torch::Tensor q;
  for (int64_t it = 0; it < o.iterations; ++it) {
    const bool early = it < o.exaggeration_iterations;
    auto num = off_diagonal / (1 + squared_distances(y));
    q = (num / num.sum()).clamp_min(1e-12);
    auto pq = ((early ? o.exaggeration : 1.0) * p - q) * num;
    auto grad = 4 * (torch::diag(pq.sum(1)) - pq).matmul(y);
    auto same_sign = (grad > 0) == (update > 0);
    gains = torch::where(same_sign, gains * 0.8, gains + 0.2).clamp_min(0.01);
    update = (early ? 0.5 : 0.8) * update - lr * gains * grad;
    y = y + update;
    y = y - y.mean(0, true);
  }
  return {y, (p * torch::log(p / q)).sum().item<double>()};
}

torch::Tensor pose_pair_figure(const torch::Tensor& embedding, const std::string& title, int size) {
  TORCH_CHECK(embedding.dim() == 2 && embedding.size(1) == 2 && embedding.size(0) % 2 == 0,
              "pose_pair_figure: expected [2N, 2], got ", embedding.sizes());
  const int64_t pairs = embedding.size(0) / 2;
  auto img = io::blank_image(size, size);
  const int margin = 40;
  auto lo = std::get<0>(embedding.min(0)), hi = std::get<0>(embedding.max(0));
  auto span = (hi - lo).clamp_min(1e-9);
  auto xy = ((embedding - lo) / span * (size - 2 * margin) + margin).contiguous();
  auto a = xy.accessor<double, 2>();
  for (int64_t i = 0; i < pairs; ++i) {
    const auto colour = hue(static_cast<double>(i) / static_cast<double>(std::max<int64_t>(1, pairs)));
    io::fill_rect(img, static_cast<int>(a[i][0]) - 3, static_cast<int>(a[i][1]) - 3, 7, 7, colour);  // latent
    io::draw_rect(img, static_cast<int>(a[pairs + i][0]) - 4, static_cast<int>(a[pairs + i][1]) - 4, 9, 9, colour);
  }
  io::draw_text(img, 10, 8, title, {0, 0, 0}, 2);
  io::draw_text(img, 10, size - 18, "filled: latent pose   outlined: real pose   same colour: same view", {60, 60, 60});
  return img;
}

}  // namespace uplvsm::study
