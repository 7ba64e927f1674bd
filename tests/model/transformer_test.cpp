#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/model/state_dict.h"
#include "uplvsm/model/transformer.h"

using namespace uplvsm;

TEST(Transformer, MatchesLvsmFixture) {
  UPLVSM_NEEDS_FIXTURES();
  // Two LVSM QK-norm blocks, d 128, d_head 32, QK RMSNorm eps 1e-5, official key names.
  auto stack = model::make_transformer_stack(2, 128, 32, 1e-5, true);
  torch::nn::Module holder;
  holder.register_module("transformer_blocks", stack);
  auto weights = io::read_safetensors(test::fixture("lvsm/transformer_weights.safetensors")).tensors;
  auto report = model::load_state_dict(holder, weights, "lvsm/transformer_weights.safetensors");
  EXPECT_EQ(report.loaded, 16);
  auto io = io::read_safetensors(test::fixture("lvsm/transformer_io.safetensors")).tensors;
  torch::NoGradGuard no_grad;
  auto x = io.at("input");
  auto y0 = stack[0]->as<model::TransformerBlockImpl>()->forward(x);
  EXPECT_LE(test::max_abs_diff(y0, io.at("block0_output")), 1e-5);
  EXPECT_LE(test::max_abs_diff(model::run_stack(stack, x), io.at("output")), 1e-5);
}

TEST(Transformer, DepthScaledInit) {
  torch::manual_seed(0);
  auto stack = model::make_transformer_stack(4, 256, 64, 1e-3, true);
  auto w0 = stack[0]->as<model::TransformerBlockImpl>()->attn->to_qkv->weight;
  auto w3 = stack[3]->as<model::TransformerBlockImpl>()->attn->to_qkv->weight;
  EXPECT_NEAR(w0.std().item<double>(), 0.02 / std::sqrt(2.0), 1e-3);
  EXPECT_NEAR(w3.std().item<double>(), 0.02 / std::sqrt(8.0), 1e-3);
}

TEST(StateDict, StrictLoadNamesMissingUnexpectedAndMisshapedKeys) {
  auto stack = model::make_transformer_stack(1, 64, 32, 1e-3, true);
  torch::nn::Module holder;
  holder.register_module("blocks", stack);
  auto sd = model::state_dict(holder);
  sd.erase("blocks.0.norm1.weight");
  sd["blocks.0.extra.weight"] = torch::zeros({3});
  sd["blocks.0.attn.fc.weight"] = torch::zeros({64, 32});
  sd["loss_computer.perceptual_loss_module.vgg.features.0.weight"] = torch::zeros({1});
  try {
    model::load_state_dict(holder, sd, "bad.safetensors");
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    std::string msg = e.what();
    EXPECT_NE(msg.find("bad.safetensors"), std::string::npos);
    EXPECT_NE(msg.find("missing keys"), std::string::npos);
    EXPECT_NE(msg.find("blocks.0.norm1.weight"), std::string::npos);
    EXPECT_NE(msg.find("blocks.0.extra.weight"), std::string::npos);
    EXPECT_NE(msg.find("blocks.0.attn.fc.weight: file [64, 32] vs model [64, 64]"), std::string::npos);
    EXPECT_NE(msg.find("skipped 1 known extra"), std::string::npos);
  }
}
