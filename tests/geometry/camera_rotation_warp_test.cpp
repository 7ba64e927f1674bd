// The rotated-camera warp against the pinhole formulas: identity, where a yaw moves the principal point's pixel, and
// the fixed band that every yaw in range keeps inside the image.
#include <gtest/gtest.h>

#include <cmath>

#include "test_util.h"
#include "uplvsm/geometry/camera_rotation_warp.h"

using namespace uplvsm;
using torch::indexing::Slice;

namespace {
// Pixel (row, column) holds its column index: bilinear sampling reproduces value(u) = u - 0.5 exactly inside.
torch::Tensor column_ramp(int64_t H, int64_t W) {
  return torch::arange(W, torch::kFloat32).view({1, 1, 1, W}).expand({1, 1, H, W}).contiguous();
}
torch::Tensor intrinsics(int64_t H, int64_t W) { return torch::tensor({{0.8f * W, 0.8f * W, 0.5f * W, 0.5f * H}}); }
}  // namespace

TEST(CameraRotationWarp, YawRotationIsAProperRotationAboutY) {
  auto R = geometry::yaw_rotation(torch::tensor({0.3, -1.1}, torch::kFloat64));
  ASSERT_EQ(R.sizes(), (std::vector<int64_t>{2, 3, 3}));
  auto eye = torch::eye(3, torch::kFloat64).expand({2, 3, 3});
  EXPECT_LT(test::max_abs_diff(torch::matmul(R, R.transpose(1, 2)), eye), 1e-12);
  EXPECT_LT(test::max_abs_diff(torch::linalg_det(R), torch::ones({2}, torch::kFloat64)), 1e-12);
  auto y = torch::tensor({0.0, 1.0, 0.0}, torch::kFloat64);
  EXPECT_LT(test::max_abs_diff(torch::matmul(R, y), y.expand({2, 3})), 1e-12);  // the axis stays
}

TEST(CameraRotationWarp, IdentityKeepsTheImageAndAYawMovesThePrincipalPixelByFTanTheta) {
  const int64_t H = 40, W = 64;
  auto image = column_ramp(H, W);
  auto k = intrinsics(H, W);
  auto same = geometry::warp_to_rotated_camera(image, k, torch::eye(3).unsqueeze(0));
  EXPECT_LT(test::max_abs_diff(same.index({Slice(), Slice(), Slice(), Slice(1, W - 1)}),
                               image.index({Slice(), Slice(), Slice(), Slice(1, W - 1)})),
            1e-4);
  const double theta = 0.1;
  auto turned = geometry::warp_to_rotated_camera(image, k, geometry::yaw_rotation(torch::tensor({theta})));
  // The output pixel whose centre is the principal point (cx, cy) = (32, 20): pixel (19.5 -> row 19/20 boundary),
  // so read the pixel centred at (32.5, 20.5) and project its ray by hand.
  const double f = 0.8 * W, x = (32.5 - 32.0) / f;
  const double u = f * (std::cos(theta) * x + std::sin(theta)) / (-std::sin(theta) * x + std::cos(theta)) + 32.0;
  EXPECT_NEAR(turned[0][0][20][32].item<double>(), u - 0.5, 1e-3);
}

TEST(CameraRotationWarp, SafeRegionIsACentralBandInsideEveryYawInRange) {
  const int64_t H = 48, W = 48;
  auto k = intrinsics(H, W);
  const double max_radians = 10 * M_PI / 180;
  auto band = geometry::yaw_safe_region(k, H, W, max_radians);
  ASSERT_EQ(band.sizes(), (std::vector<int64_t>{1, 1, H, W}));
  EXPECT_EQ(band[0][0][H / 2][W / 2].item<float>(), 1.0f);
  EXPECT_EQ(band[0][0][H / 2][0].item<float>(), 0.0f);
  EXPECT_EQ(band[0][0][H / 2][W - 1].item<float>(), 0.0f);
  EXPECT_TRUE(torch::equal(band, band.flip({3})));  // the same on both sides: it does not tell the turn's sign
  auto ones = torch::ones({1, 1, H, W});
  for (double fraction : {-1.0, -0.3, 0.4, 1.0}) {
    auto seen =
        geometry::warp_to_rotated_camera(ones, k, geometry::yaw_rotation(torch::tensor({fraction * max_radians})));
    EXPECT_GT((seen * band + (1 - band)).min().item<float>(), 0.999f) << fraction;
  }
}
