// Tests of eval/metrics: PSNR and SSIM against scikit-image 0.19.3 reference values (fixtures/ssim_psnr), batching,
// the perfect-prediction case, scipy 'reflect' padding and the Gaussian window.
#include "uplvsm/eval/metrics.h"

#include <gtest/gtest.h>

#include <fstream>

#include <nlohmann/json.hpp>

#include "test_util.h"
#include "uplvsm/io/safetensors.h"

namespace uplvsm::eval {
namespace {

struct Pair {
  torch::Tensor gt, pred;
  double psnr, ssim, ssim_f64;
};

std::vector<Pair> fixture_pairs() {
  auto tensors = io::read_safetensors(test::fixture("ssim_psnr/pairs.safetensors")).tensors;
  std::ifstream f(test::fixture("ssim_psnr/values.json"));
  auto values = nlohmann::json::parse(f);
  std::vector<Pair> pairs;
  for (const auto& v : values["pairs"]) {
    const int i = v["pair"].get<int>();
    pairs.push_back({tensors.at("pair" + std::to_string(i) + ".gt"), tensors.at("pair" + std::to_string(i) + ".pred"),
                     v["psnr"].get<double>(), v["ssim"].get<double>(), v["ssim_f64"].get<double>()});
  }
  return pairs;
}

TEST(Metrics, PsnrMatchesReference) {
  UPLVSM_NEEDS_FIXTURES();
  for (const auto& p : fixture_pairs()) {
    auto value = psnr(p.pred, p.gt);
    EXPECT_EQ(value.dim(), 0);
    EXPECT_EQ(value.scalar_type(), torch::kFloat64);
    EXPECT_NEAR(value.item<double>(), p.psnr, 1e-9);
  }
}

TEST(Metrics, SsimMatchesScikitImageFloat32) {
  UPLVSM_NEEDS_FIXTURES();
  double worst = 0;
  for (const auto& p : fixture_pairs()) {
    ASSERT_EQ(p.pred.scalar_type(), torch::kFloat32);
    const double got = ssim(p.pred, p.gt).item<double>();
    worst = std::max(worst, std::abs(got - p.ssim));
    EXPECT_NEAR(got, p.ssim, 1e-6);
  }
  RecordProperty("max_abs_err_f32", fmt::format("{:.3e}", worst));
}

TEST(Metrics, SsimMatchesScikitImageFloat64) {
  UPLVSM_NEEDS_FIXTURES();
  for (const auto& p : fixture_pairs()) {
    const double got = ssim(p.pred.to(torch::kFloat64), p.gt.to(torch::kFloat64)).item<double>();
    EXPECT_NEAR(got, p.ssim_f64, 1e-9);
  }
}

TEST(Metrics, BatchedShapesGiveTheSameValues) {
  UPLVSM_NEEDS_FIXTURES();
  auto pairs = fixture_pairs();
  // Pairs 0-2 are 64x64: [3] and [1, 3] leading shapes.
  auto pred = torch::stack({pairs[0].pred, pairs[1].pred, pairs[2].pred});
  auto gt = torch::stack({pairs[0].gt, pairs[1].gt, pairs[2].gt});
  auto s = ssim(pred.unsqueeze(0), gt.unsqueeze(0));
  auto q = psnr(pred.unsqueeze(0), gt.unsqueeze(0));
  ASSERT_EQ(s.sizes(), (std::vector<int64_t>{1, 3}));
  ASSERT_EQ(q.sizes(), (std::vector<int64_t>{1, 3}));
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(s[0][i].item<double>(), ssim(pairs[i].pred, pairs[i].gt).item<double>(), 1e-12);
    EXPECT_NEAR(q[0][i].item<double>(), pairs[i].psnr, 1e-9);
  }
}

TEST(Metrics, PerfectPredictionIsFinite) {
  auto img = torch::rand({2, 3, 16, 20});
  auto q = psnr(img, img);
  EXPECT_TRUE(torch::allclose(q, torch::full({2}, 100.0, torch::kFloat64)));  // mse clamped at 1e-10
  EXPECT_TRUE(torch::allclose(ssim(img, img), torch::ones({2}, torch::kFloat64), 0, 1e-6));
}

TEST(Metrics, PsnrClampsToUnitRange) {
  auto gt = torch::full({3, 8, 8}, 0.5);
  auto pred = torch::full({3, 8, 8}, 2.0);  // clamped to 1: mse 0.25
  EXPECT_NEAR(psnr(pred, gt).item<double>(), -10 * std::log10(0.25), 1e-9);
}

TEST(Metrics, RejectsBadInputs) {
  EXPECT_THROW(psnr(torch::rand({3, 8, 8}), torch::rand({3, 8, 9})), std::runtime_error);
  EXPECT_THROW(ssim(torch::rand({3, 10, 20}), torch::rand({3, 10, 20})), std::runtime_error);  // < 11 rows
}

TEST(Metrics, ReflectPaddingRepeatsTheEdge) {
  auto x = torch::tensor({0.0, 1.0, 2.0}, torch::kFloat64).view({1, 3});
  auto padded = reflect_pad2d(x, 5);
  // scipy 'reflect' of [a b c] by 5: b c c b a | a b c | c b a a b
  auto expected = torch::tensor({1.0, 2.0, 2.0, 1.0, 0.0, 0.0, 1.0, 2.0, 2.0, 1.0, 0.0, 0.0, 1.0}).view({1, 13});
  EXPECT_EQ(padded.sizes(), (std::vector<int64_t>{11, 13}));  // one row padded to 11 copies of itself
  EXPECT_TRUE(torch::equal(padded[0].unsqueeze(0), expected));
  EXPECT_TRUE(torch::equal(padded[10].unsqueeze(0), expected));
}

TEST(Metrics, GaussianWindow) {
  auto w = gaussian_window();
  ASSERT_EQ(w.numel(), 11);
  EXPECT_NEAR(w.sum().item<double>(), 1.0, 1e-15);
  EXPECT_TRUE(torch::equal(w, w.flip(0)));
  EXPECT_NEAR(w[5].item<double>() / w[0].item<double>(), std::exp(25.0 / (2 * 2.25)), 1e-9);
}

// The gradient energy written out pixel by pixel (an independent computation of the definition in metrics.h).
double gradient_energy_by_loops(const torch::Tensor& image) {
  auto x = image.to(torch::kFloat64).clamp(0.0, 1.0).contiguous();
  auto a = x.accessor<double, 3>();
  const int64_t C = x.size(0), H = x.size(1), W = x.size(2);
  double sum = 0;
  for (int64_t c = 0; c < C; ++c)
    for (int64_t y = 0; y < H; ++y)
      for (int64_t i = 0; i < W; ++i) {
        if (i + 1 < W) sum += std::abs(a[c][y][i + 1] - a[c][y][i]);
        if (y + 1 < H) sum += std::abs(a[c][y + 1][i] - a[c][y][i]);
      }
  return sum / static_cast<double>(C * H * (W - 1) + C * (H - 1) * W);
}

TEST(Metrics, GradientEnergyRatioMatchesThePixelLoop) {
  torch::manual_seed(3);
  auto gt = torch::rand({2, 3, 3, 9, 7}) * 1.2 - 0.1;  // some values outside [0, 1]: clamped first
  auto pred = torch::rand({2, 3, 3, 9, 7});
  auto ratio = gradient_energy_ratio(pred, gt);
  ASSERT_EQ(ratio.sizes(), (std::vector<int64_t>{2, 3}));
  EXPECT_EQ(ratio.scalar_type(), torch::kFloat64);
  for (int64_t b = 0; b < 2; ++b)
    for (int64_t v = 0; v < 3; ++v)
      EXPECT_NEAR(ratio[b][v].item<double>(), gradient_energy_by_loops(pred[b][v]) / gradient_energy_by_loops(gt[b][v]),
                  1e-12);
}

TEST(Metrics, GradientEnergyRatioOfKnownImages) {
  // A vertical edge 0 | 1 in a 1-channel 4x4 image: 4 of the 12 x-differences are 1, no y-difference.
  auto edge = torch::zeros({1, 4, 4});
  edge.narrow(2, 2, 2).fill_(1.0);
  EXPECT_NEAR(gradient_energy(edge).item<double>(), 4.0 / 24.0, 1e-15);
  EXPECT_NEAR(gradient_energy_ratio(edge, edge).item<double>(), 1.0, 1e-15);
  EXPECT_NEAR(gradient_energy_ratio(edge * 0.5, edge).item<double>(), 0.5, 1e-15);  // half the contrast
  EXPECT_NEAR(gradient_energy_ratio(torch::full({1, 4, 4}, 0.3), edge).item<double>(), 0.0, 1e-15);  // flat
  // A flat truth is floored, so the ratio stays finite.
  const double flat = gradient_energy_ratio(edge, torch::full({1, 4, 4}, 0.3)).item<double>();
  EXPECT_NEAR(flat, (4.0 / 24.0) / kMinGradientEnergy, 1e-6);
  EXPECT_THROW(gradient_energy_ratio(torch::rand({3, 1, 8}), torch::rand({3, 1, 8})), std::runtime_error);
}

TEST(Metrics, CudaMatchesCpu) {
  UPLVSM_NEEDS_FIXTURES();
  if (!torch::cuda::is_available()) GTEST_SKIP() << "no CUDA device";
  auto pairs = fixture_pairs();
  for (const auto& p : pairs) {
    auto pred = p.pred.cuda(), gt = p.gt.cuda();
    EXPECT_TRUE(ssim(pred, gt).is_cuda());
    EXPECT_NEAR(ssim(pred, gt).item<double>(), p.ssim, 1e-6);
    EXPECT_NEAR(psnr(pred, gt).item<double>(), p.psnr, 1e-9);
  }
}

}  // namespace
}  // namespace uplvsm::eval
