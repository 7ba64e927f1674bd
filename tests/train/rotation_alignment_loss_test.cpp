// The rotation-alignment term against a construction with a known answer: a target made by warping view 0 as its
// camera turned by R (so the whole view change is a turn) scores ~0 at the latent rotation R and more at others.
#include <gtest/gtest.h>

#include <limits>

#include "test_util.h"
#include "uplvsm/geometry/camera_rotation_warp.h"
#include "uplvsm/geometry/quaternion.h"
#include "uplvsm/train/rotation_alignment_loss.h"

using namespace uplvsm;

TEST(RotationAlignmentLoss, IsZeroAtTheTurnThatMadeTheTargetAndGrowsAway) {
  torch::manual_seed(3);
  const int64_t S = 32;
  // A smooth view 0 (low frequencies), so bilinear resampling is near exact.
  auto coarse = torch::rand({1, 3, 4, 4});
  auto view0 = torch::nn::functional::interpolate(coarse, torch::nn::functional::InterpolateFuncOptions()
                                                              .size(std::vector<int64_t>{S, S})
                                                              .mode(torch::kBicubic)
                                                              .align_corners(false));
  auto k = torch::tensor({{36.0f, 36.0f, 16.0f, 16.0f}});
  auto yaw = torch::tensor({0.12f});
  auto target = geometry::warp_to_rotated_camera(view0, k, geometry::yaw_rotation(yaw));
  model::Views inputs{torch::stack({view0, view0}, 1), torch::stack({k, k}, 1), {}};
  model::Views targets{target.unsqueeze(1), k.unsqueeze(1), {}};
  auto pose = [](float angle) {  // (t, q_xyzw) of a turn about y
    return torch::tensor({0.3f, 0.0f, -0.2f, 0.0f, std::sin(angle / 2), 0.0f, std::cos(angle / 2)}).view({1, 1, 7});
  };
  const double at_truth = train::rotation_alignment_loss(inputs, targets, pose(0.12f)).item<double>();
  const double near = train::rotation_alignment_loss(inputs, targets, pose(0.06f)).item<double>();
  const double unturned = train::rotation_alignment_loss(inputs, targets, pose(0.0f)).item<double>();
  EXPECT_LT(at_truth, 1e-6);
  EXPECT_GT(near, 10 * at_truth + 1e-5);
  EXPECT_GT(unturned, near);
  auto grad_pose = pose(0.06f).requires_grad_();
  train::rotation_alignment_loss(inputs, targets, grad_pose).backward();
  EXPECT_GT(grad_pose.grad().abs().narrow(-1, 3, 4).sum().item<double>(), 0);  // it teaches the rotation
  EXPECT_EQ(grad_pose.grad().narrow(-1, 0, 3).abs().sum().item<double>(), 0);  // and only the rotation
  EXPECT_NE(test::error_of([&] {
              train::rotation_alignment_loss(inputs, targets, pose(0.1f).view({1, 7}));
            }).find("expected latent poses [1, 1, 7]"),
            std::string::npos);
}

// The blur against the 2-D Gaussian computed directly: an impulse spreads into the normalised kernel, a constant
// image stays constant (borders replicated), and the blur is what it says in each channel.
TEST(RotationAlignmentLoss, GaussianBlurIsTheNormalisedGaussian) {
  const double sigma = 1.5;
  auto impulse = torch::zeros({1, 2, 15, 15});
  impulse.index_put_({0, 1, 7, 7}, 1.0);
  auto blurred = train::gaussian_blur(impulse, sigma);
  auto x = torch::arange(-7, 8, torch::kFloat64);
  auto g2 = (-(x.view({-1, 1}).pow(2) + x.view({1, -1}).pow(2)) / (2 * sigma * sigma)).exp();
  auto r = 5;  // ceil(3 sigma): taps beyond it are dropped before normalising
  auto inside = x.abs().le(r).to(torch::kFloat64);
  g2 = g2 * inside.view({-1, 1}) * inside.view({1, -1});
  g2 = g2 / g2.sum();
  EXPECT_LT((blurred[0][1].to(torch::kFloat64) - g2).abs().max().item<double>(), 1e-7);
  EXPECT_EQ(blurred[0][0].abs().max().item<float>(), 0.f);
  auto flat = torch::full({1, 3, 9, 7}, 0.4f);
  EXPECT_LT((train::gaussian_blur(flat, 4.0) - 0.4f).abs().max().item<float>(), 1e-6);
  EXPECT_NE(test::error_of([] {
              train::gaussian_blur(torch::zeros({3, 8, 8}), 1.0);
            }).find("expected images"),
            std::string::npos);
  EXPECT_NE(test::error_of([] {
              train::gaussian_blur(torch::zeros({1, 3, 8, 8}), 0.0);
            }).find("sigma must be > 0"),
            std::string::npos);
}

// Coarse-to-fine: a target turned ~14 px away from a view 0 of pixel noise. Blurred, the term falls all the way from
// the unturned camera to the turn that made the target, so gradient descent from the identity finds it; sharp, not.
TEST(RotationAlignmentLoss, BlurredItFallsFromTheIdentityToAFarTurn) {
  torch::manual_seed(4);
  const int64_t S = 48;
  auto view0 = torch::rand({1, 3, S, S});  // pixel noise: a sharp comparison has no slope beyond a pixel's shift
  auto k = torch::tensor({{54.0f, 54.0f, 24.0f, 24.0f}});
  const float truth = 0.25f;
  auto target = geometry::warp_to_rotated_camera(view0, k, geometry::yaw_rotation(torch::tensor({truth})));
  model::Views inputs{torch::stack({view0, view0}, 1), torch::stack({k, k}, 1), {}};
  model::Views targets{target.unsqueeze(1), k.unsqueeze(1), {}};
  auto pose = [](float angle) {
    return torch::tensor({0.0f, 0.0f, 0.0f, 0.0f, std::sin(angle / 2), 0.0f, std::cos(angle / 2)}).view({1, 1, 7});
  };
  double previous = std::numeric_limits<double>::infinity();
  for (int i = 0; i <= 10; ++i) {
    const float angle = truth * static_cast<float>(i) / 10;
    const double loss = train::rotation_alignment_loss(inputs, targets, pose(angle), 6.0).item<double>();
    EXPECT_LT(loss, previous) << "at " << angle << " rad";
    previous = loss;
  }
  bool sharp_falls_all_the_way = true;  // the construction is hard: unblurred, the term rises somewhere on the way
  for (int i = 1; i <= 10; ++i) {
    auto loss_at = [&](int step) {
      return train::rotation_alignment_loss(inputs, targets, pose(truth * static_cast<float>(step) / 10))
          .item<double>();
    };
    sharp_falls_all_the_way = sharp_falls_all_the_way && loss_at(i) < loss_at(i - 1);
  }
  EXPECT_FALSE(sharp_falls_all_the_way);
  auto start = pose(0.0f).requires_grad_();
  train::rotation_alignment_loss(inputs, targets, start, 6.0).backward();
  EXPECT_LT(start.grad()[0][0][4].item<float>(), 0.f);  // d loss / d q_y < 0: turning towards the truth helps
}
