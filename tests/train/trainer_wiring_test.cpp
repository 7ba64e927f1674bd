// What the trainer hands to the functions it calls: each test fails when the trainer drops one piece of the
// recipe (the accumulation and its data stream, autocast, TF32, the pose noise, the scene frame of the cameras,
// frames of another size), not only when the function itself is wrong.
#include <gtest/gtest.h>

#include <ATen/Context.h>

#include <cstdlib>

#include "train_test_util.h"
#include "uplvsm/core/autocast.h"
#include "uplvsm/data/loader.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/train/optimizer.h"
#include "uplvsm/train/trainer.h"

using namespace uplvsm;
using test::logged;

namespace {

// The losses of `config` trained from scratch on the micro dataset.
std::vector<double> losses_of(const Config& config, const std::string& name) {
  const auto run = test::temp_dir(name).string();
  train::train(config, test::micro_run_options(run));
  return logged(run);
}

}  // namespace

// Two micro-batches of one scene accumulated are one batch of two: the same scenes, views and loss per update.
TEST(TrainerWiring, AccumulatedMicroBatchesAreTheGlobalBatch) {
  auto whole = test::micro_config();
  whole.training.train_steps = 4;
  whole.training.batch_size = 2;
  auto accumulated = whole;
  accumulated.training.batch_size = 1;
  accumulated.training.global_batch_size = 2;
  const auto a = losses_of(whole, "wiring_whole"), b = losses_of(accumulated, "wiring_accumulated");
  ASSERT_EQ(a.size(), 4u);
  ASSERT_EQ(b.size(), 4u);
  for (size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(b[i], a[i], 1e-5 * a[i]) << i;
}

// The stream is keyed to micro-batches: a run with accumulation resumed mid-way reads what it would have read.
TEST(TrainerWiring, AccumulatedRunResumesExactly) {
  auto config = test::micro_config();
  config.training.train_steps = 6;
  config.training.batch_size = 1;
  config.training.global_batch_size = 2;
  const auto straight = losses_of(config, "wiring_accum_straight");
  const auto resumed = test::temp_dir("wiring_accum_resumed").string();
  auto first = test::micro_run_options(resumed);
  first.stop_after_steps = 3;
  train::train(config, first);
  train::train(config, test::micro_run_options(resumed));
  EXPECT_EQ(logged(resumed), straight);
}

// training.amp bf16 reaches the forward where bf16 pays: the first update's loss (same weights, same batch) moves
// under autocast. On a CPU without native bf16 dot products the run is fp32 (the same loss), unless
// UPLVSM_FORCE_BF16=1 asks for bf16 anyway.
TEST(TrainerWiring, Bf16AutocastChangesTheFirstLoss) {
  auto config = test::micro_config();
  config.training.train_steps = 1;
  const double fp32 = losses_of(config, "wiring_fp32").at(0);
  config.training.amp = Amp::Bf16;
  const double asked = losses_of(config, "wiring_bf16").at(0);
  if (bf16_autocast_pays(torch::kCPU))
    EXPECT_NE(asked, fp32);
  else
    EXPECT_EQ(asked, fp32) << "bf16 does not pay on this CPU: the run is fp32";
  setenv("UPLVSM_FORCE_BF16", "1", 1);
  const double forced = losses_of(config, "wiring_bf16_forced").at(0);
  unsetenv("UPLVSM_FORCE_BF16");
  EXPECT_NE(forced, fp32);
  EXPECT_NEAR(forced, fp32, 0.05 * fp32);
}

// training.tf32 reaches CUDA's switches for a run on a CUDA device (the switches exist without a GPU).
TEST(TrainerWiring, Tf32FollowsTheConfigOnACudaDevice) {
  auto config = test::micro_config();
  auto net = model::make_model(config.model);
  auto optimizer = train::make_optimizer(*net, config.training);
  auto& context = at::globalContext();
  const bool cublas = context.allowTF32CuBLAS(), cudnn = context.allowTF32CuDNN();
  auto opt = test::micro_run_options(test::temp_dir("wiring_tf32").string());
  opt.device = torch::Device(torch::kCUDA, 0);
  for (bool on : {true, false, true}) {
    config.training.tf32 = on;
    train::step_context(*net, *optimizer, config, opt);
    EXPECT_EQ(context.allowTF32CuBLAS(), on);
    EXPECT_EQ(context.allowTF32CuDNN(), on);
  }
  context.setAllowTF32CuBLAS(cublas);
  context.setAllowTF32CuDNN(cudnn);
}

// training.pose_noise_std reaches a posed model's cameras: LVSM's first loss moves with it, and the loader is told.
TEST(TrainerWiring, PoseNoiseReachesThePosedModelsCameras) {
  auto config = test::micro_config();
  config.model.variant = Variant::LVSM;
  config.training.train_steps = 1;
  const double clean = losses_of(config, "wiring_clean").at(0);
  config.training.pose_noise_std = 0.1;
  const double noisy = losses_of(config, "wiring_noisy").at(0);
  EXPECT_NE(noisy, clean);
  data::ChunkDataset dataset(test::micro_dataset(), "train");
  EXPECT_DOUBLE_EQ(train::loader_options(config, dataset, nullptr).pose_noise_std, 0.1);
}

// The model is told the loader's cameras, marked as being in the scene frame of the sample's views (the posed
// models then use them as they are, as the official dataset gives them).
TEST(TrainerWiring, MicroBatchTellsTheCamerasInTheSceneFrame) {
  const auto config = test::micro_config();
  data::ChunkDataset dataset(test::micro_dataset(), "train");
  const auto batch = data::make_training_batch(dataset, train::loader_options(config, dataset, nullptr), 0);
  const auto micro = train::micro_batch(batch, 2, torch::kCPU);
  EXPECT_EQ(micro.inputs.camera_frame, model::CameraFrame::Scene);
  EXPECT_EQ(micro.targets.camera_frame, model::CameraFrame::Scene);
  EXPECT_TRUE(torch::equal(micro.inputs.c2w, batch.input_c2w(2)));
  EXPECT_TRUE(torch::equal(micro.targets.c2w, batch.target_c2w()));
  EXPECT_TRUE(torch::equal(micro.targets.images, batch.target_images()));
}
