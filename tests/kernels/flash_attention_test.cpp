#include <gtest/gtest.h>

#include <ATen/Parallel.h>

#include <functional>
#include <limits>
#include <string>

#include "isa_levels.h"
#include "test_util.h"
#include "uplvsm/core/autocast.h"
#include "uplvsm/kernels/flash_attention.h"
#include "uplvsm/kernels/flash_attention_kernels.h"  // internal: which kernels the level serves
#include "uplvsm/kernels/flash_attention_simd.h"     // internal: the kernels' exp2
#include "uplvsm/kernels/ops.h"
#include "uplvsm/kernels/qk_norm.h"
#include "uplvsm/model/transformer.h"

using namespace uplvsm;

namespace {

bool fused_available(torch::ScalarType dtype, int64_t d_head) {
  return kernels::fused_attention_applies(torch::kCPU, dtype, d_head);
}

// The unfused reference: softmax(q k^T / sqrt(d)) v in LibTorch ops, in double so it is the exact answer.
torch::Tensor reference_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  auto qd = q.to(torch::kFloat64), kd = k.to(torch::kFloat64), vd = v.to(torch::kFloat64);
  auto s = torch::matmul(qd, kd.transpose(-2, -1)) / std::sqrt(static_cast<double>(q.size(-1)));
  return torch::matmul(torch::softmax(s, -1), vd);
}

struct Grads {
  torch::Tensor o, dq, dk, dv;
};

// Output and gradients of sum(o * w) for a fixed random w, through `fn`.
template <typename Fn>
Grads run(Fn fn, torch::Tensor q, torch::Tensor k, torch::Tensor v, const torch::Tensor& w) {
  q = q.detach().requires_grad_(true), k = k.detach().requires_grad_(true), v = v.detach().requires_grad_(true);
  auto o = fn(q, k, v);
  (o.to(torch::kFloat64) * w).sum().backward();
  return {o.detach(), q.grad(), k.grad(), v.grad()};
}

// Max abs difference of output and gradients <= tol, or <= tol * max|b| per tensor when `relative`.
void expect_close(const Grads& a, const Grads& b, double tol, bool relative = false) {
  const std::pair<const char*, std::pair<torch::Tensor, torch::Tensor>> pairs[] = {
      {"output", {a.o, b.o}}, {"dq", {a.dq, b.dq}}, {"dk", {a.dk, b.dk}}, {"dv", {a.dv, b.dv}}};
  for (const auto& [name, t] : pairs) {
    const double bound = relative ? tol * t.second.abs().max().item<double>() : tol;
    EXPECT_LE(test::max_abs_diff(t.first, t.second), bound) << name;
  }
}

UPLVSM_AVX512 void exp2_16(const float* t, float* out) {
  _mm512_storeu_ps(out, kernels::flash::detail::exp2_ps(_mm512_loadu_ps(t)));
}

}  // namespace

TEST(FlashAttention, Bf16KernelsBaseTwoExpIsWithinTwoUlpsAndKeepsNaN) {
  if (!fused_available(torch::kBFloat16, 64)) GTEST_SKIP() << "no AVX-512 BF16 at this ISA level";
  // Every exponent the softmax meets (scores minus their max: t <= 0) down to underflow, and a few above 0.
  std::vector<float> t;
  for (double x = -126.0; x <= 4.0; x += 0.0137) t.push_back(static_cast<float>(x));
  for (float x : {-0.5f, 0.5f, -1e-7f, 0.0f}) t.push_back(x);
  t.resize((t.size() + 15) / 16 * 16, 0.0f);
  std::vector<float> out(t.size());
  for (size_t i = 0; i < t.size(); i += 16) exp2_16(t.data() + i, out.data() + i);
  double worst = 0;
  for (size_t i = 0; i < t.size(); ++i)
    worst = std::max(worst, std::abs(out[i] / std::exp2(static_cast<double>(t[i])) - 1.0));
  EXPECT_LE(worst, 2.5e-7);  // fit error 1.4e-7 plus fp32 rounding
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  float special[16] = {-inf, nan, -200.0f, -155.0f}, special_out[16];
  exp2_16(special, special_out);
  EXPECT_EQ(special_out[0], 0.0f);
  EXPECT_TRUE(std::isnan(special_out[1]));
  EXPECT_EQ(special_out[2], 0.0f);
  EXPECT_EQ(special_out[3], 0.0f) << "below fp32's smallest denormal";
}

