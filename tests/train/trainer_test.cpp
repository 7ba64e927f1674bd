#include <gtest/gtest.h>

#include <fstream>

#include "train_test_util.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/state_dict.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/posed_lvsm.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/train/perceptual_loss.h"
#include "uplvsm/train/trainer.h"

using namespace uplvsm;
namespace fs = std::filesystem;

namespace {
using test::logged;
std::vector<double> logged_losses(const std::string& run) { return logged(run); }

// A run whose loss has a term beside the MSE: every logged loss is finite and above its MSE. Returns the losses.
std::vector<double> expect_losses_above_mse(const std::string& run, size_t steps) {
  const auto losses = logged_losses(run), mses = logged(run, "mse");
  EXPECT_EQ(losses.size(), steps);
  for (size_t i = 0; i < std::min(losses.size(), mses.size()); ++i) {
    EXPECT_TRUE(std::isfinite(losses[i]));
    EXPECT_GT(losses[i], mses[i]) << i;  // MSE plus a positive term
  }
  return losses;
}

}  // namespace

TEST(Trainer, LossFallsAndCheckpointRoundTrips) {
  auto config = test::micro_config();
  auto run = test::temp_dir("train_loss").string();
  auto result = train::train(config, test::micro_run_options(run));
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
  auto ckpt = io::read_checkpoint(run);
  EXPECT_EQ(ckpt.state.at("step").get<int64_t>(), 40);
  EXPECT_FALSE(ckpt.optimizer.empty());
  auto sd = io::state_dict(*net);
  ASSERT_EQ(sd.size(), ckpt.model.size());
  for (const auto& [k, v] : sd) EXPECT_TRUE(torch::equal(v, ckpt.model.at(k))) << k;
}

TEST(Trainer, ResumeReproducesTheUninterruptedRunExactly) {
  auto config = test::micro_config();
  config.training.train_steps = 16;
  auto straight = test::temp_dir("train_straight").string();
  train::train(config, test::micro_run_options(straight));

  auto resumed = test::temp_dir("train_resumed").string();
  auto first = test::micro_run_options(resumed);
  first.stop_after_steps = 7;
  EXPECT_EQ(train::train(config, first).step, 7);
  EXPECT_EQ(train::train(config, test::micro_run_options(resumed)).step, 16);  // --resume auto

  // Bitwise: same data per step (step-keyed loader), same optimiser state, same schedule.
  EXPECT_EQ(logged_losses(straight), logged_losses(resumed));
  auto a = io::read_checkpoint(straight), b = io::read_checkpoint(resumed);
  for (const auto& [k, v] : a.model) EXPECT_TRUE(torch::equal(v, b.model.at(k))) << k;
  for (const auto& [k, v] : a.optimizer) EXPECT_TRUE(torch::equal(v, b.optimizer.at(k))) << k;
}

namespace {

// `config` trained in one go, and again stopped after `stop_after` steps and resumed: both log the same losses (what
// a training option draws at random is keyed to the step). Returns the uninterrupted run's directory.
std::string expect_resumes_exactly(const Config& config, const std::string& name, int64_t stop_after) {
  auto straight = test::temp_dir(name).string();
  train::train(config, test::micro_run_options(straight));
  auto resumed = test::temp_dir(name + "_resumed").string();
  auto first = test::micro_run_options(resumed);
  first.stop_after_steps = stop_after;
  train::train(config, first);
  train::train(config, test::micro_run_options(resumed));
  EXPECT_EQ(logged_losses(resumed), logged_losses(straight));
  return straight;
}

// A loss term `config` turns on adds to the loss, and a run with it resumes exactly.
void expect_term_adds_to_the_loss_and_resumes_exactly(const Config& config, const std::string& name,
                                                      int64_t stop_after) {
  expect_losses_above_mse(expect_resumes_exactly(config, name, stop_after),
                          static_cast<size_t>(config.training.train_steps));
}

}  // namespace

