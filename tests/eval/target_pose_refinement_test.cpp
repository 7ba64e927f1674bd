// Tests of eval/target_pose_refinement: with no steps it is the estimator protocol exactly; refining moves only the
// poses (the weights stay as they were, with no gradient), lowers every view's error, finds a pose whose render is
// the target back, and the evaluator refuses it where there is no estimator pose to refine.
#include "uplvsm/eval/target_pose_refinement.h"

#include <gtest/gtest.h>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/eval/evaluator.h"
#include "uplvsm/model/model_factory.h"

namespace uplvsm::eval {
namespace {

struct Scene {
  model::Views inputs, targets;
};

Scene random_scene(int64_t b, int64_t vi, int64_t vt) {
  auto k = [](int64_t b, int64_t v) { return torch::tensor({30.0, 30.0, 16.0, 16.0}).expand({b, v, 4}).contiguous(); };
  return {{torch::rand({b, vi, 3, 32, 32}), k(b, vi), {}}, {torch::rand({b, vt, 3, 32, 32}), k(b, vt), {}}};
}

model::UPLVSM tiny_uplvsm() {
  torch::manual_seed(3);
  auto net = model::make_model(test::micro_model("uplvsm"));
  net->eval();
  return std::dynamic_pointer_cast<model::UPLVSMImpl>(net.ptr());
}

TEST(TargetPoseRefinement, PerViewMseIsTheMeanOverEachViewsPixels) {
  auto a = torch::rand({2, 3, 3, 4, 5}), b = torch::rand({2, 3, 3, 4, 5});
  auto mse = per_view_mse(a, b);
  ASSERT_EQ(mse.sizes(), (std::vector<int64_t>{2, 3}));
  for (int64_t i = 0; i < 2; ++i)
    for (int64_t v = 0; v < 3; ++v) {
      double sum = 0;
      auto d = (a[i][v] - b[i][v]).contiguous();
      for (int64_t k = 0; k < d.numel(); ++k) sum += std::pow(d.view(-1)[k].item<double>(), 2);
      EXPECT_NEAR(mse[i][v].item<double>(), sum / d.numel(), 1e-7);
    }
  EXPECT_THROW(per_view_mse(a, b.narrow(1, 0, 2)), c10::Error);
}

TEST(TargetPoseRefinement, NoStepsIsTheEstimatorProtocol) {
  auto net = tiny_uplvsm();
  auto s = random_scene(2, 2, 3);
  torch::NoGradGuard no_grad;
  auto plain = net->render(s.inputs, s.targets, model::TargetPoses::Estimator);
  auto same = render_at_refined_poses(*net, s.inputs, s.targets, {});
  EXPECT_TRUE(torch::equal(same.render, plain.render));
  EXPECT_TRUE(torch::equal(same.pose_enc, plain.pose_enc));
  EXPECT_THROW(render_at_refined_poses(*net, s.inputs, s.targets, {-1, 0.01}), c10::Error);
  EXPECT_THROW(render_at_refined_poses(*net, s.inputs, s.targets, {5, 0.0}), c10::Error);
}

TEST(TargetPoseRefinement, MovesOnlyThePosesAndLowersEveryViewsError) {
  auto net = tiny_uplvsm();
  auto s = random_scene(2, 2, 3);
  std::vector<torch::Tensor> before;
  for (const auto& p : net->parameters()) before.push_back(p.detach().clone());
  torch::NoGradGuard no_grad;  // as the evaluator calls it
  auto start = render_at_refined_poses(*net, s.inputs, s.targets, {});
  auto refined = render_at_refined_poses(*net, s.inputs, s.targets, {30, 0.02});
  auto e0 = per_view_mse(start.render, s.targets.images), e1 = per_view_mse(refined.render, s.targets.images);
  EXPECT_TRUE((e1 <= e0).all().item<bool>()) << e0 << e1;
  EXPECT_LT(e1.sum().item<double>(), e0.sum().item<double>());
  EXPECT_FALSE(torch::equal(refined.pose_enc, start.pose_enc));
  EXPECT_TRUE(torch::equal(refined.scene_latents, start.scene_latents));
  EXPECT_FALSE(refined.render.requires_grad());
  size_t i = 0;
  for (const auto& p : net->parameters()) {
    EXPECT_TRUE(torch::equal(p, before[i++]));
    EXPECT_FALSE(p.grad().defined());
  }
}

// The target is the model's own render at a pose the estimator does not read from it: refining from the estimator's
// pose must find a pose that renders it back (at least 20x closer than where it started).
TEST(TargetPoseRefinement, FindsAPoseThatRendersTheTargetBack) {
  auto net = tiny_uplvsm();
  auto s = random_scene(1, 2, 2);
  torch::NoGradGuard no_grad;
  auto latents = net->encode_scene(s.inputs.images, s.inputs.fxfycxcy);
  auto known = torch::tensor({0.4f, -0.3f, 0.2f, 0.2f, -0.1f, 0.1f, 1.0f, -0.3f, 0.2f, 0.5f, 0.0f, 0.3f, 0.0f, 0.95f})
                   .view({1, 2, 7});
  s.targets.images = net->render_views(latents, known, s.targets.fxfycxcy, 32, 32);
  auto start = render_at_refined_poses(*net, s.inputs, s.targets, {});
  auto refined = render_at_refined_poses(*net, s.inputs, s.targets, {200, 0.02});
  auto e0 = per_view_mse(start.render, s.targets.images), e1 = per_view_mse(refined.render, s.targets.images);
  EXPECT_TRUE((e1 * 20 < e0).all().item<bool>()) << e0 << e1;
}

// Through the evaluator on built-in scenes: every target's PSNR at its refined pose is at least the estimator's, and
// a model without estimator poses to refine is refused with a message that says so.
TEST(TargetPoseRefinement, TheEvaluatorScoresRefinedPosesAndRefusesItWithoutAnEstimator) {
  auto net = model::NovelViewModel(std::static_pointer_cast<model::NovelViewModelImpl>(tiny_uplvsm().ptr()));
  data::ChunkDataset dataset(test::micro_dataset(), "test");
  data::PreprocessOptions prep;
  prep.image_size = 32;
  prep.patch_size = 8;
  EvalOptions opt;
  const auto plain = evaluate(net, dataset, prep, opt);
  opt.pose_refinement = {10, 0.02};
  const auto refined = evaluate(net, dataset, prep, opt);
  ASSERT_EQ(refined.per_scene.size(), plain.per_scene.size());
  ASSERT_GT(plain.scenes, 0);
  for (size_t i = 0; i < plain.per_scene.size(); ++i)
    for (size_t v = 0; v < plain.per_scene[i].views.size(); ++v)
      EXPECT_GE(refined.per_scene[i].views[v].model.psnr, plain.per_scene[i].views[v].model.psnr - 1e-9)
          << i << " " << v;
  EXPECT_GT(refined.scores.model.psnr, plain.scores.model.psnr);

  opt.target_poses = model::TargetPoses::Dataset;
  try {
    evaluate(net, dataset, prep, opt);
    ADD_FAILURE() << "refinement with dataset target poses was accepted";
  } catch (const c10::Error& e) {
    EXPECT_NE(std::string(e.what()).find("pose refinement refines the latent poses"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace uplvsm::eval