TEST(FlashAttention, Fp32MatchesExactAttentionAndGradients) {
  if (!fused_available(torch::kFloat32, 64)) GTEST_SKIP() << "no fused fp32 attention below AVX2";
  torch::manual_seed(3);
  // Odd lengths exercise the padded key tiles and the partial micro-kernel rows; Lq != Lk the cross shapes.
  for (auto [B, H, Lq, Lk, D] : std::vector<std::array<int64_t, 5>>{
           {2, 3, 37, 53, 32}, {1, 2, 130, 130, 64}, {1, 1, 7, 300, 16}, {3, 2, 50, 5, 48}}) {
    auto q = torch::randn({B, H, Lq, D}) * 2, k = torch::randn({B, H, Lk, D}) * 2, v = torch::randn({B, H, Lk, D});
    auto w = torch::randn({B, H, Lq, D}, torch::kFloat64);
    SCOPED_TRACE(testing::Message() << "B H Lq Lk D = " << B << " " << H << " " << Lq << " " << Lk << " " << D);
    expect_close(run(kernels::fused_attention, q, k, v, w), run(reference_attention, q, k, v, w), 1e-5);
  }
}

TEST(FlashAttention, ReadsStridedHeadViewsWithoutCopies) {
  if (!fused_available(torch::kFloat32, 32)) GTEST_SKIP() << "no fused fp32 attention below AVX2";
  torch::manual_seed(4);
  // The model's layout: q, k, v are head views of one [B, L, 3 * H * D] projection.
  const int64_t B = 2, L = 40, H = 3, D = 32;
  auto qkv = torch::randn({B, L, 3 * H * D});
  auto heads = [&](int i) { return qkv.chunk(3, -1)[i].view({B, L, H, D}).transpose(1, 2); };
  auto w = torch::randn({B, H, L, D}, torch::kFloat64);
  auto fused = run(kernels::fused_attention, heads(0), heads(1), heads(2), w);
  expect_close(fused, run(reference_attention, heads(0), heads(1), heads(2), w), 1e-5);
  // The output is a head view of a [B, L, H, D] tensor: merging heads is a free reshape.
  EXPECT_TRUE(fused.o.transpose(1, 2).is_contiguous());
}

TEST(FlashAttention, Bf16StaysWithinDocumentedTolerance) {
  if (!fused_available(torch::kBFloat16, 64)) GTEST_SKIP() << "no AVX-512 BF16 at this ISA level";
  torch::manual_seed(5);
  // Odd lengths: padded key tiles, a query row without a pair partner.
  auto q = torch::randn({2, 2, 97, 64}).mul(2).to(torch::kBFloat16),
       k = torch::randn({2, 2, 131, 64}).mul(2).to(torch::kBFloat16),
       v = torch::randn({2, 2, 131, 64}).to(torch::kBFloat16);
  auto w = torch::randn({2, 2, 97, 64}, torch::kFloat64);
  auto fused = run(kernels::fused_attention, q, k, v, w);
  EXPECT_EQ(fused.o.scalar_type(), torch::kBFloat16);
  EXPECT_EQ(fused.dq.scalar_type(), torch::kBFloat16);
  // Against exact attention of the same bf16 inputs: fp32 accumulation leaves the bf16 rounding of the
  // probabilities, score gradients and results (2^-9 relative each): within 2% of each tensor's largest value.
  expect_close(fused, run(reference_attention, q, k, v, w), 2e-2, /*relative=*/true);
}

TEST(FlashAttention, Bf16GradientsAtTheDemoHeadWidthAndSeveralKeyTiles) {
  if (!fused_available(torch::kBFloat16, 32)) GTEST_SKIP() << "no AVX-512 BF16 at this ISA level";
  torch::manual_seed(7);
  // d_head 32 (the demo model) and 16; 1000 keys = a full 768-key forward tile and a tail of 232 (the online
  // softmax rescales), seven 128-key backward tiles and a tail of 104, so the transposed dK / dV stores meet full and
  // partial 16 x 16 blocks; 203 queries = two forward tasks and three backward query tiles, the last of odd length.
  for (int64_t D : {32, 16}) {
    auto q = torch::randn({2, 3, 203, D}).mul(2).to(torch::kBFloat16),
         k = torch::randn({2, 3, 1000, D}).mul(2).to(torch::kBFloat16),
         v = torch::randn({2, 3, 1000, D}).to(torch::kBFloat16);
    auto w = torch::randn({2, 3, 203, D}, torch::kFloat64);
    SCOPED_TRACE(testing::Message() << "D = " << D);
    expect_close(run(kernels::fused_attention, q, k, v, w), run(reference_attention, q, k, v, w), 2e-2, true);
  }
}