// The gradient difference term (train/gradient_difference_loss.h; the shipped chain's later stages use it).
TEST(Trainer, GradientDifferenceTermAddsToTheLossAndResumesExactly) {
  auto config = test::micro_config();
  config.training.train_steps = 6;
  config.training.gradient_difference_weight = 0.5;
  expect_term_adds_to_the_loss_and_resumes_exactly(config, "train_gradient_difference", 2);
}

TEST(Trainer, ResumeRejectsADifferentModel) {
  auto config = test::micro_config();
  config.training.train_steps = 2;
  auto run = test::temp_dir("train_mismatch").string();
  train::train(config, test::micro_run_options(run));
  config.training.train_steps = 4;
  config.model.transformer.decoder_n_layer = 2;
  try {
    train::train(config, test::micro_run_options(run));
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("model config differs"), std::string::npos) << e.what();
  }
}

// The official always trains with the perceptual term; a config asking for it without VGG19 weights is refused
// before any data is read (here: a data root that does not exist) or the run directory is made.
TEST(Trainer, PerceptualLossNeedsVgg19WeightsOrAnExplicitZero) {
  auto config = test::micro_config();
  config.training.train_steps = 3;
  config.training.perceptual_loss_weight = 0.5;
  auto refused = test::temp_dir("train_no_vgg").string() + "/run";
  auto opt = test::micro_run_options(refused);
  opt.data_root = "/nonexistent/data";
  const auto msg = test::error_of([&] { train::train(config, opt); });
  for (const char* part : {"perceptual_loss_weight is 0.5", "--vgg19", "uplvsm convert", "perceptual_loss_weight=0"})
    EXPECT_NE(msg.find(part), std::string::npos) << msg;
  EXPECT_FALSE(fs::exists(refused));

  config.training.perceptual_loss_weight = 0;  // the explicit opt-out trains with MSE alone
  auto mse_only = test::temp_dir("train_mse_only").string();
  train::train(config, test::micro_run_options(mse_only));
  auto loss = logged(mse_only), mse = logged(mse_only, "mse");
  ASSERT_EQ(loss.size(), 3u);
  for (size_t i = 0; i < loss.size(); ++i) EXPECT_DOUBLE_EQ(loss[i], mse[i]);

  config.training.perceptual_loss_weight = 0.5;
  torch::manual_seed(1);
  train::PerceptualLoss vgg;
  io::TensorMap weights;
  for (const auto& [k, v] : io::state_dict(*vgg->vgg)) weights[k] = v;
  auto run = test::temp_dir("train_perceptual").string();
  const auto vgg_path = run + "/vgg19.safetensors";
  io::write_safetensors(vgg_path, weights, {{train::kVggInputMetadataKey, "matconvnet"}});
  auto with_vgg = test::micro_run_options(run + "/run");
  with_vgg.perceptual_weights = vgg_path;
  train::train(config, with_vgg);
  auto p_loss = logged(run + "/run"), p_mse = logged(run + "/run", "mse");
  ASSERT_EQ(p_loss.size(), 3u);
  EXPECT_DOUBLE_EQ(p_mse[0], mse[0]);  // same data and initial weights: the first MSE agrees
  for (size_t i = 0; i < p_loss.size(); ++i) EXPECT_GT(p_loss[i], p_mse[i] + 1e-4) << i;  // + 0.5 * perceptual
}

TEST(Trainer, Bf16AutocastKeepsFp32MasterWeights) {
  auto config = test::micro_config();
  config.training.train_steps = 3;
  config.training.amp = Amp::Bf16;
  auto run = test::temp_dir("train_bf16").string();
  auto result = train::train(config, test::micro_run_options(run));
  EXPECT_EQ(result.step, 3);
  for (double loss : logged(run)) EXPECT_TRUE(std::isfinite(loss) && loss > 0) << loss;
  auto ckpt = io::read_checkpoint(run);
  for (const auto& [k, v] : ckpt.model) EXPECT_EQ(v.scalar_type(), torch::kFloat32) << k;
}

