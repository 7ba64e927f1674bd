#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/model/pose_mapper.h"

using namespace uplvsm;

TEST(PoseMapper, StartsAsTheIdentityAndNormalisesTheQuaternion) {
  model::PoseMapper mapper;
  auto pose = torch::tensor({{0.5, -1.0, 2.0, 0.0, 0.0, 0.0, 2.0}});
  auto out = mapper(pose);
  EXPECT_LT(test::max_abs_diff(out, torch::tensor({{0.5, -1.0, 2.0, 0.0, 0.0, 0.0, 1.0}})), 1e-6);
  auto named = mapper->named_parameters();
  EXPECT_TRUE(named.contains("A") && named.contains("b"));
  EXPECT_EQ(named.size(), 2u);
}

TEST(PoseMapper, LeastSquaresFitRecoversAKnownLinearMap) {
  torch::manual_seed(2);
  auto A = torch::randn({7, 7}, torch::kFloat64), b = torch::randn({7}, torch::kFloat64);
  auto real = torch::randn({200, 7}, torch::kFloat64);
  auto latent = torch::matmul(real, A.t()) + b;
  model::PoseMapper mapper;
  const double rms = model::fit_pose_mapper(*mapper, real, latent, 1e-10);
  EXPECT_LT(rms, 1e-6);
  EXPECT_LT(test::max_abs_diff(mapper->A, A), 1e-5);
  EXPECT_LT(test::max_abs_diff(mapper->b, b), 1e-5);
  EXPECT_NE(test::error_of([&] { model::fit_pose_mapper(*mapper, real, latent.narrow(1, 0, 6)); }).find("[N, 7]"),
            std::string::npos);
}
