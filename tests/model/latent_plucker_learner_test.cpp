// Tests of model/latent_plucker_learner's initialisation: the official zero-bias quaternion head gives arbitrary
// rotations at step 0; `identity_rotation_init` starts every latent camera near the identity, nothing else changed;
// `rotation_only_latent_camera` fixes the translation at zero; `latent_pivot_depth` turns it about a pivot.
#include "uplvsm/model/latent_plucker_learner.h"

#include <gtest/gtest.h>

#include <cmath>
#include <utility>

#include "uplvsm/geometry/camera.h"

using namespace uplvsm;
using namespace uplvsm::model;

namespace {

TransformerConfig estimator_config(bool identity) {
  TransformerConfig c;
  c.d = 64, c.d_head = 32, c.estimator_n_layer = 1;
  c.identity_rotation_init = identity;
  return c;
}

// Two estimators drawn from the same seed, so they hold the same weights and differ only where the configs do.
std::pair<LatentPluckerLearner, LatentPluckerLearner> learners_with_same_init(const TransformerConfig& a,
                                                                              const TransformerConfig& b,
                                                                              uint64_t seed) {
  torch::manual_seed(seed);
  LatentPluckerLearner first(a);
  torch::manual_seed(seed);
  return {first, LatentPluckerLearner(b)};
}

// Rotation angle (degrees) of each latent pose [N, 7] (t, q_xyzw): 2 acos |w|.
torch::Tensor rotation_degrees(const torch::Tensor& poses) {
  auto w = poses.select(1, 6).abs().clamp_max(1.0);
  return 2.0 * torch::acos(w) * (180.0 / M_PI);
}

TEST(LatentPluckerLearner, IdentityRotationInitStartsNearTheIdentityAndChangesOnlyThatBias) {
  auto [official, identity] = learners_with_same_init(estimator_config(false), estimator_config(true), 4);
  auto tokens = torch::randn({16, 10, 64}), latents = torch::randn({16, 8, 64});
  torch::NoGradGuard no_grad;
  const double official_median = rotation_degrees(official(tokens, latents)).median().item<double>();
  const double identity_max = rotation_degrees(identity(tokens, latents)).max().item<double>();
  EXPECT_GT(official_median, 30.0) << "the official init's latent rotations are arbitrary";
  EXPECT_LT(identity_max, 10.0);
  auto a = official->named_parameters(), b = identity->named_parameters();
  for (const auto& item : a) {
    const bool changed = !torch::equal(item.value(), b[item.key()]);
    EXPECT_EQ(changed, item.key() == "quaR_head.fc2.bias") << item.key();
  }
  EXPECT_TRUE(torch::equal(identity->quaR_head->fc2->bias, torch::tensor({0.0f, 0.0f, 0.0f, 1.0f})));
}

}  // namespace

TEST(LatentPluckerLearner, RotationGainScalesTheQuaternionsVectorPartBeforeNormalising) {
  // latent_rotation_gain g: q = normalise(g x, g y, g z, w) of the same head output; the translation unchanged.
  auto config = estimator_config(true);
  config.latent_rotation_gain = 8.0;
  auto [plain, gained] = learners_with_same_init(estimator_config(true), config, 6);
  auto tokens = torch::randn({5, 16, 64}), latents = torch::randn({5, 8, 64});
  torch::NoGradGuard no_grad;
  auto raw = plain->quaR_head(plain->pooled(tokens, latents));
  auto expected = torch::cat({raw.narrow(1, 0, 3) * 8.0, raw.narrow(1, 3, 1)}, 1);
  expected = expected / expected.norm(2, 1, true);
  auto poses = gained(tokens, latents), plain_poses = plain(tokens, latents);
  EXPECT_TRUE(torch::allclose(poses.narrow(1, 3, 4), expected, 1e-5, 1e-6));
  EXPECT_TRUE(torch::equal(poses.narrow(1, 0, 3), plain_poses.narrow(1, 0, 3)));
  EXPECT_GT(rotation_degrees(poses).mean().item<double>(), 4.0 * rotation_degrees(plain_poses).mean().item<double>());
}

TEST(LatentPluckerLearner, RotationOnlyLatentCameraHasZeroTranslationAndTheSameRotation) {
  // rotation_only_latent_camera: translation exactly 0 and no gradient into its head; the rotation is unchanged.
  auto config = estimator_config(false);
  config.rotation_only_latent_camera = true;
  auto [plain, turning] = learners_with_same_init(estimator_config(false), config, 5);
  auto tokens = torch::randn({3, 16, 64}), latents = torch::randn({3, 8, 64});
  auto poses = turning(tokens, latents);
  EXPECT_EQ(poses.narrow(1, 0, 3).abs().max().item<float>(), 0.0f);
  EXPECT_TRUE(torch::allclose(poses.narrow(1, 3, 4), plain(tokens, latents).narrow(1, 3, 4)));
  poses.sum().backward();
  EXPECT_FALSE(turning->absT_head->fc2->weight.grad().defined());
  EXPECT_GT(turning->quaR_head->fc2->weight.grad().abs().sum().item<float>(), 0.0f);
}

TEST(LatentPluckerLearner, PivotDepthAddsTheOrbitTranslationToARotationOnlyCamera) {
  // latent_pivot_depth with rotation_only_latent_camera: the translation is exactly the orbit's, driven by the
  // rotation (the gradient reaches the quaternion head through it); the rotation is the plain camera's.
  auto config = estimator_config(false);
  config.rotation_only_latent_camera = true;
  auto pivoted = config;
  pivoted.latent_pivot_depth = 2.0;
  auto [turning, orbiting] = learners_with_same_init(config, pivoted, 9);
  auto tokens = torch::randn({4, 16, 64}), latents = torch::randn({4, 8, 64});
  auto poses = orbiting(tokens, latents);
  auto q = turning(tokens, latents).narrow(1, 3, 4);
  EXPECT_TRUE(torch::allclose(poses.narrow(1, 3, 4), q));
  EXPECT_TRUE(torch::allclose(poses.narrow(1, 0, 3), geometry::pivot_translation(q, 2.0), 1e-5, 1e-6));
  EXPECT_GT(poses.narrow(1, 0, 3).abs().max().item<float>(), 0.1f) << "the official init's turns are large";
  poses.narrow(1, 0, 3).sum().backward();
  EXPECT_FALSE(orbiting->absT_head->fc2->weight.grad().defined());
  EXPECT_GT(orbiting->quaR_head->fc2->weight.grad().abs().sum().item<float>(), 0.0f);
}

TEST(LatentPluckerLearner, PivotDepthWithAFreeTranslationAddsTheHeadsOutput) {
  // Released (rotation_only off), the translation head's output is added to the orbit's, so a model trained with
  // a pivot and only turning starts its free stage where the first ended.
  auto config = estimator_config(false);
  config.latent_pivot_depth = 1.5;
  auto [plain, orbiting] = learners_with_same_init(estimator_config(false), config, 10);
  auto tokens = torch::randn({4, 16, 64}), latents = torch::randn({4, 8, 64});
  torch::NoGradGuard no_grad;
  auto base = plain(tokens, latents), poses = orbiting(tokens, latents);
  auto expected_t = base.narrow(1, 0, 3) + geometry::pivot_translation(base.narrow(1, 3, 4), 1.5);
  EXPECT_TRUE(torch::allclose(poses.narrow(1, 0, 3), expected_t, 1e-5, 1e-6));
  EXPECT_TRUE(torch::equal(poses.narrow(1, 3, 4), base.narrow(1, 3, 4)));
}
