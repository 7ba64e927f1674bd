#include <gtest/gtest.h>

#include <fstream>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/eval/metrics.h"
#include "uplvsm/study/pose_sensitivity.h"

using namespace uplvsm;

namespace {
study::SensitivityReport measure(model::UPLVSM& net, model::TargetPoses source = model::TargetPoses::Estimator) {
  data::ChunkDataset dataset(test::micro_dataset(), "test");
  study::SensitivityOptions opt;
  opt.gap = 5;
  opt.source = source;
  return study::measure_pose_sensitivity(net, dataset, {32, 8, true}, opt);
}
}  // namespace

TEST(PoseSensitivity, EveryFrameOfTheSpanOnceWithItsRenderScored) {
  torch::manual_seed(2);
  model::UPLVSM net(test::micro_config().model);
  auto report = measure(net);
  data::ChunkDataset dataset(test::micro_dataset(), "test");
  ASSERT_EQ(report.views.size(), static_cast<size_t>(dataset.size() * 6));  // frames 0..5 per scene
  EXPECT_EQ(report.skipped_scenes, 0);
  // The first scene recomputed here: inputs {0, 5}, every frame a target, rendered at its estimated pose.
  auto views = dataset.load_views(0, {0, 5, 1, 2, 3, 4}, {32, 8, true});
  torch::NoGradGuard no_grad;
  net->eval();
  auto images = views.images.unsqueeze(0);
  auto latents = net->encode_scene(images.narrow(1, 0, 2), views.fxfycxcy.unsqueeze(0).narrow(1, 0, 2));
  auto poses = net->estimate_poses(images, latents);
  auto render = net->render_views(latents, poses, views.fxfycxcy.unsqueeze(0), 32, 32);
  auto psnr = eval::psnr(render, images)[0];
  auto at_first = net->render_views(latents, poses.narrow(1, 0, 1).expand_as(poses).contiguous(),
                                    views.fxfycxcy.unsqueeze(0), 32, 32);
  for (int64_t j = 0; j < 6; ++j) {
    const auto& v = report.views[j];
    EXPECT_EQ(v.scene, dataset.key(0));
    EXPECT_EQ(v.input, j < 2);
    EXPECT_NEAR(v.psnr, psnr[j].item<double>(), 1e-4);
    EXPECT_NEAR(v.render_change, (render[0][j] - at_first[0][j]).abs().mean().item<double>(), 1e-5);
    EXPECT_NEAR(v.truth_change, (images[0][j] - images[0][0]).abs().mean().item<double>(), 1e-6);
  }
  EXPECT_EQ(report.views[0].frame, 0);
  EXPECT_EQ(report.views[1].frame, 5);
  EXPECT_EQ(report.views[0].render_change, 0.0);  // the first input against its own pose
  EXPECT_EQ(report.views[0].truth_change, 0.0);
}

TEST(PoseSensitivity, ADecoderBlindToThePoseScoresZero) {
  torch::manual_seed(3);
  model::UPLVSM net(test::micro_config().model);
  auto seeing = study::summarise(measure(net));
  EXPECT_GT(seeing.at("targets").at("sensitivity").get<double>(), 0.0);
  // Without its ray tokens the decoder cannot tell one pose from another.
  {
    torch::NoGradGuard no_grad;
    for (auto& p : net->target_pose_tokenizer->parameters()) p.zero_();
  }
  auto report = measure(net);
  auto blind = study::summarise(report);
  EXPECT_EQ(blind.at("targets").at("sensitivity").get<double>(), 0.0);
  EXPECT_EQ(blind.at("all_but_first_input").at("render_change").get<double>(), 0.0);
  EXPECT_GT(blind.at("targets").at("truth_change").get<double>(), 0.0);
  EXPECT_EQ(blind.at("inputs").at("views").get<int64_t>(), 2 * 2);  // two inputs in each of two scenes
  EXPECT_EQ(blind.at("targets").at("views").get<int64_t>(), 4 * 2);
  auto csv = (test::temp_dir("sensitivity") / "views.csv").string();
  study::write_sensitivity_csv(csv, report);
  std::ifstream in(csv);
  std::string header, line;
  std::getline(in, header);
  EXPECT_EQ(header, "scene,frame,input,psnr,grad_ratio,render_change,truth_change");
  int64_t rows = 0;
  while (std::getline(in, line)) ++rows;
  EXPECT_EQ(rows, 12);
}

TEST(PoseSensitivity, DatasetPosesNeedCameras) {
  torch::manual_seed(4);
  model::UPLVSM net(test::micro_config().model);
  auto s = study::summarise(measure(net, model::TargetPoses::Dataset));  // the built-in scenes have cameras
  EXPECT_GT(s.at("targets").at("sensitivity").get<double>(), 0.0);
}
