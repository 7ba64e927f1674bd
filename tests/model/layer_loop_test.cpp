// The layer loop (model/layer_loop.h) against its reference, the blocks' own forwards run one after the other: an
// LVSM stack (all rows and kept rows) and a DINOv2 stack (with and without QK-Norm, LayerScale) give the same output
// and the same gradients (input and every weight), bit for bit, in fp32 and under bf16 autocast, with and without
// gradient checkpointing. The loop fuses each block's closing residual add into the next block's norm1; the fused
// kernel adds and normalises as the separate ops do (kernels/layer_norm_to_bf16.h), so nothing may move.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <string>
#include <vector>

#include "test_util.h"
#include "uplvsm/core/autocast.h"
#include "uplvsm/core/config.h"
#include "uplvsm/model/dinov2.h"
#include "uplvsm/model/gradient_checkpoint.h"
#include "uplvsm/model/layer_loop.h"
#include "uplvsm/model/transformer.h"

namespace uplvsm::model {
namespace {

using StackFn = std::function<torch::Tensor(const torch::Tensor&)>;

// The output and the gradients (the input's, then every weight's) of sum(out * probe): a probe, so that the
// gradients reaching the stack do not depend on how its output rounded.
struct Run {
  torch::Tensor out;
  std::vector<torch::Tensor> grads;
};

Run differentiate(const torch::nn::ModuleList& stack, const torch::Tensor& x0, const StackFn& run) {
  auto params = stack->parameters();
  for (auto& p : params) p.mutable_grad() = torch::Tensor();
  auto x = x0.clone().requires_grad_(true);
  Run r;
  r.out = run(x);
  torch::manual_seed(99);
  (r.out.to(torch::kFloat32) * torch::randn(r.out.sizes())).sum().backward();
  r.grads.push_back(x.grad());
  for (auto& p : params) r.grads.push_back(p.grad());
  return r;
}

// The reference: block i's forward, given as block(i, x, last), one after the other; with checkpoint_every > 0 each
// group of that many blocks checkpointed as the loop checkpoints its groups.
torch::Tensor blocks_in_turn(size_t n, const std::function<torch::Tensor(size_t, torch::Tensor, bool)>& block,
                             const torch::nn::ModuleList& stack, torch::Tensor x, int64_t checkpoint_every) {
  const size_t group = checkpoint_every > 0 ? static_cast<size_t>(checkpoint_every) : n;
  for (size_t begin = 0; begin < n; begin += group) {
    const size_t end = std::min(n, begin + group);
    std::vector<torch::Tensor> params;
    for (size_t i = begin; i < end; ++i) {
      const auto p = stack->ptr(i)->parameters();
      params.insert(params.end(), p.begin(), p.end());
    }
    auto run = [block, begin, end, n](torch::Tensor t) {  // a copy: backward calls it after this returns
      for (size_t i = begin; i < end; ++i) t = block(i, t, i + 1 == n);
      return t;
    };
    x = checkpoint_every > 0 ? checkpointed(run, x, params) : run(x);
  }
  return x;
}

void expect_bit_equal(const Run& loop, const Run& reference, const std::string& what) {
  ASSERT_EQ(loop.out.sizes(), reference.out.sizes()) << what;
  EXPECT_EQ(loop.out.scalar_type(), reference.out.scalar_type()) << what;
  EXPECT_TRUE(torch::equal(loop.out, reference.out))
      << what << ": output off by "
      << test::max_abs_diff(loop.out.to(torch::kFloat64), reference.out.to(torch::kFloat64));
  ASSERT_EQ(loop.grads.size(), reference.grads.size()) << what;
  for (size_t i = 0; i < loop.grads.size(); ++i) {
    ASSERT_TRUE(loop.grads[i].defined() && reference.grads[i].defined()) << what << ", gradient " << i;
    EXPECT_TRUE(torch::equal(loop.grads[i], reference.grads[i]))
        << what << ", gradient " << i << " off by " << test::max_abs_diff(loop.grads[i], reference.grads[i]);
  }
}

void expect_transformer_stack_equals_its_blocks(bool bf16) {
  torch::manual_seed(7);
  auto stack = make_transformer_stack(3, 64, 32, 1e-3, true);
  const auto x = torch::randn({2, 20, 64});
  AutocastGuard autocast(torch::kCPU, bf16);
  for (const auto rows : {OutputRows{}, OutputRows{12, 8}, OutputRows{0, 5}}) {
    for (const int64_t every : {0, 1, 2}) {
      const auto block = [&stack, rows](size_t i, torch::Tensor t, bool last) {
        return stack->ptr<TransformerBlockImpl>(i)->forward(t, last ? rows : OutputRows{});
      };
      const auto loop =
          differentiate(stack, x, [&](const torch::Tensor& t) { return run_stack(stack, t, every, "test", rows); });
      const auto reference = differentiate(
          stack, x, [&](const torch::Tensor& t) { return blocks_in_turn(stack->size(), block, stack, t, every); });
      expect_bit_equal(loop, reference,
                       std::string(bf16 ? "bf16" : "fp32") + ", rows " + std::to_string(rows.start) + "+" +
                           std::to_string(rows.count) + ", checkpoint_every " + std::to_string(every));
    }
  }
}

TEST(LayerLoop, TransformerStackEqualsItsBlocksForwardsInFp32) { expect_transformer_stack_equals_its_blocks(false); }

TEST(LayerLoop, TransformerStackEqualsItsBlocksForwardsUnderBf16Autocast) {
  expect_transformer_stack_equals_its_blocks(true);
}

// A small DINOv2 (biases, LayerScale drawn away from its tiny init so it matters, QK-Norm on or off).
Dinov2 small_dino(bool qk_norm) {
  Dinov2Config c;
  c.embed_dim = 64, c.depth = 3, c.num_heads = 2, c.num_register_tokens = 0, c.pos_grid = 2;
  c.qk_norm = qk_norm, c.layerscale_init = 1e-5;
  Dinov2 net(c, 8);
  torch::NoGradGuard no_grad;
  for (auto& p : net->named_parameters())
    if (p.key().find("gamma") != std::string::npos || p.key().find("bias") != std::string::npos)
      p.value().normal_(0.5, 0.3);
  return net;
}

TEST(LayerLoop, DinoBlocksEqualTheirForwardsInFp32AndBf16) {
  for (const bool qk_norm : {true, false}) {
    auto net = small_dino(qk_norm);
    const auto x = torch::randn({2, 9, 64});
    for (const bool bf16 : {false, true}) {
      AutocastGuard autocast(torch::kCPU, bf16);
      for (const int64_t every : {0, 1, 2}) {
        const auto block = [&net](size_t i, torch::Tensor t, bool) {
          return net->blocks->ptr<DinoBlockImpl>(i)->forward(t);
        };
        net->grad_checkpoint_every = every;
        const auto loop = differentiate(net->blocks, x, [&](const torch::Tensor& t) { return net->run_blocks(t); });
        const auto reference = differentiate(net->blocks, x, [&](const torch::Tensor& t) {
          return blocks_in_turn(net->blocks->size(), block, net->blocks, t, every);
        });
        expect_bit_equal(loop, reference,
                         std::string(bf16 ? "bf16" : "fp32") + (qk_norm ? ", QK-Norm" : "") + ", checkpoint_every " +
                             std::to_string(every));
      }
    }
  }
}

// The loop's outputs also feed the official fixtures (Transformer.MatchesLvsmFixture, the DINOv2 and UP-LVSM parity
// tests); here its edges: no blocks hand the kept rows back as given, rows past the end are refused by name.
TEST(LayerLoop, NoBlocksReturnTheRowsAsGivenAndRowsPastTheEndAreRefused) {
  auto x = torch::randn({1, 6, 4});
  EXPECT_TRUE(torch::equal(run_layers({}, x), x));
  EXPECT_TRUE(torch::equal(run_layers({}, x, 0, {2, 3}), x.narrow(1, 2, 3)));
  EXPECT_NE(test::error_of([&] { run_layers({}, x, 0, {4, 3}); }).find("outside a sequence of 6"), std::string::npos);
}

}  // namespace
}  // namespace uplvsm::model
