// AdamW's element-wise update in one AVX-512 pass (kernels/ops.h: adamw_update), moved from the optimiser so that the
// trainer holds the optimiser's logic and this folder its SIMD.
#include <ATen/Parallel.h>

#include <cmath>

#include "uplvsm/kernels/bf16_simd.h"
#include "uplvsm/kernels/ops.h"

// GCC 12's _mm512_sqrt_ps starts from _mm512_undefined_ps, which -Wmaybe-uninitialized misreads.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

namespace uplvsm::kernels {

namespace {
// AdamW's per-step constants, rounded to fp32 as its tensor ops round their Scalar arguments.
struct AdamWConstants {
  float decay, beta1, one_minus_beta1, beta2, one_minus_beta2, sqrt_bias_correction2, eps, minus_step_size;
};

AdamWConstants adamw_constants(const torch::optim::AdamWOptions& o, int64_t step) {
  const auto [beta1, beta2] = o.betas();
  const double bias_correction1 = 1 - std::pow(beta1, static_cast<double>(step));
  const double bias_correction2 = 1 - std::pow(beta2, static_cast<double>(step));
  // No decay multiplies by 1, which is exact (AdamW::step skips the multiply).
  return {o.weight_decay() != 0 ? static_cast<float>(1 - o.lr() * o.weight_decay()) : 1.0f,
          static_cast<float>(beta1),
          static_cast<float>(1 - beta1),
          static_cast<float>(beta2),
          static_cast<float>(1 - beta2),
          static_cast<float>(std::sqrt(bias_correction2)),
          static_cast<float>(o.eps()),
          static_cast<float>(-(o.lr() / bias_correction1))};
}

// The element-wise body of AdamW::step, 16 lanes at a time: p.mul_(decay); m.mul_(b1).add_(g, 1 - b1) (ATen's add
// with alpha is one fused multiply-add); v.mul_(b2).addcmul_(g, g, 1 - b2) (one more: (1 - b2) g times g plus b2 v);
// denom = v.sqrt() / sqrt(bc2) + eps; p.addcdiv_(m, denom, -step_size) — every intermediate rounded to fp32 as there.
// No contraction: GCC would fuse the decayed weight's multiply into the final add, which ATen rounds in between.
UPLVSM_ROW_AVX512 __attribute__((optimize("fp-contract=off"))) void adamw_update_avx512(float* p, float* m, float* v,
                                                                                        const float* g, int64_t begin,
                                                                                        int64_t end,
                                                                                        const AdamWConstants& k) {
  const __m512 decay = _mm512_set1_ps(k.decay);
  const __m512 beta1 = _mm512_set1_ps(k.beta1), one_minus_beta1 = _mm512_set1_ps(k.one_minus_beta1);
  const __m512 beta2 = _mm512_set1_ps(k.beta2), one_minus_beta2 = _mm512_set1_ps(k.one_minus_beta2);
  const __m512 sqrt_bc2 = _mm512_set1_ps(k.sqrt_bias_correction2), eps = _mm512_set1_ps(k.eps);
  const __m512 minus_step_size = _mm512_set1_ps(k.minus_step_size);
  for (int64_t i = begin; i < end; i += 16) {
    const __mmask16 lanes = row_simd::tail_mask(end - i);
    const __m512 gi = _mm512_maskz_loadu_ps(lanes, g + i);
    const __m512 pi = _mm512_mul_ps(_mm512_maskz_loadu_ps(lanes, p + i), decay);
    const __m512 mi = _mm512_fmadd_ps(gi, one_minus_beta1, _mm512_mul_ps(_mm512_maskz_loadu_ps(lanes, m + i), beta1));
    const __m512 vi = _mm512_fmadd_ps(_mm512_mul_ps(one_minus_beta2, gi), gi,
                                      _mm512_mul_ps(_mm512_maskz_loadu_ps(lanes, v + i), beta2));
    const __m512 denom = _mm512_add_ps(_mm512_div_ps(_mm512_sqrt_ps(vi), sqrt_bc2), eps);
    _mm512_mask_storeu_ps(m + i, lanes, mi);
    _mm512_mask_storeu_ps(v + i, lanes, vi);
    _mm512_mask_storeu_ps(p + i, lanes, _mm512_add_ps(pi, _mm512_div_ps(_mm512_mul_ps(minus_step_size, mi), denom)));
  }
}

void adamw_update_rows(float* p, float* m, float* v, const float* g, int64_t n, const AdamWConstants& k) {
  constexpr int64_t kGrain = 32768;  // small tensors (biases, norms) stay on the calling thread
  at::parallel_for(0, n, kGrain, [&](int64_t begin, int64_t end) { adamw_update_avx512(p, m, v, g, begin, end, k); });
}

bool adamw_fusable(const torch::Tensor& t) {
  return t.defined() && t.device().is_cpu() && t.scalar_type() == torch::kFloat32 && t.is_contiguous();
}
}  // namespace

bool adamw_update_fuses(const torch::Tensor& p, const torch::Tensor& grad, const torch::Tensor& exp_avg,
                        const torch::Tensor& exp_avg_sq) {
  return isa_at_least(Isa::Avx512) && adamw_fusable(p) && adamw_fusable(grad) && adamw_fusable(exp_avg) &&
         adamw_fusable(exp_avg_sq) && grad.numel() == p.numel() && exp_avg.numel() == p.numel() &&
         exp_avg_sq.numel() == p.numel();
}

void adamw_update(const torch::Tensor& p, const torch::Tensor& grad, const torch::Tensor& exp_avg,
                  const torch::Tensor& exp_avg_sq, int64_t step, const torch::optim::AdamWOptions& options) {
  TORCH_CHECK(adamw_update_fuses(p, grad, exp_avg, exp_avg_sq), "adamw_update: needs fp32 contiguous CPU tensors");
  adamw_update_rows(p.data_ptr<float>(), exp_avg.data_ptr<float>(), exp_avg_sq.data_ptr<float>(),
                    grad.data_ptr<float>(), p.numel(), adamw_constants(options, step));
}

}  // namespace uplvsm::kernels