TEST(Trainer, PeriodicEvaluationIsLoggedBesideTheLoss) {
  auto config = test::micro_config();
  config.training.train_steps = 6;
  config.training.eval_every = 4;
  auto run = test::temp_dir("train_periodic_eval").string();
  auto opt = test::micro_run_options(run);
  std::vector<int64_t> steps;
  opt.periodic_eval = [&](model::NovelViewModel& net, int64_t step) {
    EXPECT_FALSE(net->is_training());
    steps.push_back(step);
    return nlohmann::json{{"psnr", step == 4 ? 20.0 : 15.0}};
  };
  train::train(config, opt);
  EXPECT_EQ(steps, (std::vector<int64_t>{4, 6}));  // every 4 steps and at the end
  std::ifstream in(fs::path(run) / "metrics.jsonl");
  std::string line;
  std::vector<double> eval_psnr;
  while (std::getline(in, line)) {
    auto j = nlohmann::json::parse(line);
    if (j.contains("eval")) eval_psnr.push_back(j["eval"]["psnr"].get<double>());
  }
  EXPECT_EQ(eval_psnr, (std::vector<double>{20.0, 15.0}));
  // The evaluation scores the test split, so it selects no weights: no "best" checkpoint beside the rotating ones,
  // and the training state keeps no best score.
  EXPECT_FALSE(fs::exists(fs::path(run) / "checkpoints/best.safetensors"));
  auto latest = io::read_checkpoint(run);
  EXPECT_EQ(latest.state.at("step"), 6);
  EXPECT_FALSE(latest.state.contains("best_eval_psnr"));
}

TEST(Trainer, MapperStageFitsTheMapperToTheEstimatorThenTrainsThroughIt) {
  auto config = test::micro_config();
  config.training.train_steps = 8;
  auto base = test::temp_dir("train_mapper_base").string();
  train::train(config, test::micro_run_options(base));

  config.model.pose_mapper = true;
  config.training.target_poses = TargetPoses::Mapper;
  config.training.train_steps = 3;
  auto run = test::temp_dir("train_mapper").string();
  auto opt = test::micro_run_options(run);
  opt.init_weights = io::resolve_checkpoint(base);
  train::train(config, opt);
  auto ckpt = io::read_checkpoint(run);
  ASSERT_TRUE(ckpt.model.count("pose_mapper.A"));
  // The least-squares start moved A away from the identity, and the fine-tune trained it further.
  EXPECT_GT((ckpt.model.at("pose_mapper.A") - torch::eye(7)).abs().max().item<double>(), 1e-3);
  EXPECT_TRUE(ckpt.optimizer.size() > 0);
  for (double loss : logged(run)) EXPECT_TRUE(std::isfinite(loss)) << loss;
}

TEST(Trainer, InitIntoADeeperModelFailsNamingTheBlocksTheFileLacks) {
  auto config = test::micro_config();
  config.training.train_steps = 2;
  auto base = test::temp_dir("train_deepen_base").string();
  train::train(config, test::micro_run_options(base));
  config.model.transformer.decoder_n_layer = 2;
  auto opt = test::micro_run_options(test::temp_dir("train_deepen_deep").string());
  opt.init_weights = io::resolve_checkpoint(base);
  EXPECT_NE(test::error_of([&] { train::train(config, opt); }).find("transformer_decoder.1."), std::string::npos);
}

TEST(Trainer, PosedVariantsTrainThroughTheSameLoop) {
  auto config = test::micro_config();
  config.model.variant = Variant::PTLVSM;
  config.model.transformer.n_layer = 2;
  config.training.train_steps = 20;
  auto run = test::temp_dir("train_ptlvsm").string();
  train::train(config, test::micro_run_options(run));
  auto losses = logged(run);
  ASSERT_EQ(losses.size(), 20u);
  EXPECT_LT(losses[19] + losses[18], losses[0] + losses[1]);
  Config loaded;
  auto net = model::load_model(run, torch::kCPU, &loaded);
  EXPECT_EQ(loaded.model.variant, Variant::PTLVSM);
  EXPECT_EQ(model::as_uplvsm(*net), nullptr);  // the decoder-only model: no estimator
  EXPECT_NE(dynamic_cast<model::PosedLVSMImpl*>(net.get()), nullptr);
}
