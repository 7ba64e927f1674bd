// Internal to the fused attention kernels and GELU (gelu.cpp): an AVX-512 exp of fp32 values.
#pragma once
#include <immintrin.h>

#include "uplvsm/kernels/bf16_simd.h"

namespace uplvsm::kernels::row_simd {

// exp(x) for x <= 0 (attention scores minus their running max, the -x^2/2 of a normal density): Cody-Waite
// reduction x = n ln2 + r and a degree-7 Taylor polynomial on |r| <= ln2 / 2 (relative error < 1e-8 before
// rounding); -inf gives 0 and NaN stays NaN (vmaxps returns its second operand when either is NaN), so a diverged
// model still yields NaN outputs.
UPLVSM_ROW_AVX512 inline __m512 exp_ps(__m512 x) {
  x = _mm512_max_ps(_mm512_set1_ps(-104.0f), x);
  const __m512 n = _mm512_roundscale_ps(_mm512_mul_ps(x, _mm512_set1_ps(1.44269504088896341f)),
                                        _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
  __m512 r = _mm512_fnmadd_ps(n, _mm512_set1_ps(0.693145751953125f), x);
  r = _mm512_fnmadd_ps(n, _mm512_set1_ps(1.428606765330187045e-06f), r);
  __m512 poly = _mm512_set1_ps(1.0f / 5040);
  poly = _mm512_fmadd_ps(poly, r, _mm512_set1_ps(1.0f / 720));
  poly = _mm512_fmadd_ps(poly, r, _mm512_set1_ps(1.0f / 120));
  poly = _mm512_fmadd_ps(poly, r, _mm512_set1_ps(1.0f / 24));
  poly = _mm512_fmadd_ps(poly, r, _mm512_set1_ps(1.0f / 6));
  poly = _mm512_fmadd_ps(poly, r, _mm512_set1_ps(0.5f));
  poly = _mm512_fmadd_ps(poly, r, _mm512_set1_ps(1.0f));
  poly = _mm512_fmadd_ps(poly, r, _mm512_set1_ps(1.0f));
  return _mm512_scalef_ps(poly, n);
}

}  // namespace uplvsm::kernels::row_simd
