// The held-out evaluation during training scores what the official train.py's does: the run's pose noise on the
// cameras (posed variants), its precision and target poses, a fixed number of scenes; a fitted mapper's score goes
// through the mapper.
#include "uplvsm/eval/training_evaluation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "train/train_test_util.h"
#include "uplvsm/model/model_factory.h"

using namespace uplvsm;

TEST(TrainingEvaluation, ScoresWithTheRunsPoseNoiseAsTheOfficialEvaluation) {
  Config config;
  config.training.pose_noise_std = 0.1;
  config.training.seed = 778;
  config.training.amp = Amp::Bf16;
  auto opt = eval::training_evaluation_options(config, model::TargetPoses::Dataset, torch::kCPU);
  EXPECT_EQ(opt.pose_noise_std, 0.1);
  EXPECT_EQ(opt.pose_noise_seed, 778u);
  EXPECT_TRUE(opt.bf16);
  EXPECT_EQ(opt.target_poses, model::TargetPoses::Dataset);
  EXPECT_EQ(opt.max_scenes, 16) << "eval.max_scenes 0: 16 scenes";
  config.eval.max_scenes = 5;
  config.training.pose_noise_std = 0;
  opt = eval::training_evaluation_options(config, model::TargetPoses::Estimator, torch::kCPU);
  EXPECT_EQ(opt.pose_noise_std, 0.0);
  EXPECT_EQ(opt.max_scenes, 5);
}

// A fitted mapper is scored at real cameras through it (a model without one cannot be), on the test split's first
// scenes, with what the caller records in metrics.json.
TEST(TrainingEvaluation, AMapperIsScoredAtRealCamerasThroughIt) {
  const auto dir = test::temp_dir("evaluate_mapper");
  const auto config = test::micro_config();
  torch::manual_seed(3);
  auto net = model::make_model(config.model);
  const auto out = (dir / "eval").string();
  EXPECT_ANY_THROW(
      eval::evaluate_mapper(net, config, test::micro_dataset(), 1, false, torch::kCPU, out, nlohmann::json::object()));
  model::require_uplvsm(net, "test")->attach_pose_mapper(model::PoseMapper(model::PoseMapperOptions{}));
  const auto summary = eval::evaluate_mapper(net, config, test::micro_dataset(), 1, false, torch::kCPU, out,
                                             {{"mapper", "m.safetensors"}});
  EXPECT_EQ(summary.scenes, 1);
  EXPECT_TRUE(std::isfinite(summary.scores.model.psnr));
  std::ifstream in(std::filesystem::path(out) / "metrics.json");
  const auto metrics = nlohmann::json::parse(in);
  EXPECT_NE(metrics.dump().find("m.safetensors"), std::string::npos);
  EXPECT_NE(metrics.dump().find("\"mapper\""), std::string::npos);
}
