#include <gtest/gtest.h>

#include "train_test_util.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/train/optimizer.h"

using namespace uplvsm;

TEST(Optimizer, OfficialParamGroups) {
  model::UPLVSM net(test::micro_config().model);
  auto g = train::split_param_groups(*net);
  auto has = [](const std::vector<std::string>& v, const std::string& k) {
    return std::find(v.begin(), v.end(), k) != v.end();
  };
  // dim > 1 (decayed): matrices, and also the latents, tokens, pos_embed and conv patch embed.
  EXPECT_TRUE(has(g.decay_names, "n_light_field_latent"));
  EXPECT_TRUE(has(g.decay_names, "image_tokenizer.1.dino_vit.pos_embed"));
  EXPECT_TRUE(has(g.decay_names, "image_tokenizer.1.dino_vit.cls_token"));
  EXPECT_TRUE(has(g.decay_names, "image_tokenizer.1.dino_vit.patch_embed.proj.weight"));
  EXPECT_TRUE(has(g.decay_names, "transformer_decoder.0.attn.to_qkv.weight"));
  // dim <= 1: norms, biases, LayerScale.
  EXPECT_TRUE(has(g.no_decay_names, "transformer_decoder.0.norm1.weight"));
  EXPECT_TRUE(has(g.no_decay_names, "image_tokenizer.1.dino_vit.blocks.0.ls1.gamma"));
  EXPECT_TRUE(has(g.no_decay_names, "estimator.absT_head.fc1.bias"));
  EXPECT_EQ(g.decay.size() + g.no_decay.size(), net->parameters().size());
}

TEST(Optimizer, WarmupThenCosine) {
  EXPECT_DOUBLE_EQ(train::lr_lambda(0, 100, 1000), 0.0);
  EXPECT_DOUBLE_EQ(train::lr_lambda(50, 100, 1000), 0.5);
  EXPECT_DOUBLE_EQ(train::lr_lambda(100, 100, 1000), 1.0);
  EXPECT_NEAR(train::lr_lambda(550, 100, 1000), 0.5, 1e-12);
  EXPECT_NEAR(train::lr_lambda(1000, 100, 1000), 0.0, 1e-12);
}
