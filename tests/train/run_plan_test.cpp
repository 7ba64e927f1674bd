#include <gtest/gtest.h>

#include <string>

#include "test_util.h"
#include "uplvsm/train/run_plan.h"

using namespace uplvsm;

namespace {

std::string described(const train::RunPlan& plan) {
  std::string all;
  for (const auto& line : train::describe_run_plan(plan)) all += line + "\n";
  return all;
}

void expect_has(const std::string& text, const std::string& part) {
  EXPECT_NE(text.find(part), std::string::npos) << "missing '" << part << "' in\n" << text;
}

}  // namespace

TEST(RunPlan, SaysTheGlobalBatchScheduleLossDataAndShuffling) {
  train::RunPlan plan;
  plan.config = load_config(std::string(UPLVSM_SOURCE_DIR) + "/configs/paper_x224.json");
  plan.batch = train::plan_batch(plan.config.training, 1, "paper_x224");
  plan.device = "cuda:0";
  plan.perceptual_weights = "x224.vgg19.safetensors";
  plan.data_root = "re10k";
  plan.scenes = 64000;
  const auto text = described(plan);
  expect_has(text, "128 scenes per update = 16 per micro-batch x 8 accumulated x 1 rank(s)");
  expect_has(text, "100000 updates; AdamW lr 0.0004 (betas 0.9/0.95, weight decay 0.05), linear warmup 4000");
  expect_has(text, "bf16 autocast, fp32 master weights; TF32 on; on cuda:0");
  expect_has(text, "1 x MSE + 0.5 x perceptual (VGG19 from x224.vgg19.safetensors)");
  expect_has(text, "64000 scenes of re10k; 12800000 samples in all = 200.0 epochs");
  expect_has(text, "the whole split, reshuffled each epoch");
  expect_has(text, "context views 25..192 frames apart");
}

TEST(RunPlan, SaysWhatIsMissingOrDifferentFromTheOfficial) {
  train::RunPlan plan;
  plan.config.training.perceptual_loss_weight = 0.5;
  plan.config.training.chunks_per_shuffle = 2;
  plan.config.training.amp = Amp::None;
  plan.batch = train::plan_batch(plan.config.training, 8, "c");
  const auto text = described(plan);
  expect_has(text, "x 1 accumulated x 8 rank(s)");
  expect_has(text, "VGG19 MISSING: the run refuses to start");
  expect_has(text, "2 chunk(s) at a time");
  expect_has(text, "fp32; TF32 off (CUDA only: no effect here); on cpu");
  expect_has(text, "not given (--data)");
}