// The bf16 kernels pack K, V, q and dO straight from their strided rows and read q and dO in place where rows start
// on whole 32-bit words (else from a copy): rows an odd number of elements apart (every other row half-word
// aligned) must give exactly what the contiguous copies give, at head widths of one, two and three 16-lane blocks of
// words' halves (16, 32, 48: a partial block of words in the transposed packing) and odd lengths.
TEST(FlashAttention, Bf16PackingOfOddStridesEqualsContiguousOperandsBitForBit) {
  if (!fused_available(torch::kBFloat16, 16)) GTEST_SKIP() << "no AVX-512 BF16 at this ISA level";
  torch::manual_seed(9);
  const int64_t B = 2, H = 2;
  for (int64_t D : {16, 32, 48})
    for (auto [Lq, Lk] : {std::pair<int64_t, int64_t>{37, 29}, {5, 70}}) {
      // [B, L, H D + 1] narrowed to [B, L, H, D] and viewed as [B, H, L, D]: row stride H D + 1, odd.
      auto odd_view = [&](int64_t L, double scale) {
        auto full = (torch::randn({B, L, H * D + 1}) * scale).to(torch::kBFloat16);
        return full.narrow(2, 0, H * D).view({B, L, H, D}).transpose(1, 2);
      };
      auto q = odd_view(Lq, 2), k = odd_view(Lk, 2), v = odd_view(Lk, 1);
      ASSERT_EQ(q.stride(2) % 2, 1);
      auto w = torch::randn({B, H, Lq, D}, torch::kFloat64);
      auto strided = run(kernels::fused_attention, q, k, v, w);
      auto packed = run(kernels::fused_attention, q.contiguous(), k.contiguous(), v.contiguous(), w);
      SCOPED_TRACE(testing::Message() << "D " << D << ", Lq " << Lq << ", Lk " << Lk);
      EXPECT_TRUE(torch::equal(strided.o, packed.o));
      EXPECT_TRUE(torch::equal(strided.dq, packed.dq));
      EXPECT_TRUE(torch::equal(strided.dk, packed.dk));
      EXPECT_TRUE(torch::equal(strided.dv, packed.dv));
      expect_close(packed, run(reference_attention, q, k, v, w), 2e-2, true);
    }
}

namespace {

struct QkvGrads {
  torch::Tensor o, dqkv, dwq, dwk;
};

// o and the gradients of sum(o * w) through QK-Norm and attention from one projection: fused, or the composition it
// replaces (the two qk_norm nodes, then fused_attention, as QKNormAttentionImpl::project builds it).
QkvGrads qkv_attention(bool fused, const torch::Tensor& qkv_in, int64_t H, const torch::Tensor& wq_in,
                       const torch::Tensor& wk_in, int64_t start, int64_t count, const torch::Tensor& w) {
  auto qkv = qkv_in.detach().requires_grad_(true);
  auto wq = wq_in.detach().requires_grad_(true), wk = wk_in.detach().requires_grad_(true);
  const int64_t B = qkv.size(0), L = qkv.size(1), D = qkv.size(2) / 3 / H;
  torch::Tensor o;
  if (fused) {
    o = kernels::fused_qk_norm_attention(qkv, H, wq, wk, 1e-3, start, count);
  } else {
    auto parts = qkv.chunk(3, -1);
    auto split = [&](const torch::Tensor& t) { return t.view({B, L, H, D}); };
    auto q = kernels::qk_norm(split(parts[0]).narrow(1, start, count), wq, 1e-3, torch::kBFloat16).transpose(1, 2);
    auto k = kernels::qk_norm(split(parts[1]), wk, 1e-3, torch::kBFloat16).transpose(1, 2);
    o = kernels::fused_attention(q, k, split(parts[2]).transpose(1, 2));
  }
  (o.to(torch::kFloat64) * w).sum().backward();
  return {o.detach(), qkv.grad(), wq.grad(), wk.grad()};
}

}  // namespace

