#include <gtest/gtest.h>

#include <fstream>

#include "train_test_util.h"
#include "uplvsm/model/checkpoint_io.h"
#include "uplvsm/train/trainer.h"

using namespace uplvsm;
namespace fs = std::filesystem;

namespace {
std::vector<double> logged_losses(const std::string& run) {
  std::vector<double> out;
  std::ifstream in(fs::path(run) / "metrics.jsonl");
  std::string line;
  while (std::getline(in, line))
    if (!line.empty()) out.push_back(nlohmann::json::parse(line).at("loss").get<double>());
  return out;
}

train::TrainOptions options(const std::string& run) {
  train::TrainOptions o;
  o.data_root = test::micro_dataset();
  o.run_dir = run;
  o.progress = false;
  return o;
}
}  // namespace

TEST(Trainer, LossFallsAndCheckpointRoundTrips) {
  auto config = test::micro_config();
  auto run = test::temp_dir("train_loss").string();
  auto result = train::train(config, options(run));
  EXPECT_EQ(result.step, 40);
  auto losses = logged_losses(run);
  ASSERT_EQ(losses.size(), 40u);
  double first = 0, last = 0;
  for (int i = 0; i < 5; ++i) first += losses[i] / 5, last += losses[35 + i] / 5;
  EXPECT_LT(last, 0.7 * first) << "first " << first << " last " << last;

  // The checkpoint rebuilds the same model: identical weights and outputs.
  Config loaded_config;
  auto net = model::load_model(run, torch::kCPU, &loaded_config);
  EXPECT_EQ(config_to_json(loaded_config), config_to_json(config));
  auto ckpt = model::read_checkpoint(run);
  EXPECT_EQ(ckpt.state.at("step").get<int64_t>(), 40);
  EXPECT_FALSE(ckpt.optimizer.empty());
  auto sd = model::state_dict(*net);
  ASSERT_EQ(sd.size(), ckpt.model.size());
  for (const auto& [k, v] : sd) EXPECT_TRUE(torch::equal(v, ckpt.model.at(k))) << k;
}

TEST(Trainer, ResumeReproducesTheUninterruptedRunExactly) {
  auto config = test::micro_config();
  config.training.train_steps = 16;
  auto straight = test::temp_dir("train_straight").string();
  train::train(config, options(straight));

  auto resumed = test::temp_dir("train_resumed").string();
  auto first = options(resumed);
  first.stop_after_steps = 7;
  EXPECT_EQ(train::train(config, first).step, 7);
  EXPECT_EQ(train::train(config, options(resumed)).step, 16);  // --resume auto

  // Bitwise: same data per step (step-keyed loader), same optimiser state, same schedule.
  EXPECT_EQ(logged_losses(straight), logged_losses(resumed));
  auto a = model::read_checkpoint(straight), b = model::read_checkpoint(resumed);
  for (const auto& [k, v] : a.model) EXPECT_TRUE(torch::equal(v, b.model.at(k))) << k;
  for (const auto& [k, v] : a.optimizer) EXPECT_TRUE(torch::equal(v, b.optimizer.at(k))) << k;
}

TEST(Trainer, ResumeRejectsADifferentModel) {
  auto config = test::micro_config();
  config.training.train_steps = 2;
  auto run = test::temp_dir("train_mismatch").string();
  train::train(config, options(run));
  config.training.train_steps = 4;
  config.model.transformer.decoder_n_layer = 2;
  try {
    train::train(config, options(run));
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("model config differs"), std::string::npos) << e.what();
  }
}
