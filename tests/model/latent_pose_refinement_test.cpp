// Tests of model/latent_pose_refinement's keep_best: the poses returned are never worse than the start, view by view,
// even where the last Adam step overshoots; the plain refinement's last pose can be (the reason for the option).
// The refinement itself is tested through the evaluation protocol (tests/eval/target_pose_refinement_test.cpp).
#include "uplvsm/model/latent_pose_refinement.h"

#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/model/model_factory.h"

namespace uplvsm::model {
namespace {

// The targets are the model's own renders at known poses and the refinement starts near them, so any long step
// overshoots: the plain refinement's last pose is then worse than the start, the kept-best one never is.
TEST(LatentPoseRefinement, KeepBestNeverReturnsAPoseWorseThanTheStart) {
  torch::manual_seed(3);
  auto net = std::dynamic_pointer_cast<UPLVSMImpl>(make_model(test::micro_model("uplvsm")).ptr());
  net->eval();
  auto k = torch::tensor({30.0, 30.0, 16.0, 16.0}).expand({2, 3, 4}).contiguous();
  const Views inputs{torch::rand({2, 2, 3, 32, 32}), k.narrow(1, 0, 2).contiguous(), {}};
  torch::NoGradGuard no_grad;
  auto latents = net->encode(inputs);
  auto truth = torch::randn({2, 3, 7}) * 0.3;
  const Views targets{net->render_views(latents, truth, k, 32, 32), k, {}};
  auto start = truth + torch::randn({2, 3, 7}) * 0.03;
  auto error_at = [&](const torch::Tensor& poses) {
    return per_view_mse(net->render_views(latents, poses, targets.fxfycxcy, 32, 32), targets.images);
  };
  const PoseRefinement overshooting{4, 1.0};  // steps far beyond the error's basin
  auto last = refine_latent_poses(*net, latents, start, targets, overshooting);
  auto best = refine_latent_poses(*net, latents, start, targets, {4, 1.0, true});
  const auto e_start = error_at(start), e_last = error_at(last), e_best = error_at(best);
  EXPECT_TRUE((e_last > e_start).any().item<bool>()) << e_start << e_last;  // so the check below can fail
  EXPECT_TRUE((e_best <= e_start).all().item<bool>()) << e_start << e_best;
  auto small = refine_latent_poses(*net, latents, start, targets, {6, 0.005, true});
  EXPECT_LT(error_at(small).sum().item<double>(), e_start.sum().item<double>());  // and it still refines
  EXPECT_FALSE(small.requires_grad());
  EXPECT_TRUE(torch::equal(refine_latent_poses(*net, latents, start, targets, {1, 0.02, true}), start));
}

}  // namespace
}  // namespace uplvsm::model
