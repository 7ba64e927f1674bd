// Tests of model/layer_norm_to_bf16: the fused LayerNorm-into-bf16 against the exact unfused chain (LibTorch's fp32
// layer_norm, then the cast): values and gradients of x, weight and bias, with and without bias, widths with and
// without the vectorised path, bf16 and fp32 upstream gradients, independent of the thread count; and the residual
// add joined to it (add_layer_norm_to_bf16) against LibTorch's add followed by the same chain.
#include "uplvsm/kernels/layer_norm_to_bf16.h"

#include <gtest/gtest.h>

#include <ATen/Parallel.h>

#include "uplvsm/core/autocast.h"
#include "uplvsm/model/transformer.h"

using namespace uplvsm;
using namespace uplvsm::model;
using namespace uplvsm::kernels;

namespace {

struct NormResult {
  torch::Tensor out, grad_x, grad_w, grad_b;
};

NormResult run_norm(bool fused, int64_t D, bool with_bias, torch::ScalarType upstream_dtype, uint64_t seed = 3) {
  torch::manual_seed(seed);
  auto x = (torch::randn({2, 37, D}) * 3 + 0.5).requires_grad_(true);
  auto weight = (1 + 0.3 * torch::randn({D})).requires_grad_(true);
  auto bias = with_bias ? (0.2 * torch::randn({D})).requires_grad_(true) : torch::Tensor();
  const double eps = 1e-5;
  auto y = fused ? layer_norm_to_bf16(x, weight, bias, eps) : layer_norm_to_bf16_unfused(x, weight, bias, eps);
  auto upstream = torch::randn(y.sizes()).to(torch::kBFloat16).to(upstream_dtype);
  y.backward(upstream);
  return {y.detach(), x.grad().clone(), weight.grad().clone(), with_bias ? bias.grad().clone() : torch::Tensor()};
}

double largest_relative_error(const torch::Tensor& a, const torch::Tensor& b) {
  auto a64 = a.to(torch::kFloat64), b64 = b.to(torch::kFloat64);
  return ((a64 - b64).abs().max() / b64.abs().max()).item<double>();
}

// The forward rounds once, to bf16, where the chain's cast rounds; before it the two differ only in the order of
// the fp32 mean and variance sums, so almost every output is bit-equal. The backward is fp32 throughout.
TEST(LayerNormToBf16, MatchesLayerNormThenCastValuesAndGradients) {
  for (int64_t D : {128, 64, 20}) {
    for (bool with_bias : {false, true}) {
      for (auto upstream : {torch::kBFloat16, torch::kFloat32}) {
        SCOPED_TRACE(testing::Message() << "D " << D << " bias " << with_bias << " upstream " << upstream);
        auto fused = run_norm(true, D, with_bias, upstream), ref = run_norm(false, D, with_bias, upstream);
        ASSERT_EQ(fused.out.scalar_type(), torch::kBFloat16);
        ASSERT_EQ(fused.grad_x.scalar_type(), torch::kFloat32);
        const double exact = fused.out.eq(ref.out).to(torch::kFloat64).mean().item<double>();
        EXPECT_GT(exact, 0.99) << "share of bit-equal outputs";
        EXPECT_LT(largest_relative_error(fused.out, ref.out), 1e-2);
        EXPECT_LT(largest_relative_error(fused.grad_x, ref.grad_x), 1e-5);
        EXPECT_LT(largest_relative_error(fused.grad_w, ref.grad_w), 1e-5);
        if (with_bias) EXPECT_LT(largest_relative_error(fused.grad_b, ref.grad_b), 1e-5);
      }
    }
  }
}

TEST(LayerNormToBf16, GradientsDoNotDependOnTheThreadCount) {
  const int threads = at::get_num_threads();
  at::set_num_threads(1);
  auto one = run_norm(true, 128, true, torch::kBFloat16, 11);
  at::set_num_threads(std::max(2, threads));
  auto several = run_norm(true, 128, true, torch::kBFloat16, 11);
  at::set_num_threads(threads);
  EXPECT_TRUE(torch::equal(one.grad_w, several.grad_w));
  EXPECT_TRUE(torch::equal(one.grad_b, several.grad_b));
  EXPECT_TRUE(torch::equal(one.grad_x, several.grad_x));
}

TEST(LayerNormToBf16, NonFiniteRowsStayNonFiniteAndOthersUntouched) {
  auto x = torch::randn({4, 32});
  x[1][5] = std::numeric_limits<float>::infinity();
  auto w = torch::ones({32});
  auto fused = layer_norm_to_bf16(x, w, {}, 1e-5), ref = layer_norm_to_bf16_unfused(x, w, {}, 1e-5);
  EXPECT_TRUE(torch::isfinite(fused[0]).all().item<bool>());
  EXPECT_FALSE(torch::isfinite(fused[1]).all().item<bool>());
  EXPECT_TRUE(torch::equal(torch::isfinite(fused), torch::isfinite(ref)));
}

TEST(LayerNormToBf16, FallsBackWhereItDoesNotFuse) {
  auto x = torch::randn({3, 16});
  EXPECT_TRUE(layer_norm_to_bf16_fuses(x, torch::ones({16}), {}));
  EXPECT_FALSE(layer_norm_to_bf16_fuses(x.to(torch::kBFloat16), torch::ones({16}), {}));  // fp32 x only
  EXPECT_FALSE(layer_norm_to_bf16_fuses(x, torch::ones({8}), {}));
  EXPECT_FALSE(layer_norm_to_bf16_fuses(x, torch::ones({16}), torch::zeros({8})));
  EXPECT_FALSE(layer_norm_to_bf16_fuses(x, torch::ones({16}, torch::kFloat64), {}));
  auto y = layer_norm_to_bf16(x, torch::ones({8}).repeat({2}), {}, 1e-5);  // fuses: a contiguous copy
  EXPECT_EQ(y.scalar_type(), torch::kBFloat16);
}

struct ResidualResult {
  torch::Tensor h, y, grad_x, grad_branch, grad_w, grad_b;
};

// h = x + branch, y = norm(h); the loss reaches both outputs (h through the next residual) unless `only`.
ResidualResult run_residual(bool fused, int64_t D, torch::ScalarType branch_dtype, const std::string& only = "") {
  torch::manual_seed(21);
  auto x = (torch::randn({3, 29, D}) * 2).requires_grad_(true);
  auto branch = torch::randn({3, 29, D}).to(branch_dtype).requires_grad_(true);
  auto weight = (1 + 0.3 * torch::randn({D})).requires_grad_(true);
  auto bias = (0.2 * torch::randn({D})).requires_grad_(true);
  auto [h, y] = fused ? add_layer_norm_to_bf16(x, branch, weight, bias, 1e-5)
                      : add_layer_norm_to_bf16_unfused(x, branch, weight, bias, 1e-5);
  auto up_h = torch::randn(h.sizes()), up_y = torch::randn(y.sizes()).to(torch::kBFloat16);
  torch::Tensor loss = torch::zeros({});
  if (only != "y") loss = loss + (h * up_h).sum();
  if (only != "h") loss = loss + (y.to(torch::kFloat32) * up_y.to(torch::kFloat32)).sum();
  loss.backward();
  auto grad_or_empty = [](const torch::Tensor& t) { return t.grad().defined() ? t.grad().clone() : torch::Tensor(); };
  return {h.detach(), y.detach(), x.grad().clone(), branch.grad().clone(), grad_or_empty(weight), grad_or_empty(bias)};
}

// h is LibTorch's add exactly; the norm's output and gradients as in the test above; the branch's gradient is the
// stream's, rounded to the branch's dtype.
TEST(LayerNormToBf16, ResidualAddJoinedToTheNormMatchesAddThenNorm) {
  for (int64_t D : {128, 20}) {
    for (auto branch_dtype : {torch::kBFloat16, torch::kFloat32}) {
      for (std::string only : {"", "h", "y"}) {
        SCOPED_TRACE(testing::Message() << "D " << D << " branch " << branch_dtype << " only " << only);
        auto fused = run_residual(true, D, branch_dtype, only), ref = run_residual(false, D, branch_dtype, only);
        EXPECT_TRUE(torch::equal(fused.h, ref.h));
        ASSERT_EQ(fused.grad_branch.scalar_type(), branch_dtype);
        EXPECT_GT(fused.y.eq(ref.y).to(torch::kFloat64).mean().item<double>(), 0.99) << "share of bit-equal outputs";
        EXPECT_LT(largest_relative_error(fused.grad_x, ref.grad_x), 1e-5);
        EXPECT_LT(largest_relative_error(fused.grad_branch, ref.grad_branch),
                  branch_dtype == torch::kFloat32 ? 1e-5 : 1e-2);
        if (only == "h") {
          EXPECT_TRUE(torch::equal(fused.grad_x, ref.grad_x));  // the add's gradient alone: nothing to round
          EXPECT_FALSE(fused.grad_w.defined() && fused.grad_w.abs().sum().item<double>() > 0);
        } else {
          EXPECT_LT(largest_relative_error(fused.grad_w, ref.grad_w), 1e-5);
          EXPECT_LT(largest_relative_error(fused.grad_b, ref.grad_b), 1e-5);
        }
      }
    }
  }
}

TEST(LayerNormToBf16, ResidualAddFallsBackWhereItDoesNotFuse) {
  auto x = torch::randn({2, 16});
  EXPECT_TRUE(add_layer_norm_to_bf16_fuses(x, x.to(torch::kBFloat16), torch::ones({16}), {}));
  EXPECT_FALSE(add_layer_norm_to_bf16_fuses(x, torch::randn({1, 16}), torch::ones({16}), {}));  // a broadcast
  EXPECT_FALSE(add_layer_norm_to_bf16_fuses(x, x.to(torch::kFloat64), torch::ones({16}), {}));
  auto [h, y] = add_layer_norm_to_bf16(x, torch::randn({1, 16}), torch::ones({16}), {}, 1e-5);
  EXPECT_EQ(h.sizes(), x.sizes());
  EXPECT_EQ(y.scalar_type(), torch::kBFloat16);
}

// A transformer block under bf16 autocast gives the same output and gradients with the fused pre-norms as with
// LibTorch's layer_norm followed by the linears' own casts (the block's forward before this kernel).
TEST(LayerNormToBf16, TransformerBlockUnderAutocastMatchesTheUnfusedNorms) {
  torch::manual_seed(5);
  TransformerBlock block(64, 32, 1e-3);
  auto x = torch::randn({2, 19, 64}).requires_grad_(true);
  torch::Tensor fused, ref;
  {
    AutocastGuard autocast(torch::kCPU, true);
    fused = block->forward(x);
    auto h = x + block->attn->forward(block->norm1->forward(x));
    ref = h + block->mlp(block->norm2->forward(h));
  }
  ASSERT_EQ(fused.scalar_type(), ref.scalar_type());
  EXPECT_LT(largest_relative_error(fused, ref), 1e-2);
  auto upstream = torch::randn(fused.sizes());
  auto grads = [&](const torch::Tensor& y) {
    block->zero_grad();
    auto gx = torch::autograd::grad({y}, {x, block->norm1->weight, block->norm2->weight}, {upstream}, true);
    return gx;
  };
  auto gf = grads(fused), gr = grads(ref);
  for (size_t i = 0; i < gf.size(); ++i) EXPECT_LT(largest_relative_error(gf[i], gr[i]), 2e-2) << "gradient " << i;
}

}  // namespace
