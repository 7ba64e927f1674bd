// The tokenizer's masked-image pretraining stage: the loss falls, the run is deterministic, and its file starts a
// UP-LVSM run through --init exactly like Meta's DINOv2 weights would (every ViT tensor arrives).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "test_util.h"
#include "train_test_util.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/state_dict.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/train/tokenizer_pretraining.h"
#include "uplvsm/train/trainer.h"

using namespace uplvsm;
namespace fs = std::filesystem;

namespace {
train::TokenizerPretrainResult pretrain(const Config& config, const std::string& run) {
  train::TokenizerPretrainOptions opt;
  opt.data_root = test::micro_dataset();
  opt.run_dir = run;
  opt.progress = false;
  return train::pretrain_tokenizer(config, opt);
}
}  // namespace

TEST(TokenizerPretraining, LossFallsDeterministicallyAndInitLoadsTheTokenizer) {
  auto config = test::micro_config();
  config.training.train_steps = 30;
  const auto run = test::temp_dir("tokenizer_stage").string();
  const auto r = pretrain(config, run);
  EXPECT_EQ(r.steps, 30);
  EXPECT_LT(r.last_loss, 0.8 * r.first_loss) << r.first_loss << " -> " << r.last_loss;
  ASSERT_TRUE(fs::exists(r.weights));
  // Same seed, same data order: the same weights.
  const auto again = pretrain(config, test::temp_dir("tokenizer_stage_again").string());
  const auto a = io::read_safetensors(r.weights).tensors, b = io::read_safetensors(again.weights).tensors;
  ASSERT_EQ(a.size(), b.size());
  for (const auto& [k, v] : a) EXPECT_TRUE(torch::equal(v, b.at(k))) << k;
  ASSERT_TRUE(a.count("mask_token"));
  // A finished stage is not redone.
  EXPECT_EQ(pretrain(config, run).steps, 0);

  // `train --init <file>`: the UP-LVSM's tokenizer starts from exactly these tensors.
  config.training.train_steps = 1;
  train::TrainOptions topt;
  topt.data_root = test::micro_dataset();
  topt.run_dir = test::temp_dir("tokenizer_init").string();
  topt.init_weights = r.weights;
  topt.progress = false;
  config.training.lr = 0;  // the one step leaves the weights as loaded
  train::train(config, topt);
  auto trained = io::state_dict(*model::load_model(topt.run_dir, torch::kCPU));
  int64_t compared = 0;
  for (const auto& [k, v] : a) {
    if (k == "mask_token") continue;
    const auto key = "image_tokenizer.1.dino_vit." + k;
    ASSERT_TRUE(trained.count(key)) << key;
    EXPECT_TRUE(torch::equal(v, trained.at(key))) << key;
    ++compared;
  }
  EXPECT_GT(compared, 10);
}
