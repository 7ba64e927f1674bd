// model/pose_error_feedback: the embedding's shapes, the correction starting at zero (a model with the
// feedback starts as the one-shot estimator), a rotation-only camera kept turning only, and the feedback reading
// the render: a change of the decoder moves the corrected pose and not the first reading, and the loss reaches the
// feedback's weights; its FLOPs are counted.
#include "uplvsm/model/pose_error_feedback.h"

#include <gtest/gtest.h>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/model/flops.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/uplvsm.h"

using namespace uplvsm;
using namespace uplvsm::model;

TEST(PoseErrorFeedback, EmbedsTwelveChannelPatchesAndNamesBadShapes) {
  PoseErrorFeedback feedback(8, 32);
  auto images = torch::rand({2, 3, 16, 24});
  torch::NoGradGuard no_grad;
  EXPECT_EQ(feedback->embed(images, images.flip(3), torch::randn({2, 6, 16, 24})).sizes(),
            (std::vector<int64_t>{2, 6, 32}));
  EXPECT_NE(test::error_of([&] {
              feedback->embed(images, images.narrow(1, 0, 2), torch::randn({2, 6, 16, 24}));
            }).find("targets and renders must be [N, 3, H, W] and rays [N, 6, H, W]"),
            std::string::npos);
}

TEST(PoseErrorFeedback, StartsAtZeroAndKeepsARotationOnlyCameraTurning) {
  torch::manual_seed(3);
  PoseErrorFeedback feedback(8, 32);
  auto poses = torch::cat(
      {torch::randn({4, 3}),
       torch::nn::functional::normalize(torch::randn({4, 4}), torch::nn::functional::NormalizeFuncOptions().dim(-1))},
      -1);
  auto pooled = torch::randn({4, 32});
  torch::NoGradGuard no_grad;
  EXPECT_LE(test::max_abs_diff(feedback->correct(poses, pooled, false), poses), 1e-6);
  feedback->correction_head->fc2->weight.normal_(0.0, 0.5);
  auto corrected = feedback->correct(poses, pooled, false);
  EXPECT_GT(test::max_abs_diff(corrected.narrow(1, 0, 3), poses.narrow(1, 0, 3)), 1e-3);
  EXPECT_LE(test::max_abs_diff(corrected.narrow(1, 3, 4).norm(2, -1), torch::ones({4})), 1e-5);
  auto turned = feedback->correct(poses, pooled, true);
  EXPECT_EQ(test::max_abs_diff(turned.narrow(1, 0, 3), poses.narrow(1, 0, 3)), 0.0);
  EXPECT_GT(test::max_abs_diff(turned.narrow(1, 3, 4), poses.narrow(1, 3, 4)), 1e-3);
}

namespace {
struct FeedbackCase {
  UPLVSM net{nullptr};
  Views targets;
  torch::Tensor latents;
};

FeedbackCase feedback_case() {
  auto c = test::micro_model();
  c.transformer.pose_error_feedback_steps = 2;
  torch::manual_seed(5);
  FeedbackCase f;
  f.net = require_uplvsm(make_model(c), "test");
  auto fxfycxcy = torch::tensor({30.0f, 30.0f, 16.0f, 16.0f}).view({1, 1, 4});
  f.latents = f.net->encode_scene(torch::rand({1, 2, 3, 32, 32}), fxfycxcy.expand({1, 2, 4}));
  f.targets = {torch::rand({1, 3, 3, 32, 32}), fxfycxcy.expand({1, 3, 4}), {}};
  return f;
}
}  // namespace

TEST(PoseErrorFeedback, AModelWithItStartsAsTheOneShotEstimator) {
  auto f = feedback_case();
  torch::NoGradGuard no_grad;
  EXPECT_LE(test::max_abs_diff(f.net->estimate_poses_with_feedback(f.targets, f.latents),
                               f.net->estimate_poses(f.targets.images, f.latents)),
            1e-6);
}

TEST(PoseErrorFeedback, ItReadsTheRenderAndTheLossReachesIt) {
  auto f = feedback_case();
  {
    torch::NoGradGuard no_grad;
    f.net->pose_error_feedback->correction_head->fc2->weight.normal_(0.0, 0.5);
  }
  auto poses = f.net->estimate_poses_with_feedback(f.targets, f.latents);
  auto render = f.net->render_views(f.latents, poses, f.targets.fxfycxcy, 32, 32);
  (render - f.targets.images).pow(2).mean().backward();
  for (const auto& p : f.net->pose_error_feedback->parameters()) EXPECT_GT(p.grad().abs().sum().item<double>(), 0.0);
  torch::NoGradGuard no_grad;
  auto first = f.net->estimate_poses(f.targets.images, f.latents);
  for (auto& p : f.net->transformer_decoder->parameters()) p.add_(torch::randn_like(p) * 0.1);  // another render
  EXPECT_LE(test::max_abs_diff(f.net->estimate_poses(f.targets.images, f.latents), first), 0.0);
  EXPECT_GT(test::max_abs_diff(f.net->estimate_poses_with_feedback(f.targets, f.latents), poses), 1e-4);
}

TEST(PoseErrorFeedback, EachStepCountsARenderAndAnEstimatorPass) {
  auto c = test::micro_model();
  auto once = model::forward_flops(c, 2, 2, 3);
  c.transformer.pose_error_feedback_steps = 2;
  auto fed_back = model::forward_flops(c, 2, 2, 3);
  EXPECT_DOUBLE_EQ(fed_back.estimator, 3 * once.estimator);
  EXPECT_DOUBLE_EQ(fed_back.decoder, 3 * once.decoder);
  EXPECT_DOUBLE_EQ(fed_back.encoder, once.encoder);
  EXPECT_GT(fed_back.other, once.other);
}
