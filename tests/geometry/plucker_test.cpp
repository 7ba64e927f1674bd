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
