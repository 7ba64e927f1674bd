// Tests of kernels/ops.h's stack runner: a stack run with each residual add deferred into the next norm (fused under
// bf16 autocast) gives what the blocks' own forwards (the paper's x + attn(norm1(x)); x + mlp(norm2(x))) give one
// after the other, in fp32 and under bf16 autocast, for every row and for the kept rows, with gradients.
#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/core/autocast.h"
#include "uplvsm/kernels/ops.h"
#include "uplvsm/model/transformer.h"

using namespace uplvsm;

namespace {

torch::Tensor run_blocks_one_by_one(const torch::nn::ModuleList& stack, torch::Tensor x, model::OutputRows rows) {
  for (size_t i = 0; i < stack->size(); ++i)
    x = stack->ptr<model::TransformerBlockImpl>(i)->forward(x, i + 1 == stack->size() ? rows : model::OutputRows{});
  return x;
}

void expect_stack_matches_blocks(bool bf16, model::OutputRows rows) {
  torch::manual_seed(7);
  auto stack = model::make_transformer_stack(3, 64, 32, 1e-3, true);
  auto x = torch::randn({2, 20, 64}, torch::requires_grad());
  AutocastGuard autocast(torch::kCPU, bf16);
  auto reference = run_blocks_one_by_one(stack, x, rows);
  auto grad_reference = torch::autograd::grad({reference.to(torch::kFloat32).square().sum()}, {x})[0];
  auto ran = model::run_stack(stack, x, 0, "test", rows);
  auto grad_ran = torch::autograd::grad({ran.to(torch::kFloat32).square().sum()}, {x})[0];
  ASSERT_EQ(ran.sizes(), reference.sizes());
  // The fused add-and-norm rounds as the separate add and norm do (layer_norm_to_bf16.h): equal up to fp32 order.
  const double tolerance = bf16 ? 2e-2 : 1e-5;
  EXPECT_LE(test::max_abs_diff(ran.to(torch::kFloat64), reference.to(torch::kFloat64)), tolerance);
  EXPECT_LE(test::max_abs_diff(grad_ran.to(torch::kFloat64), grad_reference.to(torch::kFloat64)), 10 * tolerance);
}

}  // namespace

TEST(PreNormStack, EqualsTheBlocksForwardsInFp32) {
  expect_stack_matches_blocks(false, {});
  expect_stack_matches_blocks(false, {12, 8});
}

TEST(PreNormStack, EqualsTheBlocksForwardsUnderBf16Autocast) {
  expect_stack_matches_blocks(true, {});
  expect_stack_matches_blocks(true, {0, 5});
}

TEST(PreNormStack, NoBlocksReturnTheRowsAsGiven) {
  auto x = torch::randn({1, 6, 4});
  EXPECT_TRUE(torch::equal(kernels::run_pre_norm_stack({}, x), x));
  EXPECT_TRUE(torch::equal(kernels::run_pre_norm_stack({}, x, 2, 3), x.narrow(1, 2, 3)));
}
