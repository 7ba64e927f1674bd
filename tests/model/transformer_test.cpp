#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <string>
#include <vector>

#include "test_util.h"
#include "uplvsm/core/autocast.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/state_dict.h"
#include "uplvsm/kernels/flash_attention.h"
#include "uplvsm/model/dinov2.h"
#include "uplvsm/model/transformer.h"

using namespace uplvsm;

TEST(Transformer, MatchesLvsmFixture) {
  UPLVSM_NEEDS_FIXTURES();
  // Two LVSM QK-norm blocks, d 128, d_head 32, QK RMSNorm eps 1e-5, official key names.
  auto stack = model::make_transformer_stack(2, 128, 32, 1e-5, true);
  torch::nn::Module holder;
  holder.register_module("transformer_blocks", stack);
  auto weights = io::read_safetensors(test::fixture("lvsm/transformer_weights.safetensors")).tensors;
  auto report = io::load_state_dict(holder, weights, "lvsm/transformer_weights.safetensors");
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

// The official per-block rule (ptlvsm.py; uplvsm.py's encoder and decoder alike at d490397).
TEST(Transformer, OfficialBlockInitStdsInEveryCombination) {
  const auto both = model::official_block_init_stds(8, true, true);
  ASSERT_EQ(both.size(), 8u);
  for (size_t i = 0; i < both.size(); ++i) EXPECT_DOUBLE_EQ(both[i], 0.02 / std::sqrt(2.0 * (i + 1)));
  for (double s : model::official_block_init_stds(8, true, false)) EXPECT_DOUBLE_EQ(s, 0.005);
  for (bool depth : {false, true})
    for (double s : model::official_block_init_stds(8, false, depth)) EXPECT_DOUBLE_EQ(s, 0.02);
  EXPECT_TRUE(model::official_block_init_stds(0, true, true).empty());
}

// torch.nn.init.trunc_normal_'s bounds are absolute: [-1, 2] at std 1 cuts both tails (the mean moves to
// (phi(-1) - phi(2)) / (Phi(2) - Phi(-1)) = 0.2296), while [-2, 2] at std 0.02 cuts nothing.
TEST(Transformer, TruncNormalBoundsAreAbsoluteAsPyTorchs) {
  torch::manual_seed(0);
  auto cut = model::trunc_normal_(torch::empty({200000}), 0.0, 1.0, -1.0, 2.0);
  EXPECT_GE(cut.min().item<double>(), -1.0);
  EXPECT_LE(cut.max().item<double>(), 2.0);
  EXPECT_NEAR(cut.mean().item<double>(), 0.2296, 0.01);
  auto wide = model::trunc_normal_(torch::empty({200000}), 0.0, 0.02, -2.0, 2.0);
  EXPECT_NEAR(wide.std().item<double>(), 0.02, 2e-4);
  EXPECT_GT(wide.abs().max().item<double>(), 0.08);  // beyond 4 std
  EXPECT_NE(test::error_of([] { model::trunc_normal_(torch::empty({4}), 0.0, 0.0, -2.0, 2.0); }).find("std > 0"),
            std::string::npos);
}

namespace {
// A stack's output and the gradients of x and of every weight for the loss sum(out * probe).
struct StackRun {
  torch::Tensor out, x_grad;
  std::vector<torch::Tensor> weight_grads;
};

StackRun run_and_differentiate(const torch::nn::ModuleList& stack, const torch::Tensor& x0, int64_t checkpoint_every,
                               model::OutputRows rows, const torch::Tensor& probe) {
  for (auto& p : stack->parameters()) p.mutable_grad() = torch::Tensor();
  auto x = x0.clone().requires_grad_(true);
  StackRun run;
  run.out = model::run_stack(stack, x, checkpoint_every, "test", rows);
  (run.out.to(torch::kFloat32) * probe).sum().backward();
  run.x_grad = x.grad();
  for (auto& p : stack->parameters()) run.weight_grads.push_back(p.grad().clone());
  return run;
}
}  // namespace

TEST(Transformer, OutputRowsEqualTheRowsOfTheFullStack) {
  // The last block computes only the rows a caller reads; everything else is unchanged, so the kept rows, the input
  // gradient and every weight gradient equal the full stack's sliced to those rows (fp32, checkpointed or not, a
  // span at the start, the end and the middle).
  torch::manual_seed(0);
  auto stack = model::make_transformer_stack(3, 64, 32, 1e-3, true);
  auto x = torch::randn({2, 40, 64});
  for (const auto rows : {model::OutputRows{0, 16}, model::OutputRows{24, 16}, model::OutputRows{5, 1}}) {
    for (const int64_t checkpoint_every : {0, 2}) {
      auto probe = torch::randn({2, rows.count, 64});
      auto full_probe = torch::zeros({2, 40, 64});
      full_probe.narrow(1, rows.start, rows.count).copy_(probe);
      const auto full = run_and_differentiate(stack, x, checkpoint_every, {}, full_probe);
      const auto kept = run_and_differentiate(stack, x, checkpoint_every, rows, probe);
      ASSERT_EQ(kept.out.sizes(), probe.sizes());
      EXPECT_LE(test::max_abs_diff(kept.out, full.out.narrow(1, rows.start, rows.count)), 1e-5);
      EXPECT_LE(test::max_abs_diff(kept.x_grad, full.x_grad), 1e-5);
      for (size_t i = 0; i < full.weight_grads.size(); ++i)
        EXPECT_LE(test::max_abs_diff(kept.weight_grads[i], full.weight_grads[i]), 1e-4) << "weight " << i;
    }
  }
  EXPECT_THROW(model::run_stack(stack, x, 0, "test", {30, 16}), c10::Error);  // past the end: named, not read
}

TEST(Transformer, OutputRowsUnderBf16AutocastMatchTheFullStack) {
  // Under autocast the kept rows take the same kernels (fused attention with fewer queries than keys).
  torch::manual_seed(1);
  auto stack = model::make_transformer_stack(2, 64, 32, 1e-3, true);
  auto x = torch::randn({2, 48, 64});
  AutocastGuard autocast(x.device(), true);
  const model::OutputRows rows{0, 20};
  auto probe = torch::randn({2, 20, 64});
  auto full_probe = torch::zeros({2, 48, 64});
  full_probe.narrow(1, 0, 20).copy_(probe);
  const auto full = run_and_differentiate(stack, x, 0, {}, full_probe);
  const auto kept = run_and_differentiate(stack, x, 0, rows, probe);
  const double scale = full.out.abs().max().item<double>();
  EXPECT_LE(test::max_abs_diff(kept.out.to(torch::kFloat32), full.out.narrow(1, 0, 20).to(torch::kFloat32)),
            0.02 * scale);
  EXPECT_LE(test::max_abs_diff(kept.x_grad, full.x_grad), 0.02 * full.x_grad.abs().max().item<double>());
}

namespace {

// Names of the autograd nodes behind t.
std::vector<std::string> graph_node_names(const torch::Tensor& t) {
  std::vector<std::string> names;
  std::vector<torch::autograd::Node*> stack{t.grad_fn().get()};
  std::set<torch::autograd::Node*> seen;
  while (!stack.empty()) {
    auto* node = stack.back();
    stack.pop_back();
    if (!node || !seen.insert(node).second) continue;
    names.push_back(node->name());
    for (const auto& edge : node->next_edges()) stack.push_back(edge.function.get());
  }
  return names;
}

bool has_node(const std::vector<std::string>& names, const std::string& part) {
  return std::any_of(names.begin(), names.end(),
                     [&](const std::string& n) { return n.find(part) != std::string::npos; });
}

}  // namespace

// Under bf16 autocast, where the fused kernels run, the QKNorm attention of a block (and DINOv2's) is the single
// QK-Norm-and-attention node; in fp32 it stays QK-Norm then attention (the official comparisons' path).
TEST(Transformer, QKNormAttentionUnderAutocastIsOneFusedNode) {
  if (!kernels::fused_qk_norm_attention_applies(torch::zeros({1, 1, 96}, torch::kBFloat16), torch::ones({32}), 32))
    GTEST_SKIP() << "no fused bf16 attention on this CPU";
  torch::manual_seed(2);
  model::QKNormAttention layer(64, 32, 1e-3);
  auto x = torch::randn({2, 19, 64}).requires_grad_(true);
  torch::Tensor autocast_out;
  {
    AutocastGuard autocast(x.device(), true);
    autocast_out = layer->forward(x, model::OutputRows{3, 9});
  }
  const auto fused_names = graph_node_names(autocast_out);
  EXPECT_TRUE(has_node(fused_names, "FusedQKNormAttention"));
  EXPECT_FALSE(has_node(fused_names, "QKNormFunction"));
  EXPECT_EQ(autocast_out.size(1), 9);
  const auto fp32_names = graph_node_names(layer->forward(x));
  EXPECT_FALSE(has_node(fp32_names, "FusedQKNormAttention"));
  EXPECT_TRUE(has_node(fp32_names, "QKNormFunction"));
  model::DinoAttention dino(64, 2, true, 1e-3);
  AutocastGuard autocast(x.device(), true);
  EXPECT_TRUE(has_node(graph_node_names(dino->forward(x)), "FusedQKNormAttention"));
}

TEST(StateDict, StrictLoadNamesMissingUnexpectedAndMisshapedKeys) {
  auto stack = model::make_transformer_stack(1, 64, 32, 1e-3, true);
  torch::nn::Module holder;
  holder.register_module("blocks", stack);
  auto sd = io::state_dict(holder);
  sd.erase("blocks.0.norm1.weight");
  sd["blocks.0.extra.weight"] = torch::zeros({3});
  sd["blocks.0.attn.fc.weight"] = torch::zeros({64, 32});
  sd["loss_computer.perceptual_loss_module.vgg.features.0.weight"] = torch::zeros({1});
  try {
    io::load_state_dict(holder, sd, "bad.safetensors");
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
