#include <gtest/gtest.h>

#include "train/train_test_util.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/study/attention_map.h"

using namespace uplvsm;

namespace {
model::UPLVSM micro_net() {
  auto cfg = test::micro_model();
  cfg.transformer.encoder_n_layer = 2;  // so the figure replays a block before the last one
  torch::manual_seed(3);
  return model::UPLVSM(cfg);
}
torch::Tensor intrinsics() { return torch::tensor({{30.0, 30.0, 16.0, 16.0}, {30.0, 30.0, 16.0, 16.0}}); }
}  // namespace

TEST(AttentionMap, ReplayedEncoderMatchesTheForward) {
  auto net = micro_net();
  net->eval();
  torch::NoGradGuard no_grad;
  auto images = torch::rand({1, 2, 3, 32, 32});
  model::ForwardTrace trace;
  net->encode_scene(images, intrinsics().unsqueeze(0), &trace);
  auto h = trace.encoder_input;
  for (const auto& block : *net->transformer_encoder) h = block->as<model::TransformerBlockImpl>()->forward(h);
  EXPECT_TRUE(torch::allclose(h, trace.encoder_output, 1e-6, 1e-6));
}

TEST(AttentionMap, QueryPatchFindsItselfInAnIdenticalSecondView) {
  auto net = micro_net();
  auto view = torch::rand({1, 3, 32, 32});
  auto images = torch::cat({view, view});
  auto r = study::cross_view_attention(net, images, intrinsics(), 1, 2);
  ASSERT_EQ(r.attention.sizes(), (std::vector<int64_t>{4, 4}));
  ASSERT_EQ(r.similarity.sizes(), (std::vector<int64_t>{4, 4}));
  // Tokenizer features of the same patch are identical: cosine 1, the maximum.
  EXPECT_NEAR(r.similarity[1][2].item<double>(), 1.0, 1e-5);
  EXPECT_EQ(r.similarity.argmax().item<int64_t>(), 1 * 4 + 2);
  // Attention weights on view 2 are a part of one softmax row.
  EXPECT_GT(r.attention.min().item<double>(), 0.0);
  EXPECT_LT(r.attention.sum().item<double>(), 1.0);
  EXPECT_TRUE(net->is_training());  // the model's mode is restored
  auto fig = study::attention_figure(images, r, 64);
  EXPECT_EQ(fig.dim(), 3);
  EXPECT_GE(fig.size(1), 3 * 64);
  EXPECT_THROW(study::cross_view_attention(net, images, intrinsics(), 4, 0), c10::Error);
  auto posed = model::make_model(test::micro_model("lvsm"));  // no scene encoder: not an UP-LVSM
  EXPECT_THROW(model::require_uplvsm(posed, "study attention"), c10::Error);
}

TEST(AttentionMap, HeatColoursRunFromDarkBlueToRed) {
  auto c = study::heat_colours(torch::tensor({0.0, 1.0 / 3, 2.0 / 3, 1.0}).view({1, 4}));
  EXPECT_TRUE(torch::allclose(c.index({torch::indexing::Slice(), 0, 0}), torch::tensor({0.0f, 0.0f, 0.5f})));
  EXPECT_TRUE(torch::allclose(c.index({torch::indexing::Slice(), 0, 1}), torch::tensor({0.0f, 1.0f, 1.0f})));
  EXPECT_TRUE(torch::allclose(c.index({torch::indexing::Slice(), 0, 2}), torch::tensor({1.0f, 1.0f, 0.0f})));
  EXPECT_TRUE(torch::allclose(c.index({torch::indexing::Slice(), 0, 3}), torch::tensor({1.0f, 0.0f, 0.0f})));
}
