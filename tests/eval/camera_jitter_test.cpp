// The camera path `eval --jitter` renders (the wobble measure itself: picture_motion_test.cpp).
#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/eval/camera_jitter.h"

using namespace uplvsm;

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
