// `uplvsm eval`'s options through eval:: without the binary: the protocol auto picks (as trained; the mapper given
// with --mapper), and what metrics.json records of the request.
#include "uplvsm/eval/evaluation_run.h"

#include <gtest/gtest.h>

#include <fstream>

#include "train/train_test_util.h"
#include "uplvsm/model/model_factory.h"

using namespace uplvsm;

TEST(EvaluationRun, AutoIsTheTrainedProtocolOrTheMapperGivenAndTheRequestIsRecorded) {
  const auto dir = test::temp_dir("evaluation_run");
  const auto checkpoint = (dir / "ckpt.safetensors").string();
  std::ofstream(checkpoint) << "x";
  auto config = test::micro_config();
  torch::manual_seed(1);
  auto net = model::make_model(config.model);
  eval::EvalRequest r;
  r.checkpoint = checkpoint;
  r.data = "rooms";
  r.out = "out";
  r.max_scenes = 3;
  r.refinement.steps = 2;
  r.bf16 = true;
  auto opt = eval::evaluation_options(r, config, net, torch::kCPU);
  EXPECT_EQ(opt.target_poses, model::TargetPoses::Estimator);
  EXPECT_EQ(opt.max_scenes, 3);
  EXPECT_TRUE(opt.bf16);
  EXPECT_FALSE(opt.lpips);
  EXPECT_EQ(opt.extra.at("checkpoint"), checkpoint);
  EXPECT_EQ(opt.extra.at("data"), "rooms");
  EXPECT_EQ(opt.extra.at("config"), "micro");
  EXPECT_EQ(opt.extra.at("target_poses"), "estimator");
  EXPECT_EQ(opt.extra.at("pose_refinement").at("steps"), 2);
  // Trained from dataset cameras: auto scores with them.
  config.training.target_poses = TargetPoses::Dataset;
  EXPECT_EQ(eval::evaluation_options(r, config, net, torch::kCPU).target_poses, model::TargetPoses::Dataset);
  // A --mapper: auto is the mapper's protocol.
  model::require_uplvsm(net, "test")->attach_pose_mapper(model::PoseMapper(model::PoseMapperOptions{}));
  r.mapper = "m.safetensors";
  opt = eval::evaluation_options(r, config, net, torch::kCPU);
  EXPECT_EQ(opt.target_poses, model::TargetPoses::Mapper);
  EXPECT_EQ(opt.extra.at("mapper"), "m.safetensors");
}
