#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/eval/camera_jitter.h"

using namespace uplvsm;

namespace {
// A steady "camera path": a gradient sliding by `step` pixels per frame.
torch::Tensor sliding_gradient(int64_t frames, double step = 0.25) {
  auto x = torch::arange(64, torch::kFloat64).view({1, 1, 1, 64});
  auto t = torch::arange(frames, torch::kFloat64).view({-1, 1, 1, 1});
  return (torch::sin((x + step * t) / 10.0) * 0.4 + 0.5).expand({frames, 3, 16, 64}).contiguous();
}
}  // namespace

TEST(CameraJitter, AStillOrSteadilyChangingSequenceHasNone) {
  EXPECT_EQ(eval::temporal_jitter(torch::full({5, 3, 8, 8}, 0.3, torch::kFloat64)), 0.0);
  auto t = torch::arange(10, torch::kFloat64).view({-1, 1, 1, 1});
  EXPECT_NEAR(eval::temporal_jitter(0.2 + 0.01 * t.expand({10, 3, 8, 8})), 0.0, 1e-9);  // a steady fade
  EXPECT_NEAR(eval::temporal_change(0.2 + 0.01 * t.expand({10, 3, 8, 8})), 0.01 * 255, 1e-9);
  EXPECT_LT(eval::temporal_jitter(sliding_gradient(12)), 0.05);  // a steady slide
  // A change half as large is not steadier: the same slide at half the contrast, the same jitter.
  EXPECT_NEAR(eval::temporal_jitter(sliding_gradient(12, 0.5)),
              eval::temporal_jitter(0.5 + 0.5 * (sliding_gradient(12, 0.5) - 0.5)), 1e-9);
}

TEST(CameraJitter, NoiseGivesRootThreeAndARenderAlternatingBetweenTwoImagesTwo) {
  torch::manual_seed(4);
  auto noise = torch::randn({400, 3, 8, 8}, torch::kFloat64) * 0.02 + 0.5;
  EXPECT_NEAR(eval::temporal_jitter(noise), std::sqrt(3.0), 0.03);
  auto sign = (torch::arange(9) % 2 * 2 - 1).to(torch::kFloat64).view({-1, 1, 1, 1});
  EXPECT_NEAR(eval::temporal_jitter(0.5 + 0.01 * sign.expand({9, 3, 4, 4})), 2.0, 1e-9);
  // A slide that wobbles, every other frame two steps on instead of a quarter, against the steady one.
  auto wobbling = torch::stack({sliding_gradient(9)[0], sliding_gradient(9, 2.0)[1], sliding_gradient(9)[2],
                                sliding_gradient(9, 2.0)[3], sliding_gradient(9)[4]});
  EXPECT_GT(eval::temporal_jitter(wobbling), 20 * eval::temporal_jitter(sliding_gradient(5)));
  EXPECT_NE(test::error_of([&] { eval::temporal_jitter(noise.narrow(0, 0, 2)); }).find("T >= 3"), std::string::npos);
}

TEST(CameraJitter, APathIsCutIntoStepsBetweenItsFrames) {
  auto q1 = torch::tensor({0.0, std::sin(0.2), 0.0, std::cos(0.2)});
  auto poses = torch::stack({torch::tensor({0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0}),
                             torch::cat({torch::tensor({1.0, 0.0, 2.0}), q1})})
                   .unsqueeze(0)
                   .to(torch::kFloat32);
  auto path = eval::subdivide_path(poses, 4);
  ASSERT_EQ(path.size(1), 5);
  EXPECT_LT(test::max_abs_diff(path[0][0], poses[0][0]), 1e-6);
  EXPECT_LT(test::max_abs_diff(path[0][4], poses[0][1]), 1e-6);
  EXPECT_LT(test::max_abs_diff(path[0][2].slice(0, 0, 3), torch::tensor({0.5, 0.0, 1.0})), 1e-6);
  // Half way, half the turn: 0.2 rad of half-angle -> 0.1.
  EXPECT_NEAR(path[0][2][4].item<double>(), std::sin(0.1), 1e-5);  // q_y
  EXPECT_NEAR(path[0][2].slice(0, 3).norm().item<double>(), 1.0, 1e-6);
}
