// The held-out evaluation during training scores what the official train.py's does: the run's pose noise on the
// cameras (posed variants), its precision and target poses, a fixed number of scenes.
#include "uplvsm/eval/training_evaluation.h"

#include <gtest/gtest.h>

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
