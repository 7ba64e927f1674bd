#include <gtest/gtest.h>

#include <cmath>

#include "test_util.h"
#include "uplvsm/render/trajectory.h"

using namespace uplvsm;

TEST(Trajectory, EndpointsLinearTranslationAndSlerp) {
  double s = std::sqrt(0.5);
  auto keys = torch::tensor({{0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0}, {2.0, 0.0, -4.0, 0.0, 0.0, s, s}}, torch::kFloat64);
  auto path = render::interpolate_poses(keys, 5);
  ASSERT_EQ(path.sizes(), (std::vector<int64_t>{5, 7}));
  EXPECT_LE(test::max_abs_diff(path[0], keys[0]), 1e-12);
  EXPECT_LE(test::max_abs_diff(path[4], keys[1]), 1e-12);
  EXPECT_NEAR(path[2][0].item<double>(), 1.0, 1e-12);  // halfway in translation
  EXPECT_NEAR(path[2][2].item<double>(), -2.0, 1e-12);
  EXPECT_NEAR(path[2][5].item<double>(), std::sin(M_PI / 8), 1e-12);  // 45 of 90 degrees
}

TEST(Trajectory, SegmentsRepeatTheirBoundaries) {
  auto keys = torch::zeros({3, 7});
  keys.select(1, 6).fill_(1.0);
  keys[1][0] = 1.0;
  keys[2][0] = 3.0;
  auto path = render::interpolate_poses(keys, 4);
  ASSERT_EQ(path.size(0), 8);  // (K - 1) * frames, both ends included per segment (official render_video)
  EXPECT_FLOAT_EQ(path[3][0].item<float>(), 1.0f);
  EXPECT_FLOAT_EQ(path[4][0].item<float>(), 1.0f);
  auto k = render::interpolate_intrinsics(torch::tensor({{10.0, 10.0, 5.0, 5.0}, {20.0, 20.0, 5.0, 5.0}}), 3);
  EXPECT_FLOAT_EQ(k[1][0].item<float>(), 15.0f);
}

TEST(Trajectory, RejectsBadShapes) {
  EXPECT_THROW(render::interpolate_poses(torch::zeros({1, 7}), 4), c10::Error);
  EXPECT_THROW(render::interpolate_poses(torch::zeros({2, 6}), 4), c10::Error);
}
