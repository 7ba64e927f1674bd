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

TEST(PoseMapper, MlpMapperStartsAsItsLinearFitAndReadsTheScene) {
  torch::manual_seed(3);
  auto real = torch::randn({64, 7}, torch::kFloat64), latent = torch::randn({64, 7}, torch::kFloat64);
  model::PoseMapper linear, mlp(model::PoseMapperOptions{model::PoseMapperKind::Mlp, 16});
  model::fit_pose_mapper(*linear, real, latent);
  model::fit_pose_mapper(*mlp, real, latent);
  EXPECT_FALSE(linear->reads_scene());
  EXPECT_TRUE(mlp->reads_scene());
  auto poses = torch::randn({2, 5, 7});
  auto scene = torch::randn({2, model::kSceneConditioningDims});
  EXPECT_LT(test::max_abs_diff(mlp(poses, scene), linear(poses)), 1e-6);  // a zero residual at the start
  // A trained residual depends on the scene: the same real pose maps differently in two scenes.
  {
    torch::NoGradGuard no_grad;
    for (auto& p : mlp->mlp->parameters()) p.normal_(0, 0.3);
  }
  auto same_pose = poses.select(1, 0).unsqueeze(1).expand({2, 1, 7}).contiguous();
  same_pose[1].copy_(same_pose[0]);
  auto out = mlp(same_pose, scene);
  EXPECT_GT(test::max_abs_diff(out[0], out[1]), 1e-4);
  EXPECT_NE(test::error_of([&] { mlp(poses); }).find("needs the scene's conditioning"), std::string::npos);
}

TEST(PoseMapper, KindsAreNamedAndAnUnknownOneIsRefused) {
  EXPECT_EQ(model::parse_pose_mapper_kind("linear"), model::PoseMapperKind::Linear);
  EXPECT_EQ(model::to_string(model::parse_pose_mapper_kind("mlp")), "mlp");
  EXPECT_NE(test::error_of([] { model::parse_pose_mapper_kind("cubic"); }).find("expected linear or mlp"),
            std::string::npos);
}

TEST(PoseMapper, SceneConditioningIsTheLatentPosesOfBothInputViews) {
  auto poses = torch::arange(2 * 2 * 7, torch::kFloat32).reshape({2, 2, 7});
  EXPECT_TRUE(torch::equal(model::scene_conditioning(poses), torch::cat({poses.select(1, 0), poses.select(1, 1)}, -1)));
  auto one = poses.narrow(1, 0, 1);
  EXPECT_TRUE(torch::equal(model::scene_conditioning(one), torch::cat({one.select(1, 0), one.select(1, 0)}, -1)));
  EXPECT_EQ(model::scene_conditioning(poses).size(1), model::kSceneConditioningDims);
}

TEST(PoseMapper, TheInverseFindsTheRealPoseOneBaselineAwayThatMapsToALatentPose) {
  torch::manual_seed(11);
  model::PoseMapper mlp(model::PoseMapperOptions{model::PoseMapperKind::Mlp, 16});
  {
    // A residual as steep as the linear part: a fixed point on A^-1 need not converge here.
    torch::NoGradGuard no_grad;
    for (auto& p : mlp->mlp->parameters()) p.normal_(0, 0.3);
  }
  auto scene = torch::randn({1, model::kSceneConditioningDims});
  auto q = torch::tensor({0.1, -0.2, 0.05, 0.97});
  auto real = torch::cat({torch::tensor({0.6, -0.48, 0.64}), q / q.norm()});
  auto latent = mlp(real.unsqueeze(0), scene)[0].detach();
  auto inverse = model::invert_pose_mapper(*mlp, latent, scene);
  EXPECT_LT(inverse.residual, 1e-5);
  EXPECT_NEAR(inverse.real.narrow(0, 0, 3).norm().item<double>(), 1.0, 1e-9);  // one baseline
  EXPECT_NEAR(inverse.real.narrow(0, 3, 4).norm().item<double>(), 1.0, 1e-9);
  EXPECT_LT(test::max_abs_diff(mlp(inverse.real.to(torch::kFloat32).unsqueeze(0), scene)[0], latent), 1e-4);
  EXPECT_NE(test::error_of([&] { model::invert_pose_mapper(*mlp, latent); }).find("scene's conditioning"),
            std::string::npos);
}

TEST(PoseMapper, ALatentPoseNoRealPoseReachesIsToldByItsResidual) {
  // The identity map: a latent pose three baselines away is reached at best one baseline away, 2 short.
  model::PoseMapper identity;
  auto latent = torch::tensor({0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 1.0});
  auto inverse = model::invert_pose_mapper(*identity, latent);
  EXPECT_LT(test::max_abs_diff(inverse.real, torch::tensor({0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}, torch::kFloat64)),
            1e-6);
  EXPECT_NEAR(inverse.residual, 2.0 / std::sqrt(7.0), 1e-6);
}

TEST(PoseMapper, ASingularMapperIsStillInvertedFromTheAxisStarts) {
  // A degenerate mapper (its linear part maps z to nothing) has no linear inverse; the solve still reaches the
  // closest real pose it can and says how far it stays.
  model::PoseMapper flat;
  {
    torch::NoGradGuard no_grad;
    flat->A[2][2].fill_(0.0);
  }
  auto latent = torch::tensor({1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0});
  auto inverse = model::invert_pose_mapper(*flat, latent);
  EXPECT_TRUE(torch::isfinite(inverse.real).all().item<bool>());
  EXPECT_LT(inverse.residual, 1e-6);
}
