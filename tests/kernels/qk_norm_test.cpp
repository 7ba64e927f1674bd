// Tests of model/qk_norm: the fused QK-Norm against the exact unfused chain (values and gradients of x and the
// weight; fp32, bf16, bf16 -> fp32), on strided head views, independent of the thread count.
#include "uplvsm/kernels/qk_norm.h"

#include <gtest/gtest.h>

#include <ATen/Parallel.h>

#include "uplvsm/core/autocast.h"
#include "uplvsm/model/transformer.h"

using namespace uplvsm;
using namespace uplvsm::model;
using namespace uplvsm::kernels;

namespace {

struct Result {
  torch::Tensor out, grad_x, grad_w;
};

// [B, L, H, D] query view into a [B, L, 3 H D] projection (the layout QKNormAttention normalises), and its gradients
// under a fixed upstream gradient.
Result run(bool fused, torch::ScalarType in, torch::ScalarType out_dtype, int64_t D, uint64_t seed = 3) {
  torch::manual_seed(seed);
  const int64_t B = 2, L = 37, H = 3;
  auto projection = (torch::randn({B, L, 3 * H * D}) * 2).to(in).requires_grad_(true);
  auto weight = (1 + 0.3 * torch::randn({D})).requires_grad_(true);
  auto x = projection.chunk(3, -1)[0].view({B, L, H, D});
  const double eps = 1e-3;
  auto y = fused ? qk_norm(x, weight, eps, out_dtype) : qk_norm_unfused(x, weight, eps, out_dtype);
  auto upstream = torch::randn(y.sizes()).to(out_dtype);
  y.backward(upstream);
  return {y.detach(), projection.grad().chunk(3, -1)[0].contiguous(), weight.grad().clone()};
}

double max_rel(const torch::Tensor& a, const torch::Tensor& b) {
  auto a64 = a.to(torch::kFloat64), b64 = b.to(torch::kFloat64);
  return ((a64 - b64).abs().max() / b64.abs().max()).item<double>();
}

TEST(QKNorm, Fp32MatchesTheUnfusedChainValuesAndGradients) {
  for (int64_t D : {32, 64, 14}) {
    auto fused = run(true, torch::kFloat32, torch::kFloat32, D), ref = run(false, torch::kFloat32, torch::kFloat32, D);
    ASSERT_EQ(fused.out.scalar_type(), torch::kFloat32);
    EXPECT_LT(max_rel(fused.out, ref.out), 1e-6) << D;
    EXPECT_LT(max_rel(fused.grad_x, ref.grad_x), 1e-5) << D;
    EXPECT_LT(max_rel(fused.grad_w, ref.grad_w), 1e-5) << D;
    EXPECT_EQ(fused.grad_x.sizes(), ref.grad_x.sizes());
  }
}

// bf16 rounds twice in the forward (x r, then times the weight) and twice in the backward; the fused pass rounds at
// the same places, so the results agree up to the fp32 sums' order: almost always bit for bit.
TEST(QKNorm, Bf16RoundsWhereTheUnfusedChainRounds) {
  for (auto out_dtype : {torch::kBFloat16, torch::kFloat32}) {
    auto fused = run(true, torch::kBFloat16, out_dtype, 32), ref = run(false, torch::kBFloat16, out_dtype, 32);
    ASSERT_EQ(fused.out.scalar_type(), out_dtype);
    ASSERT_EQ(fused.grad_x.scalar_type(), torch::kBFloat16);
    const double exact = fused.out.eq(ref.out).to(torch::kFloat64).mean().item<double>();
    EXPECT_GT(exact, 0.99) << "share of bit-equal outputs";
    EXPECT_LT(max_rel(fused.out, ref.out), 1e-2);
    EXPECT_LT(max_rel(fused.grad_x, ref.grad_x), 2e-2);
    EXPECT_LT(max_rel(fused.grad_w, ref.grad_w), 1e-4);
  }
}

TEST(QKNorm, WeightGradientDoesNotDependOnTheThreadCount) {
  const int threads = at::get_num_threads();
  at::set_num_threads(1);
  auto one = run(true, torch::kFloat32, torch::kFloat32, 32, 11);
  at::set_num_threads(std::max(2, threads));
  auto several = run(true, torch::kFloat32, torch::kFloat32, 32, 11);
  at::set_num_threads(threads);
  EXPECT_TRUE(torch::equal(one.grad_w, several.grad_w));
  EXPECT_TRUE(torch::equal(one.grad_x, several.grad_x));
}

// The kernels take the rows' sums sixteen at a time; a row's output and gradient must not depend on its group.
TEST(QKNorm, EachRowComesOutAsIfNormalisedAlone) {
  for (auto dtype : {torch::kFloat32, torch::kBFloat16})
    for (int64_t D : {32, 64}) {
      torch::manual_seed(5);
      auto projection = (torch::randn({1, 37, 3 * 2 * D}) * 2).to(dtype).requires_grad_(true);
      auto weight = (1 + 0.3 * torch::randn({D})).requires_grad_(true);
      auto x = projection.chunk(3, -1)[0].view({1, 37, 2, D});
      auto upstream = torch::randn({1, 37, 2, D}).to(dtype);
      auto y = qk_norm(x, weight, 1e-3, dtype);
      y.backward(upstream);
      auto grad_all = projection.grad().chunk(3, -1)[0].view({1, 37, 2, D}).clone();
      for (int64_t l = 0; l < 37; l += 5) {
        projection.mutable_grad() = torch::Tensor();
        auto row = x.narrow(1, l, 1);
        auto y_row = qk_norm(row, weight, 1e-3, dtype);
        y_row.backward(upstream.narrow(1, l, 1));
        auto grad_row = projection.grad().chunk(3, -1)[0].view({1, 37, 2, D}).narrow(1, l, 1);
        EXPECT_TRUE(torch::equal(y_row, y.narrow(1, l, 1))) << "row " << l << ", D " << D << ", " << dtype;
        EXPECT_TRUE(torch::equal(grad_row, grad_all.narrow(1, l, 1))) << "row " << l << ", D " << D << ", " << dtype;
      }
    }
}

TEST(QKNorm, NonFiniteRowsStayNonFiniteAndOthersUntouched) {
  auto x = torch::randn({4, 32});
  x[1][5] = std::numeric_limits<float>::infinity();
  auto w = torch::ones({32});
  auto fused = qk_norm(x, w, 1e-3, torch::kFloat32), ref = qk_norm_unfused(x, w, 1e-3, torch::kFloat32);
  EXPECT_TRUE(torch::isfinite(fused[0]).all().item<bool>());
  EXPECT_FALSE(torch::isfinite(fused[1]).all().item<bool>());
  EXPECT_TRUE(torch::equal(torch::isfinite(fused), torch::isfinite(ref)));
}

// The attention layer under bf16 autocast hands the fused attention kernel the same q and k as the unfused RMSNorm
// followed by attention's own cast.
TEST(QKNorm, AttentionLayerUnderAutocastMatchesTheUnfusedNorm) {
  torch::manual_seed(5);
  QKNormAttention layer(64, 32, 1e-3);
  auto x = torch::randn({2, 19, 64});
  torch::Tensor fused, ref;
  {
    AutocastGuard autocast(torch::kCPU, true);
    fused = layer->forward(x);
    auto qkv = layer->to_qkv(x).chunk(3, -1);
    auto split = [&](const torch::Tensor& t) { return t.view({2, 19, 2, 32}); };
    auto q = qk_norm_unfused(split(qkv[0]), layer->q_norm->weight, 1e-3, torch::kFloat32).transpose(1, 2);
    auto k = qk_norm_unfused(split(qkv[1]), layer->k_norm->weight, 1e-3, torch::kFloat32).transpose(1, 2);
    auto o = attention(q, k, split(qkv[2]).transpose(1, 2));
    ref = layer->fc(o.transpose(1, 2).reshape({2, 19, 64}));
  }
  EXPECT_EQ(fused.scalar_type(), ref.scalar_type());
  EXPECT_LT(max_rel(fused, ref), 1e-2);
}

}  // namespace
