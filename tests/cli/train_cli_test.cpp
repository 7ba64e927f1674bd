// `uplvsm train` as a user meets it: --dry-run's plan (the paper's global batch on one process and on eight), and a
// full-size command without --vgg19 refused at once, before any data is read.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <string>

#include "test_util.h"

using namespace uplvsm;

namespace {
std::string config(const std::string& name) { return std::string(UPLVSM_SOURCE_DIR) + "/configs/" + name + ".json"; }
}  // namespace

TEST(TrainCli, DryRunShowsThePapersGlobalBatchOnOneProcessAndOnEight) {
  const auto vgg = config("tiny");  // any existing file: a dry run only checks that --vgg19 is given
  std::string out;
  ASSERT_EQ(test::run_cli("train --dry-run --config " + config("paper_x224") + " --vgg19 " + vgg, &out), 0);
  EXPECT_NE(out.find("128 scenes per update = 16 per micro-batch x 8 accumulated x 1 rank(s)"), std::string::npos)
      << out;
  EXPECT_NE(out.find("bf16 autocast"), std::string::npos) << out;
  EXPECT_NE(out.find("the whole split, reshuffled each epoch"), std::string::npos) << out;
  ASSERT_EQ(test::run_cli("train --dry-run --ranks 8 --config " + config("paper_x224") + " --vgg19 " + vgg, &out), 0);
  EXPECT_NE(out.find("128 scenes per update = 16 per micro-batch x 1 accumulated x 8 rank(s)"), std::string::npos)
      << out;
  ASSERT_EQ(test::run_cli("train --dry-run --config " + config("paper_x518") + " --vgg19 " + vgg, &out), 0);
  EXPECT_NE(out.find("48 scenes per update = 6 per micro-batch x 8 accumulated x 1 rank(s)"), std::string::npos) << out;
  // Planned on 3 ranks, 128 does not divide: the plan says why instead of training on another batch.
  EXPECT_NE(test::run_cli("train --dry-run --ranks 3 --config " + config("paper_x224") + " --vgg19 " + vgg, &out), 0);
  EXPECT_NE(out.find("training.global_batch_size = 128 is not a multiple"), std::string::npos) << out;
}

TEST(TrainCli, FullSizeTrainingWithoutVgg19IsRefusedAtOnce) {
  const auto dir = test::temp_dir("train_cli_no_vgg");
  const auto data = dir / "data";
  std::filesystem::create_directories(data / "train");  // empty: reading it would fail with another message
  const auto run = dir / "run";
  std::string out;
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_NE(test::run_cli(
                "train --config " + config("paper_x224") + " --data " + data.string() + " --run " + run.string(), &out),
            0);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 20.0);
  for (const char* part : {"--vgg19", "uplvsm convert", "--set training.perceptual_loss_weight=0"})
    EXPECT_NE(out.find(part), std::string::npos) << out;
  EXPECT_FALSE(std::filesystem::exists(run));
  // The dry run of the same command says the same, after its plan.
  EXPECT_NE(test::run_cli("train --dry-run --config " + config("paper_x224"), &out), 0);
  EXPECT_NE(out.find("VGG19 MISSING"), std::string::npos) << out;
  EXPECT_NE(out.find("uplvsm convert"), std::string::npos) << out;
}
