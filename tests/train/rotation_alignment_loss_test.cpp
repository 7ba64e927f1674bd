// The rotation-alignment term against a construction with a known answer: a target made by warping view 0 as its
// camera turned by R (so the whole view change is a turn) scores ~0 at the latent rotation R and more at others.
#include <gtest/gtest.h>

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
