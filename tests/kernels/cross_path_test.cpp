// The ops of kernels/ops.h at every ISA level this CPU has (isa_levels.h): whichever path the dispatch takes there,
// each op gives its exact (fp64) result within a few fp32 ulps, or within one bf16 step where its output is bf16;
// attention against fp64 attention of the same operands, with gradients.
#include <gtest/gtest.h>

#include <cmath>

#include "isa_levels.h"
#include "test_util.h"
#include "uplvsm/core/autocast.h"
#include "uplvsm/kernels/flash_attention.h"
#include "uplvsm/kernels/ops.h"

using namespace uplvsm;

class CrossPath : public test::AtIsaLevel {};
UPLVSM_AT_EVERY_ISA_LEVEL(CrossPath);

namespace {

constexpr double kFp32Ulp = 1.0 / (1 << 23);  // fp32's relative step at 1
constexpr double kBf16Step = 1.0 / (1 << 8);  // bf16's relative step at the bottom of a binade (one rounding: half)

// Every element of `got` within rel * |truth| + floor of `truth`.
void expect_within(const torch::Tensor& got, const torch::Tensor& truth, double rel, double floor, const char* what) {
  auto g = got.to(torch::kFloat64), t = truth.to(torch::kFloat64);
  const auto bad = ((g - t).abs() > t.abs() * rel + floor).sum().item<int64_t>();
  EXPECT_EQ(bad, 0) << what << ": " << bad << " of " << t.numel() << " elements off; largest difference "
                    << test::max_abs_diff(g, t) << " at " << isa_name(active_isa());
}

torch::Tensor exact_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  auto qd = q.to(torch::kFloat64), kd = k.to(torch::kFloat64), vd = v.to(torch::kFloat64);
  auto s = torch::matmul(qd, kd.transpose(-2, -1)) / std::sqrt(static_cast<double>(q.size(-1)));
  return torch::matmul(torch::softmax(s, -1), vd);
}

torch::Tensor bf16_rounded(const torch::Tensor& t) { return t.to(torch::kBFloat16).to(torch::kFloat32); }

}  // namespace

// fp32 attention and its gradients, through whichever path runs at the level: fused (AVX2, AVX-512) or LibTorch.
TEST_P(CrossPath, Fp32AttentionAndGradientsMatchFp64) {
  torch::manual_seed(21);
  // Odd lengths: padded key tiles, partial micro-kernel rows; several key tiles (300); d_head 16, 32, 64.
  for (auto [Lq, Lk, D] : std::vector<std::array<int64_t, 3>>{{37, 53, 32}, {130, 130, 64}, {7, 300, 16}}) {
    SCOPED_TRACE(testing::Message() << "Lq " << Lq << " Lk " << Lk << " D " << D);
    auto q = (torch::randn({2, 3, Lq, D}) * 2).requires_grad_(true), k = (torch::randn({2, 3, Lk, D}) * 2);
    auto v = torch::randn({2, 3, Lk, D});
    k.requires_grad_(true), v.requires_grad_(true);
    auto w = torch::randn({2, 3, Lq, D}, torch::kFloat64);
    auto o = kernels::attention(q, k, v);
    ASSERT_EQ(o.scalar_type(), torch::kFloat32);
    (o.to(torch::kFloat64) * w).sum().backward();
    auto qd = q.detach().to(torch::kFloat64).requires_grad_(true), kd = k.detach().to(torch::kFloat64);
    auto vd = v.detach().to(torch::kFloat64);
    kd.requires_grad_(true), vd.requires_grad_(true);
    auto exact = exact_attention(qd, kd, vd);
    (exact * w).sum().backward();
    // Sums of up to 300 products: a few hundred fp32 ulps of the tensor's scale.
    const double scale = 256 * kFp32Ulp;
    expect_within(o, exact.detach(), scale, scale * exact.abs().max().item<double>(), "output");
    expect_within(q.grad(), qd.grad(), scale, scale * qd.grad().abs().max().item<double>(), "dq");
    expect_within(k.grad(), kd.grad(), scale, scale * kd.grad().abs().max().item<double>(), "dk");
    expect_within(v.grad(), vd.grad(), scale, scale * vd.grad().abs().max().item<double>(), "dv");
  }
}

