// The parameter count read from a config equals what the built model registers (every variant, DINOv2 options,
// the pose mapper), and the training memory bound grows and shrinks with what it should.
#include <gtest/gtest.h>

#include "train/train_test_util.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/train/memory_estimate.h"

using namespace uplvsm;

TEST(MemoryEstimate, ParameterCountFromTheConfigEqualsTheBuiltModel) {
  std::vector<ModelConfig> configs;
  for (std::string variant : {"uplvsm", "ptlvsm", "lvsm"}) configs.push_back(test::micro_model(variant));
  auto mapper = test::micro_model();
  mapper.pose_mapper = true;
  configs.push_back(mapper);
  auto no_qk_norm = test::micro_model();
  no_qk_norm.dinov2.qk_norm = false;
  no_qk_norm.dinov2.num_register_tokens = 0;
  no_qk_norm.dinov2.mlp_ratio = 2;
  configs.push_back(no_qk_norm);
  auto image_tokens = test::micro_model();
  image_tokens.keep_image_tokens = true;
  configs.push_back(image_tokens);
  for (std::string name : {"tiny", "tiny_ptlvsm", "tiny_lvsm", "tiny_mapper"})
    configs.push_back(load_config(std::string(UPLVSM_SOURCE_DIR) + "/configs/" + name + ".json").model);
  for (const auto& c : configs) {
    auto net = model::make_model(c);
    EXPECT_EQ(train::parameter_count(c), net->parameter_count()) << config_to_json(Config{"c", c}).dump();
  }
}

TEST(MemoryEstimate, TrainingMemoryScalesWithBatchAndCheckpointing) {
  auto config = load_config(std::string(UPLVSM_SOURCE_DIR) + "/configs/paper_x224.json");
  config.training.grad_checkpoint_every = 0;
  config.training.amp = Amp::None;
  const auto base = train::training_memory(config);
  EXPECT_EQ(base.state_bytes, 16.0 * static_cast<double>(base.parameters));
  EXPECT_GT(base.activation_bytes, 0.0);

  auto doubled = config;
  doubled.training.batch_size *= 2;
  EXPECT_DOUBLE_EQ(train::training_memory(doubled).activation_bytes, 2 * base.activation_bytes);

  auto checkpointed = config;
  checkpointed.training.grad_checkpoint_every = 1;
  EXPECT_LT(train::training_memory(checkpointed).activation_bytes, base.activation_bytes / 10);

  auto bf16 = config;
  bf16.training.amp = Amp::Bf16;
  EXPECT_DOUBLE_EQ(train::training_memory(bf16).activation_bytes, base.activation_bytes / 2);

  auto two_passes = config;  // the inputs' latent cameras: the encoder twice and the estimator over input view 1
  two_passes.model.encoder_latent_cameras = true;
  EXPECT_GT(train::training_memory(two_passes).activation_bytes, base.activation_bytes);

  // The unfittable config: d = 100032 needs terabytes for its state alone.
  auto huge = config;
  huge.model.transformer.d = huge.model.dinov2.embed_dim = 100032;
  EXPECT_GT(train::training_memory(huge).state_bytes, 1e13);
}