// The norm applied as the kernels read q and k, and qkv's gradient written as one tensor, give the composition's
// bits: outputs and qkv gradients equal; the weights' gradients, summed per head instead of per block of rows, within
// fp32 rounding. Head widths 16 / 32 / 64, odd lengths (several groups of 16 rows and backward key tiles), all
// queries or a range, and a projection whose rows are an odd number of elements apart.
TEST(FlashAttention, QKNormOnReadEqualsQKNormThenAttentionBitForBit) {
  if (!fused_available(torch::kBFloat16, 16)) GTEST_SKIP() << "no AVX-512 BF16 at this ISA level";
  torch::manual_seed(13);
  const int64_t B = 2, H = 3;
  for (int64_t D : {16, 32, 64})
    for (int64_t L : {37, 150})
      for (bool odd_rows : {false, true})
        for (auto [start, count] : {std::pair<int64_t, int64_t>{0, L}, {5, 20}}) {
          const int64_t width = 3 * H * D;
          auto qkv = (torch::randn({B, L, width + (odd_rows ? 1 : 0)}) * 2).to(torch::kBFloat16).narrow(2, 0, width);
          auto wq = 1 + 0.3 * torch::randn({D}), wk = 1 + 0.3 * torch::randn({D});
          auto w = torch::randn({B, H, count, D}, torch::kFloat64);
          SCOPED_TRACE(testing::Message() << "D " << D << ", L " << L << ", odd rows " << odd_rows << ", queries "
                                          << start << " + " << count);
          ASSERT_TRUE(kernels::fused_qk_norm_attention_applies(qkv, wq, D));
          auto fused = qkv_attention(true, qkv, H, wq, wk, start, count, w);
          auto composed = qkv_attention(false, qkv, H, wq, wk, start, count, w);
          EXPECT_TRUE(torch::equal(fused.o, composed.o));
          EXPECT_TRUE(torch::equal(fused.dqkv, composed.dqkv));
          EXPECT_LE(test::max_abs_diff(fused.dwq, composed.dwq), 1e-5 * composed.dwq.abs().max().item<double>());
          EXPECT_LE(test::max_abs_diff(fused.dwk, composed.dwk), 1e-5 * composed.dwk.abs().max().item<double>());
        }
}

// fp32 without gradients (inference): the norm read by the fp32 kernels gives the bits of qk_norm (fp32) then
// fused_attention; with gradients on it does not apply (the fp32 backward has no norm), and its backward refuses.
TEST(FlashAttention, QKNormOnReadInFp32InferenceEqualsQKNormThenAttentionBitForBit) {
  if (!kernels::flash::qk_norm_on_read_available()) GTEST_SKIP() << "QK-Norm on read needs AVX-512";
  torch::manual_seed(19);
  const int64_t B = 2, H = 3;
  for (int64_t D : {16, 32, 64})
    for (int64_t L : {37, 150})
      for (auto [start, count] : {std::pair<int64_t, int64_t>{0, L}, {5, 20}}) {
        const int64_t width = 3 * H * D;
        auto qkv = (torch::randn({B, L, width + 1}) * 2).narrow(2, 0, width);  // rows an odd number apart
        auto wq = 1 + 0.3 * torch::randn({D}), wk = 1 + 0.3 * torch::randn({D});
        SCOPED_TRACE(testing::Message() << "D " << D << ", L " << L << ", queries " << start << " + " << count);
        EXPECT_FALSE(kernels::fused_qk_norm_attention_applies(qkv, wq, D)) << "gradients on: not served";
        torch::NoGradGuard no_grad;
        ASSERT_TRUE(kernels::fused_qk_norm_attention_applies(qkv, wq, D));
        auto fused = kernels::fused_qk_norm_attention(qkv, H, wq, wk, 1e-3, start, count);
        auto parts = qkv.chunk(3, -1);
        auto split = [&](const torch::Tensor& t) { return t.view({B, L, H, D}); };
        auto q = kernels::qk_norm(split(parts[0]).narrow(1, start, count), wq, 1e-3, torch::kFloat32).transpose(1, 2);
        auto k = kernels::qk_norm(split(parts[1]), wk, 1e-3, torch::kFloat32).transpose(1, 2);
        auto composed = kernels::fused_attention(q, k, split(parts[2]).transpose(1, 2));
        ASSERT_EQ(fused.scalar_type(), torch::kFloat32);
        EXPECT_TRUE(torch::equal(fused, composed));
      }
}

