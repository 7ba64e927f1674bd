#include "uplvsm/kernels/gelu.h"

#include <ATen/Parallel.h>
#include <ATen/record_function.h>

#include <cstdlib>
#include <cstring>

#include "uplvsm/kernels/bf16_simd.h"
#include "uplvsm/kernels/exp_simd.h"

namespace uplvsm::kernels {
namespace {

using torch::autograd::AutogradContext;
using torch::autograd::variable_list;
using BF16 = c10::BFloat16;

// Elements per parallel task: a few hundred microseconds of work, so waking the second thread pays.
constexpr int64_t kGrain = 1 << 15;

bool forced_aten() {
  static const bool aten = [] {
    const char* env = std::getenv("UPLVSM_GELU");
    return env && std::strcmp(env, "aten") == 0;
  }();
  return aten;
}

// 16 bf16 values from p, the last ones zero past `mask`, as fp32 (the masked tail only: Zen 4 runs masked 16-bit
// loads and stores far slower than plain ones).
UPLVSM_ROW_AVX512 inline __m512 load_tail(const BF16* p, __mmask16 mask) {
  const __m256i bits = _mm256_maskz_loadu_epi16(mask, p);
  return _mm512_castsi512_ps(_mm512_slli_epi32(_mm512_cvtepu16_epi32(bits), 16));
}

UPLVSM_ROW_AVX512 inline void store_tail(BF16* p, __m512 v, __mmask16 mask) {
  _mm256_mask_storeu_epi16(p, mask, row_simd::to_bf16_bits(v));
}

// The normal distribution function Phi(x) = (1 + erf(x / sqrt 2)) / 2 through A&S 7.1.28 with z = |x| / sqrt 2:
// 1 - erf(z) = (1 + a1 z + ... + a6 z^6)^-16. Infinite q gives 0 and 1 in the tails; NaN stays NaN.
UPLVSM_ROW_AVX512 inline __m512 normal_cdf(__m512 x) {
  const __m512 z = _mm512_mul_ps(_mm512_abs_ps(x), _mm512_set1_ps(0.70710678118654752f));
  __m512 q = _mm512_set1_ps(0.0000430638f);
  q = _mm512_fmadd_ps(q, z, _mm512_set1_ps(0.0002765672f));
  q = _mm512_fmadd_ps(q, z, _mm512_set1_ps(0.0001520143f));
  q = _mm512_fmadd_ps(q, z, _mm512_set1_ps(0.0092705272f));
  q = _mm512_fmadd_ps(q, z, _mm512_set1_ps(0.0422820123f));
  q = _mm512_fmadd_ps(q, z, _mm512_set1_ps(0.0705230784f));
  q = _mm512_fmadd_ps(q, z, _mm512_set1_ps(1.0f));
  q = _mm512_mul_ps(q, q);  // q^2, q^4, q^8, q^16
  q = _mm512_mul_ps(q, q);
  q = _mm512_mul_ps(q, q);
  q = _mm512_mul_ps(q, q);
  const __m512 half_tail = _mm512_div_ps(_mm512_set1_ps(0.5f), q);  // Phi(-|x|)
  const __mmask16 positive = _mm512_cmp_ps_mask(x, _mm512_setzero_ps(), _CMP_GE_OQ);
  return _mm512_mask_sub_ps(half_tail, positive, _mm512_set1_ps(1.0f), half_tail);
}

UPLVSM_ROW_AVX512 inline __m512 gelu16(__m512 x) { return _mm512_mul_ps(x, normal_cdf(x)); }

// d gelu / dx = Phi(x) + x phi(x), phi(x) = exp(-x^2 / 2) / sqrt(2 pi), times the upstream gradient, in the order
// LibTorch's kernel multiplies.
UPLVSM_ROW_AVX512 inline __m512 gelu_backward16(__m512 x, __m512 g) {
  const __m512 minus_half = _mm512_set1_ps(-0.5f), beta = _mm512_set1_ps(0.39894228040143268f);
  const __m512 pdf = _mm512_mul_ps(beta, row_simd::exp_ps(_mm512_mul_ps(_mm512_mul_ps(x, x), minus_half)));
  return _mm512_mul_ps(g, _mm512_add_ps(normal_cdf(x), _mm512_mul_ps(x, pdf)));
}

UPLVSM_ROW_AVX512 void forward_range(const BF16* x, int64_t begin, int64_t end, BF16* y) {
  int64_t i = begin;
  for (; i + 16 <= end; i += 16) row_simd::store16(y + i, gelu16(row_simd::load16(x + i)));
  if (i < end) {
    const __mmask16 mask = row_simd::tail_mask(end - i);
    store_tail(y + i, gelu16(load_tail(x + i, mask)), mask);
  }
}

UPLVSM_ROW_AVX512 void backward_range(const BF16* x, const BF16* g, int64_t begin, int64_t end, BF16* gx) {
  int64_t i = begin;
  for (; i + 16 <= end; i += 16)
    row_simd::store16(gx + i, gelu_backward16(row_simd::load16(x + i), row_simd::load16(g + i)));
  if (i < end) {
    const __mmask16 mask = row_simd::tail_mask(end - i);
    store_tail(gx + i, gelu_backward16(load_tail(x + i, mask), load_tail(g + i, mask)), mask);
  }
}

struct GeluFunction : torch::autograd::Function<GeluFunction> {
  static torch::Tensor forward(AutogradContext* ctx, torch::Tensor x) {
    RECORD_FUNCTION("uplvsm::gelu", std::vector<c10::IValue>());
    x = x.contiguous();
    auto y = torch::empty_like(x, torch::MemoryFormat::Contiguous);
    const BF16* in = x.data_ptr<BF16>();
    BF16* out = y.data_ptr<BF16>();
    at::parallel_for(0, x.numel(), kGrain, [&](int64_t begin, int64_t end) { forward_range(in, begin, end, out); });
    ctx->save_for_backward({x});
    return y;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grad_outputs) {
    RECORD_FUNCTION("uplvsm::gelu_backward", std::vector<c10::IValue>());
    const auto x = ctx->get_saved_variables()[0];
    const auto g = grad_outputs[0].to(torch::kBFloat16).contiguous();
    auto gx = torch::empty_like(x, torch::MemoryFormat::Contiguous);
    const BF16 *in = x.data_ptr<BF16>(), *up = g.data_ptr<BF16>();
    BF16* out = gx.data_ptr<BF16>();
    at::parallel_for(0, x.numel(), kGrain,
                     [&](int64_t begin, int64_t end) { backward_range(in, up, begin, end, out); });
    return {gx};
  }
};

}  // namespace

bool gelu_fuses(const torch::Tensor& x) {
  return !forced_aten() && x.device().is_cpu() && x.scalar_type() == torch::kBFloat16 && isa_at_least(Isa::Avx512);
}

torch::Tensor gelu(const torch::Tensor& x) {
  if (gelu_fuses(x)) return GeluFunction::apply(x);
  // bf16 without the fused kernel: in fp32, rounded once, as the fused kernel computes (LibTorch 1.13's own bf16
  // GELU on an AVX2 CPU is off by more than a bf16 step for a third of N(0, 9) inputs).
  if (x.scalar_type() == torch::kBFloat16 && x.device().is_cpu() && !forced_aten())
    return torch::gelu(x.to(torch::kFloat32)).to(torch::kBFloat16);
  return torch::gelu(x);
}

}  // namespace uplvsm::kernels
