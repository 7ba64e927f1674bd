// training.ema_decay: the weight average against a hand computation, its place in checkpoints, evaluations and the
// resume, and that it leaves the training itself unchanged.
#include <gtest/gtest.h>

#include <fstream>

#include "train_test_util.h"
#include "uplvsm/model/checkpoint_io.h"
#include "uplvsm/model/memory_estimate.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/state_dict.h"
#include "uplvsm/train/checkpoint.h"
#include "uplvsm/train/trainer.h"
#include "uplvsm/train/weight_ema.h"

using namespace uplvsm;
namespace fs = std::filesystem;

namespace {

std::vector<double> ema_run_losses(const std::string& run) {
  std::vector<double> out;
  std::ifstream in(fs::path(run) / "metrics.jsonl");
  std::string line;
  while (std::getline(in, line))
    if (!line.empty() && nlohmann::json::parse(line).contains("loss"))
      out.push_back(nlohmann::json::parse(line).at("loss").get<double>());
  return out;
}

Config ema_config(double decay, int64_t steps) {
  auto c = test::micro_config();
  c.training.train_steps = steps;
  c.training.ema_decay = decay;
  return c;
}

void expect_same_tensors(const model::NamedTensors& a, const model::NamedTensors& b, const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (const auto& [k, v] : a) EXPECT_TRUE(torch::equal(v, b.at(k))) << what << ": " << k;
}

}  // namespace

TEST(WeightEma, DecayWarmsUpThenHoldsTheConfiguredValue) {
  EXPECT_DOUBLE_EQ(train::ema_decay_at(0.999, 0), 0.1);  // (1 + 0) / (10 + 0)
  EXPECT_DOUBLE_EQ(train::ema_decay_at(0.999, 10), 11.0 / 20.0);
  EXPECT_DOUBLE_EQ(train::ema_decay_at(0.999, 100000), 0.999);
  EXPECT_DOUBLE_EQ(train::ema_decay_at(0.5, 100), 0.5);
}

TEST(WeightEma, UpdateAndSwapMatchAHandComputation) {
  torch::nn::Linear layer(3, 2);
  auto ema = train::make_weight_ema(*layer, 0.9);
  ASSERT_EQ(ema.names, (std::vector<std::string>{"bias", "weight"}));  // by name, as the optimiser state
  const auto w0 = layer->weight.detach().clone();
  std::vector<torch::Tensor> expected{w0.to(torch::kDouble)};
  for (int n = 0; n < 3; ++n) {
    {
      torch::NoGradGuard no_grad;
      layer->weight.add_(0.25 * (n + 1));
    }
    const double d = std::min(0.9, (1.0 + n) / (10.0 + n));
    expected.push_back(d * expected.back() + (1 - d) * layer->weight.detach().to(torch::kDouble));
    train::update_weight_ema(ema, n);
  }
  EXPECT_TRUE(torch::allclose(ema.average[1].to(torch::kDouble), expected.back(), 0, 1e-6));
  const auto trained = layer->weight.detach().clone();
  {
    train::WeightEmaScope average(&ema);
    EXPECT_TRUE(torch::equal(layer->weight, ema.params[1]));  // the module's own tensor, now the average
    EXPECT_TRUE(torch::allclose(layer->weight.detach().to(torch::kDouble), expected.back(), 0, 1e-6));
    EXPECT_TRUE(torch::equal(train::online_weights_while_swapped(ema).at("online/weight"), trained));
  }
  EXPECT_TRUE(torch::equal(layer->weight, trained));  // swapped back
}