TEST(FlashAttention, QKNormOnReadRejectsWhatItCannotServeByName) {
  if (!fused_available(torch::kBFloat16, 32)) GTEST_SKIP() << "no AVX-512 BF16 at this ISA level";
  auto qkv = torch::randn({1, 8, 3 * 2 * 32}).to(torch::kBFloat16);
  auto w = torch::ones({32});
  auto expect_error = [](const std::function<void()>& call, const std::string& part) {
    try {
      call();
      ADD_FAILURE() << "expected an error naming " << part;
    } catch (const c10::Error& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  expect_error([&] { kernels::fused_qk_norm_attention(qkv, 5, w, w, 1e-3, 0, 8); }, "[B, L, 3 H D] for 5 heads");
  expect_error([&] { kernels::fused_qk_norm_attention(qkv.to(torch::kFloat32), 2, w, w, 1e-3, 0, 8); },
               "fp32 qkv with AVX-512, gradients off");
  expect_error([&] { kernels::fused_qk_norm_attention(qkv.to(torch::kFloat64), 2, w, w, 1e-3, 0, 8); }, "bf16 qkv");
  expect_error([&] { kernels::fused_qk_norm_attention(qkv, 2, torch::ones({16}), w, 1e-3, 0, 8); }, "weights of size");
  expect_error([&] { kernels::fused_qk_norm_attention(qkv, 2, w, w, 1e-3, 4, 5); }, "query rows [4, 9) outside the 8");
  expect_error([&] { kernels::fused_qk_norm_attention(qkv, 2, w, w, 1e-3, 0, 0); }, "query rows [0, 0)");
}

TEST(FlashAttention, QKNormOnReadWeightGradientsDoNotDependOnTheThreadCount) {
  if (!fused_available(torch::kBFloat16, 32)) GTEST_SKIP() << "no AVX-512 BF16 at this ISA level";
  torch::manual_seed(17);
  auto qkv = torch::randn({3, 41, 3 * 4 * 32}).to(torch::kBFloat16);
  auto wq = 1 + 0.3 * torch::randn({32}), wk = 1 + 0.3 * torch::randn({32});
  auto w = torch::randn({3, 4, 41, 32}, torch::kFloat64);
  const int threads = at::get_num_threads();
  at::set_num_threads(1);
  auto one = qkv_attention(true, qkv, 4, wq, wk, 0, 41, w);
  at::set_num_threads(std::max(2, threads));
  auto several = qkv_attention(true, qkv, 4, wq, wk, 0, 41, w);
  at::set_num_threads(threads);
  EXPECT_TRUE(torch::equal(one.dwq, several.dwq));
  EXPECT_TRUE(torch::equal(one.dwk, several.dwk));
  EXPECT_TRUE(torch::equal(one.dqkv, several.dqkv));
}

TEST(FlashAttention, ModelAttentionUsesFusedKernelUnderAutocastAndFallsBackElsewhere) {
  if (!fused_available(torch::kFloat32, 32)) GTEST_SKIP() << "no fused fp32 attention below AVX2";
  torch::manual_seed(6);
  auto q = torch::randn({1, 2, 20, 32}), k = torch::randn({1, 2, 20, 32}), v = torch::randn({1, 2, 20, 32});
  auto exact = reference_attention(q, k, v);
  EXPECT_LE(test::max_abs_diff(kernels::attention(q, k, v).to(torch::kFloat64), exact), 1e-5);
  {
    AutocastGuard amp(torch::kCPU, true);
    auto o = kernels::attention(q, k, v);
    EXPECT_EQ(o.scalar_type(), torch::kBFloat16);
    EXPECT_LE(test::max_abs_diff(o.to(torch::kFloat64), exact), 3e-2);
  }
  // d_head 24 is not a multiple of 16: the unfused path serves it.
  EXPECT_FALSE(fused_available(torch::kFloat32, 24));
  auto q24 = torch::randn({1, 2, 9, 24}), k24 = torch::randn({1, 2, 9, 24}), v24 = torch::randn({1, 2, 9, 24});
  EXPECT_LE(
      test::max_abs_diff(kernels::attention(q24, k24, v24).to(torch::kFloat64), reference_attention(q24, k24, v24)),
      1e-5);
  kernels::set_attention_kernel(kernels::AttentionKernel::Unfused);
  EXPECT_FALSE(fused_available(torch::kFloat32, 32));
  EXPECT_LE(test::max_abs_diff(kernels::attention(q, k, v).to(torch::kFloat64), exact), 1e-5);
  kernels::set_attention_kernel(kernels::AttentionKernel::Fused);
}

class FlashAttentionAtLevel : public test::AtIsaLevel {};
UPLVSM_AT_EVERY_ISA_LEVEL(FlashAttentionAtLevel);

// Training skips a step whose loss is not finite: a NaN inside attention must not be smoothed away, on whichever
// path attention() takes at the level (fused fp32 from AVX2, fused bf16 with AVX-512 BF16, LibTorch below).
TEST_P(FlashAttentionAtLevel, NonFiniteInputsGiveNonFiniteOutputsLikeTheReference) {
  for (bool autocast : {false, true}) {
    SCOPED_TRACE(testing::Message() << (autocast ? "bf16 autocast" : "fp32"));
    auto attend = [&](const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
      AutocastGuard amp(torch::kCPU, autocast);
      return kernels::attention(q, k, v).to(torch::kFloat32);
    };
    auto q = torch::randn({1, 1, 20, 32}), k = torch::randn({1, 1, 20, 32}), v = torch::randn({1, 1, 20, 32});
    q[0][0][3][5] = std::numeric_limits<float>::quiet_NaN();
    auto o = attend(q, k, v);
    EXPECT_TRUE(torch::isnan(o[0][0][3]).all().item<bool>()) << "the NaN query's row";
    EXPECT_TRUE(torch::isfinite(o[0][0][4]).all().item<bool>()) << "other rows stay finite";
    // A NaN key makes one score of every row NaN: every output row is NaN, as in softmax(q k^T) v.
    q[0][0][3][5] = 0.0f;
    k[0][0][7][3] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_TRUE(torch::isnan(attend(q, k, v)).all().item<bool>()) << "a NaN key";
    EXPECT_TRUE(torch::isnan(reference_attention(q, k, v)).all().item<bool>());
  }
}

// Which kernel serves each dtype at each level: fp32 fused from AVX2 on, bf16 fused only with AVX-512 BF16, QK-Norm
// on read only with AVX-512; and a level's fused kernel agrees with fp64 attention on the model's layout.
TEST_P(FlashAttentionAtLevel, EachLevelServesTheDtypesItHasKernelsFor) {
  EXPECT_EQ(fused_available(torch::kFloat32, 32), GetParam() >= Isa::Avx2);
  EXPECT_EQ(fused_available(torch::kBFloat16, 32), GetParam() >= Isa::Avx512Bf16);
  EXPECT_EQ(kernels::flash::qk_norm_on_read_available(), GetParam() >= Isa::Avx512);
  if (GetParam() < Isa::Avx2) {
    EXPECT_THROW(
        kernels::fused_attention(torch::randn({1, 1, 4, 32}), torch::randn({1, 1, 4, 32}), torch::randn({1, 1, 4, 32})),
        c10::Error);
    return;
  }
  torch::manual_seed(4);
  const int64_t B = 2, L = 40, H = 3, D = 32;
  auto qkv = torch::randn({B, L, 3 * H * D});
  auto heads = [&](int i) { return qkv.chunk(3, -1)[i].view({B, L, H, D}).transpose(1, 2); };
  auto w = torch::randn({B, H, L, D}, torch::kFloat64);
  expect_close(run(kernels::fused_attention, heads(0), heads(1), heads(2), w),
               run(reference_attention, heads(0), heads(1), heads(2), w), 1e-5);
}

TEST(FlashAttention, RejectsMismatchedShapes) {
  auto q = torch::randn({1, 2, 8, 32}), k = torch::randn({1, 2, 9, 32}), v = torch::randn({1, 2, 10, 32});
  EXPECT_THROW(kernels::fused_attention(q, k, v), c10::Error);
  EXPECT_THROW(kernels::fused_attention(q, k.to(torch::kBFloat16), k), c10::Error);
  auto q24 = torch::randn({1, 2, 8, 24});  // d_head not a multiple of 16: only attention()'s fallback serves it
  EXPECT_THROW(kernels::fused_attention(q24, q24, q24), c10::Error);
}
