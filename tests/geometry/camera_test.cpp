#include <gtest/gtest.h>

#include <cmath>

#include "test_util.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/quaternion.h"

using namespace uplvsm;

TEST(Quaternion, ScalarLastConvention) {
  // 90 degrees about z: q = (0, 0, sin 45, cos 45) in (x, y, z, w).
  double s = std::sqrt(0.5);
  auto R = geometry::quat_to_rotation(torch::tensor({0.0, 0.0, s, s}, torch::kFloat64));
  auto expected = torch::tensor({{0.0, -1.0, 0.0}, {1.0, 0.0, 0.0}, {0.0, 0.0, 1.0}}, torch::kFloat64);
  EXPECT_LE(test::max_abs_diff(R, expected), 1e-12);
}

TEST(Quaternion, NonUnitQuaternionGivesRotation) {
  auto q = torch::tensor({0.3, -0.2, 0.5, 2.0}, torch::kFloat64);  // official quat_to_mat: s = 2 / |q|^2
  auto R = geometry::quat_to_rotation(q);
  EXPECT_LE(test::max_abs_diff(torch::matmul(R, R.t()), torch::eye(3, torch::kFloat64)), 1e-12);
}

TEST(Quaternion, RoundTripWithPositiveW) {
  torch::manual_seed(3);
  auto q = torch::randn({64, 4}, torch::kFloat64);
  q = q / q.norm(2, -1, true);
  auto back = geometry::rotation_to_quat(geometry::quat_to_rotation(q));
  auto sign = torch::where(q.select(1, 3) < 0, -torch::ones({64}, torch::kFloat64), torch::ones({64}, torch::kFloat64));
  EXPECT_LE(test::max_abs_diff(back, q * sign.unsqueeze(1)), 1e-9);
  EXPECT_TRUE((back.select(1, 3) >= 0).all().item<bool>());
}

// The product composes rotations in the first one's frame, for non-unit quaternions too (lengths multiply).
TEST(Quaternion, ProductComposesTheRotationMatrices) {
  torch::manual_seed(5);
  auto a = torch::randn({32, 4}, torch::kFloat64), b = torch::randn({32, 4}, torch::kFloat64);
  auto ab = geometry::quat_multiply(a, b);
  auto expected = torch::matmul(geometry::quat_to_rotation(a), geometry::quat_to_rotation(b));
  EXPECT_LE(test::max_abs_diff(geometry::quat_to_rotation(ab), expected), 1e-12);
  EXPECT_LE(test::max_abs_diff(ab.norm(2, -1), a.norm(2, -1) * b.norm(2, -1)), 1e-12);
  auto identity = torch::tensor({0.0, 0.0, 0.0, 1.0}, torch::kFloat64).expand({32, 4});
  EXPECT_LE(test::max_abs_diff(geometry::quat_multiply(a, identity), a), 1e-15);
}

TEST(Quaternion, SlerpEndpointsAndMidpoint) {
  double s = std::sqrt(0.5);
  auto q0 = torch::tensor({0.0, 0.0, 0.0, 1.0}, torch::kFloat64);
  auto q1 = torch::tensor({0.0, 0.0, s, s}, torch::kFloat64);  // 90 deg about z
  EXPECT_LE(test::max_abs_diff(geometry::quat_slerp(q0, q1, 0.0), q0), 1e-12);
  EXPECT_LE(test::max_abs_diff(geometry::quat_slerp(q0, q1, 1.0), q1), 1e-12);
  auto mid = geometry::quat_slerp(q0, q1, 0.5);  // 45 deg
  EXPECT_NEAR(mid[2].item<double>(), std::sin(M_PI / 8), 1e-12);
  // Shortest path: -q1 is the same rotation.
  EXPECT_LE(test::max_abs_diff(geometry::quat_slerp(q0, -q1, 0.5), mid), 1e-12);
}

TEST(Camera, PoseEncodingRoundTrip) {
  torch::manual_seed(4);
  auto q = torch::randn({5, 4}, torch::kFloat64);
  q = q / q.norm(2, -1, true);
  q = torch::where(q.select(1, 3).unsqueeze(1) < 0, -q, q);
  auto enc = torch::cat({torch::randn({5, 3}, torch::kFloat64), q}, 1);
  auto c2w = geometry::pose_encoding_to_c2w(enc);
  EXPECT_LE(test::max_abs_diff(geometry::c2w_to_pose_encoding(c2w), enc), 1e-9);
  EXPECT_LE(test::max_abs_diff(c2w.select(1, 3), torch::tensor({0.0, 0.0, 0.0, 1.0}, torch::kFloat64).expand({5, 4})),
            0);
}

TEST(Camera, InvertRigidAndFirstViewNormalisation) {
  torch::manual_seed(5);
  auto q = torch::randn({3, 4}, torch::kFloat64);
  auto c2w =
      geometry::pose_encoding_to_c2w(torch::cat({torch::randn({3, 3}, torch::kFloat64), q / q.norm(2, -1, true)}, 1));
  EXPECT_LE(test::max_abs_diff(geometry::invert_rigid(c2w), torch::linalg_inv(c2w)), 1e-12);
  auto normed = geometry::normalize_to_first_view(c2w);
  EXPECT_LE(test::max_abs_diff(normed[0], torch::eye(4, torch::kFloat64)), 1e-12);
  // Relative poses are preserved.
  auto rel = torch::matmul(torch::linalg_inv(c2w[1]), c2w[2]);
  auto rel_n = torch::matmul(torch::linalg_inv(normed[1]), normed[2]);
  EXPECT_LE(test::max_abs_diff(rel, rel_n), 1e-10);
}

TEST(Camera, OfficialSceneNormalisation) {
  torch::manual_seed(6);
  auto q = torch::randn({4, 4}, torch::kFloat64);
  auto c2w = geometry::pose_encoding_to_c2w(
      torch::cat({torch::randn({4, 3}, torch::kFloat64) * 5 + 3, q / q.norm(2, -1, true)}, 1));
  auto out = geometry::official_scene_normalize(c2w, 1.35);
  auto t = out.index({torch::indexing::Slice(), torch::indexing::Slice(0, 3), 3});
  EXPECT_NEAR(t.abs().max().item<double>(), 1.0 / 1.35, 1e-12);
  EXPECT_LE(t.mean(0).abs().max().item<double>(), 1e-9);  // re-centred on the mean camera centre
  // Rotations stay rotations.
  auto R = out.index({0, torch::indexing::Slice(0, 3), torch::indexing::Slice(0, 3)});
  EXPECT_LE(test::max_abs_diff(torch::matmul(R, R.t()), torch::eye(3, torch::kFloat64)), 1e-9);
}

TEST(Camera, IntrinsicsPixelsNormalised) {
  auto n = torch::tensor({0.6, 1.0, 0.5, 0.5}, torch::kFloat64);
  auto p = geometry::intrinsics_to_pixels(n, 360, 640);
  EXPECT_LE(test::max_abs_diff(p, torch::tensor({384.0, 360.0, 320.0, 180.0}, torch::kFloat64)), 1e-12);
  EXPECT_LE(test::max_abs_diff(geometry::intrinsics_to_normalized(p, 360, 640), n), 1e-12);
  auto K = geometry::intrinsics_matrix(p);
  EXPECT_DOUBLE_EQ(K[0][2].item<double>(), 320.0);
  EXPECT_DOUBLE_EQ(K[1][1].item<double>(), 360.0);
  EXPECT_DOUBLE_EQ(K[2][2].item<double>(), 1.0);
}
