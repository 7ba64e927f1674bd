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

// The moments exist before the first step (allocated next to the weights), as the zeros AdamW's first step would
// create: two steps move the weights and moments exactly as an AdamW left to create its state lazily.
TEST(Optimizer, MomentsAllocatedUpFrontStepLikeLazyOnes) {
  torch::manual_seed(5);
  auto eager_net = torch::nn::Linear(6, 4), lazy_net = torch::nn::Linear(6, 4);
  {
    torch::NoGradGuard no_grad;
    lazy_net->weight.copy_(eager_net->weight);
    lazy_net->bias.copy_(eager_net->bias);
  }
  TrainingConfig tc;
  tc.lr = 1e-2;
  tc.weight_decay = 0.05;
  auto eager = train::make_optimizer(*eager_net, tc);
  ASSERT_EQ(eager->state().size(), 2u);
  for (const auto& [key, state] : eager->state()) {
    const auto& s = static_cast<torch::optim::AdamWParamState&>(*state);
    EXPECT_EQ(s.step(), 0);
    EXPECT_EQ(s.exp_avg().abs().max().item<float>(), 0.f);
    EXPECT_EQ(s.exp_avg_sq().abs().max().item<float>(), 0.f);
  }
  torch::optim::AdamW lazy(train::official_param_groups(*lazy_net, tc), torch::optim::AdamWOptions(tc.lr));
  ASSERT_TRUE(lazy.state().empty());
  for (int step = 0; step < 2; ++step) {
    const auto x = torch::randn({3, 6});
    for (auto net : {eager_net, lazy_net}) {  // a holder copy shares its module
      net->zero_grad();
      net->forward(x).pow(2).sum().backward();
    }
    eager->step();
    lazy.step();
  }
  EXPECT_TRUE(eager_net->weight.equal(lazy_net->weight));
  EXPECT_TRUE(eager_net->bias.equal(lazy_net->bias));
  const auto& eager_state = static_cast<torch::optim::AdamWParamState&>(
      *eager->state().at(train::state_key(eager->state(), eager_net->weight)));
  const auto& lazy_state =
      static_cast<torch::optim::AdamWParamState&>(*lazy.state().at(train::state_key(lazy.state(), lazy_net->weight)));
  EXPECT_EQ(eager_state.step(), 2);
  EXPECT_TRUE(eager_state.exp_avg_sq().equal(lazy_state.exp_avg_sq()));
}
