#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/plucker.h"
#include "uplvsm/io/safetensors.h"

using namespace uplvsm;

TEST(Plucker, MatchesLvsmFixture) {
  UPLVSM_NEEDS_FIXTURES();
  auto f = io::read_safetensors(test::fixture("lvsm/rays.safetensors")).tensors;
  for (std::string prefix : {"", "offcenter."}) {
    auto k = f.at(prefix.empty() ? "fxfycxcy" : prefix + "fxfycxcy");
    auto [o, d] = geometry::compute_rays(f.at("c2w"), k, 32, 32);
    EXPECT_LE(test::max_abs_diff(o, f.at(prefix + "ray_o")), 1e-5) << prefix;
    EXPECT_LE(test::max_abs_diff(d, f.at(prefix + "ray_d")), 1e-5) << prefix;
    auto p = geometry::plucker_rays(f.at("c2w"), k, 32, 32);
    EXPECT_LE(test::max_abs_diff(p, f.at(prefix + "plucker")), 1e-5) << prefix;
  }
}

TEST(Plucker, IdentityCameraHandComputed) {
  // 2x2 image, fx = fy = 1, cx = cy = 1: pixel (0,0) looks through (-0.5, -0.5, 1).
  auto c2w = torch::eye(4).unsqueeze(0);
  auto k = torch::tensor({{1.0f, 1.0f, 1.0f, 1.0f}});
  auto p = geometry::plucker_rays(c2w, k, 2, 2);
  ASSERT_EQ(p.sizes(), (std::vector<int64_t>{1, 6, 2, 2}));
  double n = std::sqrt(1.5);
  EXPECT_NEAR(p[0][3][0][0].item<double>(), -0.5 / n, 1e-6);
  EXPECT_NEAR(p[0][4][0][0].item<double>(), -0.5 / n, 1e-6);
  EXPECT_NEAR(p[0][5][0][0].item<double>(), 1.0 / n, 1e-6);
  EXPECT_NEAR(p[0][3][1][1].item<double>(), 0.5 / n, 1e-6);     // row 1, col 1
  EXPECT_LE(p.slice(1, 0, 3).abs().max().item<double>(), 0.0);  // origin at 0: zero moment
}

TEST(Plucker, MomentIsOriginCrossDirection) {
  auto c2w = torch::eye(4).unsqueeze(0);
  c2w[0][0][3] = 1.0;  // camera at x = 1, looking along +z: moment = (1,0,0) x (0,0,1) = (0,-1,0)
  auto k = torch::tensor({{100.0f, 100.0f, 0.5f, 0.5f}});
  auto p = geometry::plucker_rays(c2w, k, 1, 1);
  EXPECT_NEAR(p[0][1][0][0].item<double>(), -1.0, 1e-5);
  EXPECT_NEAR(p[0][0][0][0].item<double>(), 0.0, 1e-5);
}

// bf16 cameras (the estimator's poses under autocast): the camera-frame directions are still made in fp32 from the
// fp32 intrinsics and rounded once, by the rotation, as the official rays_from_c2w (data_utils.py:46-54 at d490397).
// Built in bf16, the pixel centres would round themselves: at 224 px columns 129 and 130 would share a ray.
TEST(Plucker, Bf16CamerasKeepFp32PixelCentresRoundedOnce) {
  const int64_t W = 224, H = 4;
  auto c2w = torch::eye(4).unsqueeze(0).to(torch::kBFloat16);
  auto k = torch::tensor({{201.3f, 201.3f, 112.0f, 2.0f}});
  auto [o, d] = geometry::compute_rays(c2w, k, H, W);
  ASSERT_EQ(d.scalar_type(), torch::kBFloat16);
  // The expected rays: (x, y, 1) of the pixel centres in fp32, rounded to bf16 once, normalised in fp32.
  auto xs = (torch::arange(W, torch::kFloat32) + 0.5 - 112.0f) / 201.3f;
  auto ys = (torch::arange(H, torch::kFloat32) + 0.5 - 2.0f) / 201.3f;
  auto x = xs.view({1, W}).expand({H, W}).to(torch::kBFloat16).to(torch::kFloat32);
  auto y = ys.view({H, 1}).expand({H, W}).to(torch::kBFloat16).to(torch::kFloat32);
  auto norm = (x * x + y * y + 1).sqrt();
  auto expected_x = (x / norm).to(torch::kFloat64);
  const auto off = (d[0][0].to(torch::kFloat64) - expected_x).abs() - expected_x.abs() / 256;
  EXPECT_LE(off.max().item<double>(), 1e-7) << "x components further than a bf16 rounding from the fp32 directions";
  // Neighbouring columns past the 128th pixel are distinct rays.
  for (int64_t col = 128; col < 160; ++col)
    EXPECT_NE(d[0][0][1][col].item<float>(), d[0][0][1][col + 1].item<float>()) << "columns " << col << ", " << col + 1;
}
