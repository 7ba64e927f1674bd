#include <gtest/gtest.h>

#include <cmath>

#include "test_util.h"
#include "uplvsm/study/tsne.h"

using namespace uplvsm;

TEST(Tsne, AffinitiesHaveThePerplexityAsked) {
  torch::manual_seed(0);
  auto x = torch::randn({60, 7}, torch::kFloat64) * 3;
  auto sq = x.pow(2).sum(1, true);
  auto d2 = (sq + sq.t() - 2 * x.matmul(x.t())).clamp_min(0);
  auto p = study::conditional_affinities(d2, 10.0);
  EXPECT_LE((p.sum(1) - 1).abs().max().item<double>(), 1e-9);
  EXPECT_LE(p.diagonal().abs().max().item<double>(), 0.0);
  auto entropy = -(p * torch::log(p.clamp_min(1e-300))).sum(1);
  EXPECT_LE((entropy - std::log(10.0)).abs().max().item<double>(), 1e-4);
}

TEST(Tsne, SeparatesTwoClustersAndKeepsNeighbours) {
  torch::manual_seed(1);
  auto a = torch::randn({30, 7}, torch::kFloat64), b = torch::randn({30, 7}, torch::kFloat64) + 8;
  auto x = torch::cat({a, b});
  study::TsneOptions o;
  o.perplexity = 10;
  o.iterations = 500;
  auto r = study::tsne(x, o);
  ASSERT_EQ(r.embedding.sizes(), (std::vector<int64_t>{60, 2}));
  EXPECT_TRUE(torch::isfinite(r.embedding).all().item<bool>());
  EXPECT_GT(r.kl_divergence, 0);
  auto y = r.embedding;
  auto sq = y.pow(2).sum(1, true);
  auto d = (sq + sq.t() - 2 * y.matmul(y.t())) + torch::eye(60, torch::kFloat64) * 1e9;
  auto nearest = d.argmin(1);
  int same = 0;
  for (int64_t i = 0; i < 60; ++i) same += (i < 30) == (nearest[i].item<int64_t>() < 30);
  EXPECT_GE(same, 58);
  auto ca = y.slice(0, 0, 30).mean(0), cb = y.slice(0, 30).mean(0);
  const double spread = (y.slice(0, 0, 30) - ca).norm(2, 1).mean().item<double>();
  EXPECT_GT((ca - cb).norm().item<double>(), 1.5 * spread);
  EXPECT_THROW(study::tsne(torch::zeros({3, 2})), c10::Error);
}

TEST(Tsne, PosePairFigureDrawsEveryPair) {
  auto emb = torch::tensor({{0.0, 0.0}, {1.0, 1.0}, {0.1, 0.0}, {0.9, 1.0}}, torch::kFloat64);
  auto img = study::pose_pair_figure(emb, "t-SNE", 300);
  ASSERT_EQ(img.sizes(), (std::vector<int64_t>{300, 300, 3}));
  // Coloured (non-grey) pixels exist: the markers.
  auto f = img.to(torch::kInt32);
  auto chroma = std::get<0>(f.max(2)) - std::get<0>(f.min(2));
  EXPECT_GT((chroma > 50).sum().item<int64_t>(), 40);
  EXPECT_THROW(study::pose_pair_figure(torch::zeros({3, 2}), "x"), c10::Error);
}
