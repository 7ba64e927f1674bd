#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/eval/camera_jitter.h"

using namespace uplvsm;

namespace {
// A smooth "camera path": a gradient sliding one pixel per frame.
torch::Tensor sliding_gradient(int64_t frames) {
  auto x = torch::arange(64, torch::kFloat64).view({1, 1, 1, 64});
  auto t = torch::arange(frames, torch::kFloat64).view({-1, 1, 1, 1});
  return (torch::sin((x + t) / 10.0) * 0.4 + 0.5).expand({frames, 3, 16, 64}).contiguous();
}
}  // namespace

TEST(CameraJitter, TheTruthItselfAndAnErrorThatStaysPutHaveNone) {
  auto truth = sliding_gradient(10);
  EXPECT_NEAR(eval::temporal_jitter(truth, truth), 0.0, 1e-9);
  EXPECT_NEAR(eval::temporal_jitter(truth + 0.1, truth), 0.0, 1e-9);             // a colour cast
  // A contrast change scales with the truth's own change: 20% less contrast, 20% of its frame-to-frame change.
  const double change = eval::temporal_jitter(torch::zeros_like(truth), truth);
  EXPECT_GT(change, 1.0);
  EXPECT_NEAR(eval::temporal_jitter(truth * 0.8 + 0.05, truth), 0.2 * change, 1e-9);
}

TEST(CameraJitter, IndependentNoiseOfSdSigmaGivesSigmaRootTwo) {
  torch::manual_seed(4);
  auto truth = sliding_gradient(40);
  const double sigma = 0.02;
  auto noisy = truth + sigma * torch::randn(truth.sizes(), torch::kFloat64);
  EXPECT_NEAR(eval::temporal_jitter(noisy, truth), sigma * std::sqrt(2.0) * 255, 0.02 * 255 * sigma);
}

TEST(CameraJitter, ARenderThatAlternatesByDeltaGivesTwoDelta) {
  auto truth = sliding_gradient(9);
  auto sign = (torch::arange(9) % 2 * 2 - 1).to(torch::kFloat64).view({-1, 1, 1, 1});
  const double delta = 0.01;
  EXPECT_NEAR(eval::temporal_jitter(truth + delta * sign, truth), 2 * delta * 255, 1e-9);
  // A render that lags the path by one frame everywhere is off in every frame, yet moves as the truth does.
  auto lagging = torch::cat({truth.narrow(0, 0, 1), truth.narrow(0, 0, 8)});
  EXPECT_LT(eval::temporal_jitter(lagging, truth), eval::temporal_jitter(truth + delta * sign, truth));
  EXPECT_NE(test::error_of([&] { eval::temporal_jitter(truth.narrow(0, 0, 1), truth.narrow(0, 0, 1)); })
                .find("T >= 2"),
            std::string::npos);
}
