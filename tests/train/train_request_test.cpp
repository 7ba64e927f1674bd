#include <gtest/gtest.h>

#include <filesystem>
#include <stdexcept>
#include <string>

#include "test_util.h"
#include "uplvsm/train/train_request.h"

using namespace uplvsm;

namespace {

train::TrainRequest tiny_request() {
  train::TrainRequest r;
  r.config_path = std::string(UPLVSM_SOURCE_DIR) + "/configs/tiny.json";
  return r;
}

}  // namespace

TEST(TrainRequest, AppliesTheSetStepsAmpAndSubsetOverrides) {
  auto r = tiny_request();
  r.set = {"training.warmup=7"};
  r.steps = 123;
  r.amp = "bf16";
  r.subset = "little.json";
  const auto config = train::train_config(r);
  EXPECT_EQ(config.training.warmup, 7);
  EXPECT_EQ(config.training.train_steps, 123);
  EXPECT_EQ(config.training.amp, Amp::Bf16);
  EXPECT_EQ(config.training.subset, std::filesystem::absolute("little.json").string());
  EXPECT_FALSE(config.model.pose_mapper);
}

TEST(TrainRequest, MapperStageTurnsOnThePoseMapperAndNeedsAStart) {
  auto r = tiny_request();
  r.stage = "mapper";
  r.init = "model.safetensors";
  const auto config = train::train_config(r);
  EXPECT_TRUE(config.model.pose_mapper);
  EXPECT_EQ(config.training.target_poses, TargetPoses::Mapper);
  r.init.clear();
  r.resume = "none";
  EXPECT_THROW(train::train_config(r), std::runtime_error);
}

TEST(TrainRequest, DryRunPlanCarriesTheRequestWithoutData) {
  auto r = tiny_request();
  r.vgg19 = "vgg.safetensors";
  r.init = "init.safetensors";
  const auto config = train::train_config(r);
  const auto plan = train::dry_run_plan(r, config, 1, "cpu");
  EXPECT_EQ(plan.device, "cpu");
  EXPECT_EQ(plan.perceptual_weights, "vgg.safetensors");
  EXPECT_EQ(plan.init, "init.safetensors");
  EXPECT_FALSE(plan.resuming);
  EXPECT_FALSE(plan.scenes.has_value());
  EXPECT_EQ(plan.batch.ranks, 1);
}

TEST(TrainRequest, RequireRunStartsRefusesAPerceptualLossWithoutWeights) {
  auto r = tiny_request();
  r.set = {"training.perceptual_loss_weight=0.5"};
  const auto config = train::train_config(r);
  EXPECT_THROW(train::require_run_starts(train::dry_run_plan(r, config, 1, "cpu")), std::runtime_error);
  r.vgg19 = "vgg.safetensors";
  EXPECT_NO_THROW(train::require_run_starts(train::dry_run_plan(r, config, 1, "cpu")));
}
