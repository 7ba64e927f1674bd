// The turned-view term against an independent computation: the latent camera turned through its rotation matrix
// (c2w composed with the yaw, converted back to the 7-D encoding) instead of the quaternion product, the truth warped
// by the homography, the error averaged by hand over the pixels the warp keeps.
#include <gtest/gtest.h>

#include <cmath>

#include "train_test_util.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/camera_rotation_warp.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/train/turned_view_loss.h"

using namespace uplvsm;

namespace {

struct TurnedViewCase {
  model::UPLVSM net{nullptr};
  model::Views targets;
  torch::Tensor latents, pose_enc;
};

TurnedViewCase turned_view_case() {
  torch::manual_seed(11);
  TurnedViewCase c;
  c.net = model::UPLVSM(test::micro_model());
  const int64_t b = 2, v = 2, S = 32;
  auto k = torch::tensor({40.0f, 40.0f, 16.0f, 16.0f}).expand({b, v, 4}).contiguous();
  auto inputs = torch::rand({b, 2, 3, S, S});
  c.targets = {torch::rand({b, v, 3, S, S}), k, {}};
  c.latents = c.net->encode_scene(inputs, k);
  c.pose_enc = c.net->estimate_poses(c.targets.images, c.latents);
  return c;
}

torch::Tensor independent_loss(TurnedViewCase& c, const torch::Tensor& yaws) {
  const int64_t n = yaws.size(0), S = 32;
  auto turn = geometry::yaw_rotation(yaws);
  auto c2w = geometry::pose_encoding_to_c2w(c.pose_enc.flatten(0, 1));
  auto turned = c2w.clone();
  turned.narrow(1, 0, 3).narrow(2, 0, 3).copy_(torch::matmul(c2w.narrow(1, 0, 3).narrow(2, 0, 3), turn));
  auto enc = geometry::c2w_to_pose_encoding(turned).view({2, 2, 7});
  auto render = c.net->render_views(c.latents, enc, c.targets.fxfycxcy, S, S).flatten(0, 1);
  auto k = c.targets.fxfycxcy.flatten(0, 1);
  auto truth = geometry::warp_to_rotated_camera(c.targets.images.flatten(0, 1), k, turn);
  auto kept = geometry::warp_to_rotated_camera(torch::ones({n, 1, S, S}), k, turn) > 0.999;
  auto error = (render - truth).pow(2).sum(1, true);  // over the channels
  return error.masked_select(kept).sum() / (kept.sum() * 3);
}

}  // namespace

TEST(TurnedViewLoss, MatchesTheRotationMatrixRouteAndIsThePlainErrorWithoutATurn) {
  torch::NoGradGuard no_grad;
  auto c = turned_view_case();
  auto yaws = torch::tensor({0.15f, -0.1f, 0.05f, -0.17f});
  auto loss = train::turned_view_loss(*c.net, c.targets, c.pose_enc, c.latents, yaws);
  EXPECT_NEAR(loss.item<double>(), independent_loss(c, yaws).item<double>(), 1e-5);

  // No turn: the render of the plain latent pose against the plain target, every pixel kept.
  auto zero = train::turned_view_loss(*c.net, c.targets, c.pose_enc, c.latents, torch::zeros({4}));
  auto plain = c.net->render_views(c.latents, c.pose_enc, c.targets.fxfycxcy, 32, 32);
  EXPECT_NEAR(zero.item<double>(), torch::mse_loss(plain, c.targets.images).item<double>(), 1e-6);
  EXPECT_GT(std::abs(loss.item<double>() - zero.item<double>()), 1e-4);  // the turn changed what is compared
  EXPECT_NE(test::error_of([&] {
              train::turned_view_loss(*c.net, c.targets, c.pose_enc, c.latents, yaws.narrow(0, 0, 3));
            }).find("expected 4 yaws, got 3"),
            std::string::npos);
}

TEST(TurnedViewLoss, ItsGradientReachesTheDecoderAndTheEstimator) {
  auto c = turned_view_case();
  train::turned_view_loss(*c.net, c.targets, c.pose_enc, c.latents, torch::full({4}, 0.1f)).backward();
  double decoder = 0, estimator = 0;
  for (const auto& p : c.net->named_parameters()) {
    if (!p.value().grad().defined()) continue;
    const double g = p.value().grad().abs().sum().item<double>();
    if (p.key().rfind("transformer_decoder.", 0) == 0) decoder += g;
    if (p.key().rfind("estimator.", 0) == 0) estimator += g;
  }
  EXPECT_GT(decoder, 0);
  EXPECT_GT(estimator, 0);
}

TEST(TurnedViewLoss, YawsAreDrawnWithinTheRangeAndKeyedToTheStep) {
  TrainingConfig tc;
  tc.turned_view_degrees = 12;
  auto a = train::draw_turn_angles(1000, tc, 5), again = train::draw_turn_angles(1000, tc, 5);
  EXPECT_TRUE(torch::equal(a, again));
  EXPECT_FALSE(torch::equal(a, train::draw_turn_angles(1000, tc, 6)));
  const double limit = 12 * M_PI / 180;
  EXPECT_LE(a.abs().max().item<double>(), limit);
  EXPECT_GT(a.abs().max().item<double>(), 0.9 * limit);  // the range is used, not a sliver of it
}
