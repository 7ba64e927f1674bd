// Tests of model/latent_plucker_learner: the official head (translation from its MLP, a unit quaternion from the
// other), and `rotation_only_latent_camera` fixing the translation at zero.
#include "uplvsm/model/latent_plucker_learner.h"

#include <gtest/gtest.h>

#include <utility>

using namespace uplvsm;
using namespace uplvsm::model;

namespace {

TransformerConfig estimator_config() {
  TransformerConfig c;
  c.d = 64, c.d_head = 32, c.estimator_n_layer = 1;
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

}  // namespace

TEST(LatentPluckerLearner, PosesAreTheHeadsTranslationAndNormalisedQuaternion) {
  torch::manual_seed(4);
  LatentPluckerLearner estimator(estimator_config());
  auto tokens = torch::randn({5, 16, 64}), latents = torch::randn({5, 8, 64});
  torch::NoGradGuard no_grad;
  auto pooled = estimator->pooled(tokens, latents);
  ASSERT_EQ(pooled.sizes(), (std::vector<int64_t>{5, 64}));
  auto poses = estimator(tokens, latents);
  ASSERT_EQ(poses.sizes(), (std::vector<int64_t>{5, 7}));
  EXPECT_TRUE(torch::allclose(poses.narrow(1, 0, 3), estimator->absT_head(pooled), 1e-6, 1e-6));
  auto q = estimator->quaR_head(pooled);
  EXPECT_TRUE(torch::allclose(poses.narrow(1, 3, 4), q / q.norm(2, 1, true), 1e-5, 1e-6));
}

TEST(LatentPluckerLearner, RotationOnlyLatentCameraHasZeroTranslationAndTheSameRotation) {
  // rotation_only_latent_camera: translation exactly 0 and no gradient into its head; the rotation is unchanged.
  auto config = estimator_config();
  config.rotation_only_latent_camera = true;
  auto [plain, turning] = learners_with_same_init(estimator_config(), config, 5);
  auto tokens = torch::randn({3, 16, 64}), latents = torch::randn({3, 8, 64});
  auto poses = turning(tokens, latents);
  EXPECT_EQ(poses.narrow(1, 0, 3).abs().max().item<float>(), 0.0f);
  EXPECT_TRUE(torch::allclose(poses.narrow(1, 3, 4), plain(tokens, latents).narrow(1, 3, 4)));
  poses.sum().backward();
  EXPECT_FALSE(turning->absT_head->fc2->weight.grad().defined());
  EXPECT_GT(turning->quaR_head->fc2->weight.grad().abs().sum().item<float>(), 0.0f);
}
