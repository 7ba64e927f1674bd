// `uplvsm train` as a user meets it: --dry-run's plan (the paper's global batch on one process and on eight), and a
// full-size command without --vgg19 or without the pretrained tokenizer refused at once, before any data is read.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <string>

#include "test_util.h"
#include "uplvsm/core/autocast.h"

using namespace uplvsm;

namespace {
std::string config(const std::string& name) { return std::string(UPLVSM_SOURCE_DIR) + "/configs/" + name + ".json"; }
}  // namespace

TEST(TrainCli, DryRunShowsThePapersGlobalBatchOnOneProcessAndOnEight) {
  // Any existing files: a dry run only checks that --vgg19 and --init are given.
  const auto vgg = config("tiny") + " --init " + config("tiny");
  std::string out;
  ASSERT_EQ(test::run_cli("train --dry-run --config " + config("paper_x224") + " --vgg19 " + vgg, &out), 0);
  EXPECT_NE(out.find("128 scenes per update = 16 per micro-batch x 8 accumulated x 1 rank(s)"), std::string::npos)
      << out;
  // bf16 where this CPU has native bf16 dot products; elsewhere the plan says it runs fp32 and why.
  EXPECT_NE(
      out.find(bf16_autocast_pays(torch::kCPU) ? "bf16 autocast" : "fp32 (bf16 asked for: this CPU has no native"),
      std::string::npos)
      << out;
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
  EXPECT_NE(test::run_cli("train --config " + config("paper_x224") + " --init " + config("tiny") + " --data " +
                              data.string() + " --run " + run.string(),
                          &out),
            0);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 20.0);
  for (const char* part : {"--vgg19", "uplvsm convert", "--set training.perceptual_loss_weight=0"})
    EXPECT_NE(out.find(part), std::string::npos) << out;
  EXPECT_FALSE(std::filesystem::exists(run));
  // The dry run of the same command says the same, after its plan.
  EXPECT_NE(test::run_cli("train --dry-run --config " + config("paper_x224") + " --init " + config("tiny"), &out), 0);
  EXPECT_NE(out.find("VGG19 MISSING"), std::string::npos) << out;
  EXPECT_NE(out.find("uplvsm convert"), std::string::npos) << out;
}

// The authors always start the DINOv2 ViT-B/14 tokenizer from Meta's pretrained weights: a full-size run without
// --init refuses within seconds, naming the file and the explicit opt-out; the dry-run says where the tokenizer
// starts in each case.
TEST(TrainCli, FullSizeTrainingWithoutPretrainedTokenizerIsRefusedAtOnce) {
  const auto dir = test::temp_dir("train_cli_no_init");
  const auto data = dir / "data";
  std::filesystem::create_directories(data / "train");
  const auto run = dir / "run";
  const std::string no_perceptual = " --set training.perceptual_loss_weight=0";
  std::string out;
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_NE(test::run_cli("train --config " + config("paper_x224") + no_perceptual + " --data " + data.string() +
                              " --run " + run.string(),
                          &out),
            0);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 20.0);
  for (const char* part :
       {"--init dinov2_vitb14_reg4_pretrain.pth", "dl.fbaipublicfiles.com", "--set training.random_tokenizer=true"})
    EXPECT_NE(out.find(part), std::string::npos) << out;
  EXPECT_FALSE(std::filesystem::exists(run));
  EXPECT_NE(test::run_cli("train --dry-run --config " + config("paper_x224") + no_perceptual, &out), 0);
  EXPECT_NE(out.find("tokenizer     MISSING"), std::string::npos) << out;
  ASSERT_EQ(test::run_cli("train --dry-run --config " + config("paper_x224") + no_perceptual +
                              " --set training.random_tokenizer=true",
                          &out),
            0)
      << out;
  EXPECT_NE(out.find("random, by choice"), std::string::npos) << out;
  ASSERT_EQ(test::run_cli(
                "train --dry-run --config " + config("paper_x224") + no_perceptual + " --init " + config("tiny"), &out),
            0)
      << out;
  EXPECT_NE(out.find("tokenizer     --init " + config("tiny")), std::string::npos) << out;
  ASSERT_EQ(test::run_cli("train --dry-run --config " + config("tiny"), &out), 0) << out;
  EXPECT_NE(out.find("random (no released DINOv2 weights of this size)"), std::string::npos) << out;
}