TEST(WeightEma, RestoringOnlineWeightsChecksNamesAndShapes) {
  torch::nn::Linear layer(3, 2);
  auto ema = train::make_weight_ema(*layer, 0.9);
  EXPECT_FALSE(train::restore_online_weights(ema, {{"exp_avg/weight", torch::zeros({2, 3})}}, "f.safetensors"));
  auto message = [&](const model::NamedTensors& state) {
    try {
      train::restore_online_weights(ema, state, "f.safetensors");
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message({{"online/weight", torch::zeros({2, 3})}}).find("f.safetensors: 1 trained-weight tensors"),
            std::string::npos);
  EXPECT_NE(message({{"online/weight", torch::zeros({3, 3})}, {"online/bias", torch::zeros({2})}})
                .find("online/weight have shape [3,3] but the parameter is [2,3]"),
            std::string::npos);
  EXPECT_NE(message({{"online/weight", torch::zeros({2, 3})}, {"online/bian", torch::zeros({2})}})
                .find("no trained weights online/bias"),
            std::string::npos);
  const auto loaded = layer->weight.detach().clone();
  EXPECT_TRUE(train::restore_online_weights(
      ema, {{"online/weight", torch::ones({2, 3})}, {"online/bias", torch::ones({2})}}, "f.safetensors"));
  EXPECT_TRUE(torch::equal(layer->weight, torch::ones({2, 3})));  // the trained weights go on training
  EXPECT_TRUE(torch::equal(ema.average[1], loaded));              // the loaded average stays the average
}

// The average leaves the training as it was (same losses, the checkpoint's trained weights are the plain run's), and
// the checkpoint's model tensors are the average of the weights after every step, computed here from the plain run's
// per-step checkpoints.
TEST(WeightEma, CheckpointHoldsTheAverageOfThePlainRunsWeights) {
  const int64_t steps = 6;
  auto plain_config = ema_config(0, steps);
  plain_config.training.checkpoint_every = 1;
  plain_config.training.keep_checkpoints = steps;
  auto plain = test::temp_dir("ema_plain").string();
  train::train(plain_config, test::micro_run_options(plain));
  auto averaged = test::temp_dir("ema_averaged").string();
  train::train(ema_config(0.8, steps), test::micro_run_options(averaged));
  EXPECT_EQ(ema_run_losses(averaged), ema_run_losses(plain));

  torch::manual_seed(static_cast<uint64_t>(plain_config.training.seed));
  auto start = model::state_dict(*model::make_model(plain_config.model));  // the run's first weights
  std::map<std::string, torch::Tensor> expected;
  for (const auto& [k, v] : start) expected[k] = v.to(torch::kDouble);
  const auto all = train::training_checkpoints(plain + "/checkpoints");
  ASSERT_EQ(all.size(), static_cast<size_t>(steps));
  for (int64_t n = 0; n < steps; ++n) {
    const double d = std::min(0.8, (1.0 + n) / (10.0 + n));
    for (const auto& [k, v] : model::read_checkpoint(all[n]).model)
      expected[k] = d * expected[k] + (1 - d) * v.to(torch::kDouble);
  }
  const auto ckpt = model::read_checkpoint(averaged);
  const auto last_plain = model::read_checkpoint(all.back());
  EXPECT_EQ(ckpt.state.at("ema_updates").get<int64_t>(), steps);
  int64_t differ = 0;
  for (const auto& [k, v] : ckpt.model) {
    EXPECT_TRUE(torch::allclose(v.to(torch::kDouble), expected.at(k), 0, 1e-6)) << k;
    const auto online = ckpt.optimizer.find("online/" + k);
    const auto& trained = online == ckpt.optimizer.end() ? v : online->second;  // a buffer is its own average
    EXPECT_TRUE(torch::equal(trained, last_plain.model.at(k))) << k;
    differ += !torch::equal(v, last_plain.model.at(k));
  }
  EXPECT_GT(differ, 0);
}

TEST(WeightEma, RunsResumeExactlyAndEvaluateTheAverage) {
  auto config = ema_config(0.9, 10);
  config.training.eval_every = 10;
  auto straight = test::temp_dir("ema_straight").string();
  model::NamedTensors evaluated;
  auto with_eval = [&](const std::string& run) {
    auto o = test::micro_run_options(run);
    o.periodic_eval = [&](model::NovelViewModel& net, int64_t) {
      evaluated.clear();
      for (const auto& [k, v] : model::state_dict(*net)) evaluated[k] = v.clone();  // not the live tensors
      return nlohmann::json{{"psnr", 20.0}};
    };
    return o;
  };
  train::train(config, with_eval(straight));
  const auto a = model::read_checkpoint(straight);
  expect_same_tensors(evaluated, a.model, "the evaluation's weights against the checkpoint's average");
  expect_same_tensors(model::read_checkpoint(straight + "/checkpoints/best.safetensors").model, a.model, "best");

  auto resumed = test::temp_dir("ema_resumed").string();
  auto first = test::micro_run_options(resumed);
  first.stop_after_steps = 4;
  train::train(config, first);
  train::train(config, with_eval(resumed));
  const auto b = model::read_checkpoint(resumed);
  EXPECT_EQ(ema_run_losses(resumed), ema_run_losses(straight));
  expect_same_tensors(b.model, a.model, "the average");
  expect_same_tensors(b.optimizer, a.optimizer, "optimiser state and trained weights");
}

// Turning the average off on resume goes on from the trained weights, not from their average.
TEST(WeightEma, ResumingWithoutTheAverageGoesOnFromTheTrainedWeights) {
  auto plain = test::temp_dir("ema_off_plain").string();
  train::train(ema_config(0, 10), test::micro_run_options(plain));
  auto switched = test::temp_dir("ema_off_switched").string();
  auto first = test::micro_run_options(switched);
  first.stop_after_steps = 4;
  train::train(ema_config(0.9, 10), first);
  train::train(ema_config(0, 10), test::micro_run_options(switched));
  EXPECT_EQ(ema_run_losses(switched), ema_run_losses(plain));
  const auto ckpt = model::read_checkpoint(switched);
  for (const auto& [k, v] : ckpt.optimizer) EXPECT_NE(k.rfind("online/", 0), 0u) << k;
  EXPECT_EQ(ckpt.state.at("ema_updates").get<int64_t>(), 0);  // turned on again, its warm-up starts afresh
  expect_same_tensors(ckpt.model, model::read_checkpoint(plain).model, "weights");
}

TEST(WeightEma, ConfigRangeAndMemory) {
  auto message = [](double decay) {
    auto c = test::micro_config();
    c.training.ema_decay = decay;
    try {
      validate_config(c, "cfg.json");
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message(0.999), "no error");
  for (double bad : {-0.1, 1.0, std::nan("")})
    EXPECT_NE(message(bad).find("cfg.json: training.ema_decay must be in [0, 1)"), std::string::npos) << bad;
  auto c = test::micro_config();
  const double plain = model::training_memory(c).state_bytes;
  c.training.ema_decay = 0.99;
  EXPECT_DOUBLE_EQ(model::training_memory(c).state_bytes, plain * 20 / 16);
}