// Under bf16 autocast every path takes bf16 operands and sums in fp32: the fused AVX-512 BF16 kernel (which also
// rounds the probabilities to bf16) within 2 % of the output's scale, every other path within one bf16 step of
// each element, as one rounding of an fp32 result allows (LibTorch's own autocast matmuls sum P v in bf16 on CPUs
// without AVX-512 BF16: 1.2-1.3 % errors, which this bound rejects).
TEST_P(CrossPath, AttentionUnderAutocastSumsInFp32AndRoundsOnce) {
  torch::manual_seed(22);
  auto q = torch::randn({1, 12, 256, 64}) * 2, k = torch::randn({1, 12, 256, 64}) * 2;
  auto v = torch::rand({1, 12, 256, 64}) + 1;  // positive: the output's sums do not cancel
  torch::Tensor o;
  {
    AutocastGuard amp(torch::kCPU, true);
    o = kernels::attention(q, k, v);
  }
  ASSERT_EQ(o.scalar_type(), torch::kBFloat16);
  auto exact = exact_attention(bf16_rounded(q), bf16_rounded(k), bf16_rounded(v));
  if (kernels::fused_attention_applies(torch::kCPU, torch::kBFloat16, 64))
    expect_within(o, exact, 0, 2e-2 * exact.abs().max().item<double>(), "fused bf16 output");
  else
    expect_within(o, exact, kBf16Step, 1e-6, "output");
}

// A pre-norm block's norm into its linear layers under autocast: bf16 out, one rounding of the fp32 norm.
TEST_P(CrossPath, LayerNormIntoBf16IsOneRoundingOfTheExactNorm) {
  torch::manual_seed(23);
  for (int64_t D : {64, 20}) {
    SCOPED_TRACE(testing::Message() << "D " << D);
    auto x = torch::randn({3, 41, D}) * 3 + 0.5, branch = torch::randn({3, 41, D});
    auto w = 1 + 0.3 * torch::randn({D}), b = 0.2 * torch::randn({D});
    auto exact = [&](const torch::Tensor& h) {
      return torch::layer_norm(h.to(torch::kFloat64), {D}, w.to(torch::kFloat64), b.to(torch::kFloat64), 1e-5);
    };
    AutocastGuard amp(torch::kCPU, true);
    auto y = kernels::layer_norm(x, w, b, 1e-5, /*into_linear=*/true);
    expect_within(y, exact(x), kBf16Step, 1e-6, "layer_norm");
    auto [h, y2] = kernels::add_layer_norm(x, branch, w, b, 1e-5, /*into_linear=*/true);
    EXPECT_TRUE(torch::equal(h, x + branch)) << "the residual stream stays fp32 and exact";
    expect_within(y2, exact(x + branch), kBf16Step, 1e-6, "add_layer_norm");
  }
}

// QK-Norm (the official RMSNorm) into fp32 and into bf16, on strided head views as attention reads them.
TEST_P(CrossPath, QKNormIsTheExactRmsNormWithinFp32UlpsOrOneBf16Rounding) {
  torch::manual_seed(24);
  for (int64_t D : {64, 24}) {
    SCOPED_TRACE(testing::Message() << "D " << D);
    auto x = (torch::randn({2, 19, 3 * 2 * D}) * 2).narrow(2, 0, 2 * D).view({2, 19, 2, D}).transpose(1, 2);
    auto w = 1 + 0.3 * torch::randn({D});
    auto xd = x.to(torch::kFloat64);
    auto exact = xd * torch::rsqrt(xd.pow(2).mean(-1, true) + 1e-3) * w.to(torch::kFloat64);
    expect_within(kernels::rms_norm(x, w, 1e-3, torch::kFloat32), exact, 8 * kFp32Ulp, 1e-7, "fp32");
    expect_within(kernels::rms_norm(x, w, 1e-3, torch::kBFloat16), exact, kBf16Step, 1e-6, "bf16");
  }
}

// GELU in fp32 and bf16 against fp64 erf: fp32 within a few ulps (and an absolute floor where 1 + erf(x / sqrt 2)
// cancels for x << 0), bf16 within one step.
TEST_P(CrossPath, GeluMatchesTheExactErfForm) {
  torch::manual_seed(25);
  auto x = torch::randn({10007}) * 3;
  auto xd = x.to(torch::kFloat64);
  auto exact = 0.5 * xd * torch::erfc(-xd / std::sqrt(2.0));
  expect_within(kernels::gelu(x), exact, 8 * kFp32Ulp, 1e-6, "fp32");
  auto xb = x.to(torch::kBFloat16);
  auto xbd = xb.to(torch::kFloat64);
  expect_within(kernels::gelu(xb), 0.5 * xbd * torch::erfc(-xbd / std::sqrt(2.0)), kBf16Step, 2e-6, "bf16");
}

// What the paths line of `uplvsm info` and the test binaries names follows the level.
TEST_P(CrossPath, KernelPathsLineNamesTheLevelAndTheAttentionPath) {
  const auto line = kernels::describe_kernel_paths();
  EXPECT_NE(line.find("ISA " + isa_name(GetParam()) + " "), std::string::npos) << line;
  const bool fused = GetParam() >= Isa::Avx2;
  EXPECT_EQ(line.find("attention fp32 fused") != std::string::npos, fused) << line;
  EXPECT_EQ(line.find("--amp bf16 bf16") != std::string::npos, GetParam() >= Isa::Avx512Bf16) << line;
}
