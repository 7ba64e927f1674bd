#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/camera_control.h"

using namespace uplvsm;

namespace {
// Random rigid cameras [b, v, 4, 4].
torch::Tensor random_cameras(int64_t b, int64_t v) {
  auto q = torch::randn({b, v, 4}, torch::kFloat64);
  q = q / q.norm(2, -1, true);
  auto t = torch::randn({b, v, 3}, torch::kFloat64) * 2;
  return geometry::pose_encoding_to_c2w(torch::cat({t, q}, -1));
}
}  // namespace

TEST(CameraControlPoses, FirstInputIsTheIdentityAndInputOneAtUnitDistance) {
  torch::manual_seed(0);
  auto inputs = random_cameras(3, 2);
  auto poses = geometry::camera_control_poses(inputs, inputs);
  ASSERT_EQ(poses.sizes(), (std::vector<int64_t>{3, 2, 7}));
  auto identity = torch::tensor({0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0}, torch::kFloat32);
  EXPECT_LT(test::max_abs_diff(poses.select(1, 0), identity.expand({3, 7})), 1e-5);
  auto baseline = poses.select(1, 1).narrow(-1, 0, 3).norm(2, -1);
  EXPECT_LT(test::max_abs_diff(baseline, torch::ones({3})), 1e-5);
}

TEST(CameraControlPoses, InvariantToAGlobalRigidTransformAndScale) {
  torch::manual_seed(1);
  auto inputs = random_cameras(2, 2), targets = random_cameras(2, 4);
  auto world = random_cameras(1, 1).view({1, 1, 4, 4});  // a new world frame...
  auto moved = [&](torch::Tensor c2w) {
    c2w = torch::matmul(world, c2w).clone();
    c2w.index({"...", torch::indexing::Slice(0, 3), 3}).mul_(3.7);  // ... in other units
    return c2w;
  };
  auto a = geometry::camera_control_poses(inputs, targets);
  auto b = geometry::camera_control_poses(moved(inputs), moved(targets));
  EXPECT_LT(test::max_abs_diff(a, b), 1e-4);
}

TEST(CameraControlPoses, WorldCamerasFromPosesInvertThem) {
  torch::manual_seed(2);
  for (int64_t vi : {1, 2}) {
    auto inputs = random_cameras(2, vi), targets = random_cameras(2, 4);
    auto poses = geometry::camera_control_poses(inputs, targets);
    auto world = geometry::camera_control_to_world(inputs, poses);
    ASSERT_EQ(world.sizes(), (std::vector<int64_t>{2, 4, 4, 4}));
    EXPECT_LE(test::max_abs_diff(world, targets.to(torch::kFloat32)), 1e-4) << vi << " input views";
  }
}

TEST(CameraControlPoses, RejectsNonFiniteCameras) {
  auto c = random_cameras(1, 2);
  c[0][1][0][3] = std::nan("");
  EXPECT_NE(test::error_of([&] { geometry::camera_control_poses(c, c); }).find("NaN"), std::string::npos);
}
