// Internal to the fused QK-Norm (qk_norm.cpp) and the attention kernels that apply it as they read q and k
// (flash_attention_kernels_bf16.cpp): QK-Norm's arithmetic on groups of up to 16 rows with AVX-512, forward and
// backward, so that both compute the same bits. Callers compile their calling functions with UPLVSM_ROW_AVX512 and
// check isa_at_least(Isa::Avx512); D is a multiple of 16.
#pragma once
#include <immintrin.h>

#include <cstdint>

#include "uplvsm/kernels/bf16_simd.h"

namespace uplvsm::kernels::qk_norm_rows {

constexpr int64_t kGroup = 16;  // rows whose horizontal sums are taken together

// Lane i of the result is the sum of v[i]'s lanes, in one fixed tree (lanes i and i + 8, then i and i + 4, then
// (0 + 2) + (1 + 3), as GCC's _mm512_reduce_add_ps): sixteen rows' horizontal sums as one transposition, and a row's
// sum does not depend on the rows beside it.
UPLVSM_ROW_AVX512 inline __m512 reduce_rows(const __m512 v[kGroup]) {
  __m512 t8[8], t4[4], t2[2];
  for (int k = 0; k < 8; ++k)  // rows 2k, 2k + 1: lanes i + (i + 8), in 256-bit halves
    t8[k] = _mm512_add_ps(_mm512_shuffle_f32x4(v[2 * k], v[2 * k + 1], 0x44),
                          _mm512_shuffle_f32x4(v[2 * k], v[2 * k + 1], 0xEE));
  for (int k = 0; k < 4; ++k)  // rows 4k .. 4k + 3: lanes i + (i + 4), one row per 128-bit lane
    t4[k] = _mm512_add_ps(_mm512_shuffle_f32x4(t8[2 * k], t8[2 * k + 1], 0x88),
                          _mm512_shuffle_f32x4(t8[2 * k], t8[2 * k + 1], 0xDD));
  for (int k = 0; k < 2; ++k)  // 0 + 2 and 1 + 3 within each row
    t2[k] = _mm512_add_ps(_mm512_shuffle_ps(t4[2 * k], t4[2 * k + 1], _MM_SHUFFLE(1, 0, 1, 0)),
                          _mm512_shuffle_ps(t4[2 * k], t4[2 * k + 1], _MM_SHUFFLE(3, 2, 3, 2)));
  const __m512 sums = _mm512_add_ps(_mm512_shuffle_ps(t2[0], t2[1], _MM_SHUFFLE(2, 0, 2, 0)),
                                    _mm512_shuffle_ps(t2[0], t2[1], _MM_SHUFFLE(3, 1, 3, 1)));
  // Lane 4 l + t now holds row l + 4 t.
  return _mm512_permutexvar_ps(_mm512_setr_epi32(0, 4, 8, 12, 1, 5, 9, 13, 2, 6, 10, 14, 3, 7, 11, 15), sums);
}

// Rows x[0..n) (n <= 16): r[i] = 1 / sqrt(mean(x[i]^2) + eps) and out[i] = ((x[i] r[i]) rounded to T) w, rounded
// to TOut — RMSNormImpl's forward followed by the cast to TOut.
template <typename T, typename TOut>
UPLVSM_ROW_AVX512 inline void forward_group(const T* const x[kGroup], int64_t n, const float* w, float eps, int64_t D,
                                            TOut* const out[kGroup], float r[kGroup]) {
  using namespace row_simd;
  __m512 acc[kGroup];
  for (int64_t i = 0; i < kGroup; ++i) {
    acc[i] = _mm512_setzero_ps();
    for (int64_t j = 0; i < n && j < D; j += 16) {
      const __m512 xv = load16(x[i] + j);
      acc[i] = _mm512_fmadd_ps(xv, xv, acc[i]);
    }
  }
  const __m512 mean = _mm512_div_ps(reduce_rows(acc), _mm512_set1_ps(static_cast<float>(D)));
  const __m512 rr = _mm512_div_ps(_mm512_set1_ps(1.0f), _mm512_sqrt_ps(_mm512_add_ps(mean, _mm512_set1_ps(eps))));
  alignas(64) float rs[kGroup];
  _mm512_store_ps(rs, rr);
  for (int64_t i = 0; i < n; ++i) {
    r[i] = rs[i];
    const __m512 rv = _mm512_set1_ps(rs[i]);
    for (int64_t j = 0; j < D; j += 16)
      store16(out[i] + j, _mm512_mul_ps(round16<T>(_mm512_mul_ps(load16(x[i] + j), rv)), _mm512_loadu_ps(w + j)));
  }
}

// The backward of forward_group for upstream gradients g[i]: gx[i] = g_y r + x (2 / D) (-0.5 g_r r^3) with
// g_y = (g w) rounded to T and g_r = sum(g_y x), rounded to T; when gw is not null, the weight gradient g * y (y
// rounded to T) is added into it row by row, in order — in registers over the group up to 128 features.
template <typename T, typename TOut>
UPLVSM_ROW_AVX512 inline void backward_group(const T* const x[kGroup], const TOut* const g[kGroup], int64_t n,
                                             const float* w, const float r[kGroup], int64_t D, T* const gx[kGroup],
                                             float* gw) {
  using namespace row_simd;
  constexpr int kMaxVectors = 8;
  const bool gw_in_registers = gw && D <= 16 * kMaxVectors;
  __m512 gw_acc[kMaxVectors];
#pragma GCC unroll 8
  for (int v = 0; v < kMaxVectors; ++v)
    gw_acc[v] = gw_in_registers && 16 * v < D ? _mm512_loadu_ps(gw + 16 * v) : _mm512_setzero_ps();
  __m512 acc[kGroup];
  for (int64_t i = 0; i < kGroup; ++i) {
    acc[i] = _mm512_setzero_ps();
    if (i >= n) continue;
    const __m512 rv = _mm512_set1_ps(r[i]);
    if (gw_in_registers) {
#pragma GCC unroll 8
      for (int v = 0; v < kMaxVectors; ++v) {
        if (16 * v >= D) break;
        const __m512 xv = load16(x[i] + 16 * v), gv = load16(g[i] + 16 * v);
        acc[i] = _mm512_fmadd_ps(round16<T>(_mm512_mul_ps(gv, _mm512_loadu_ps(w + 16 * v))), xv, acc[i]);
        gw_acc[v] = _mm512_fmadd_ps(gv, round16<T>(_mm512_mul_ps(xv, rv)), gw_acc[v]);
      }
      continue;
    }
    for (int64_t j = 0; j < D; j += 16) {
      const __m512 xv = load16(x[i] + j), gv = load16(g[i] + j);
      acc[i] = _mm512_fmadd_ps(round16<T>(_mm512_mul_ps(gv, _mm512_loadu_ps(w + j))), xv, acc[i]);
      if (gw) _mm512_storeu_ps(gw + j, _mm512_fmadd_ps(gv, round16<T>(_mm512_mul_ps(xv, rv)), _mm512_loadu_ps(gw + j)));
    }
  }
  if (gw_in_registers) {
#pragma GCC unroll 8
    for (int v = 0; v < kMaxVectors; ++v)
      if (16 * v < D) _mm512_storeu_ps(gw + 16 * v, gw_acc[v]);
  }
  // g_sq2 = 2 (-0.5 g_r r^3 / D), in the order of operations of a one-row loop.
  const __m512 rv = _mm512_maskz_loadu_ps(tail_mask(n), r);
  const __m512 t =
      _mm512_mul_ps(_mm512_mul_ps(_mm512_set1_ps(-0.5f), reduce_rows(acc)), _mm512_mul_ps(_mm512_mul_ps(rv, rv), rv));
  alignas(64) float g_sq2[kGroup];
  _mm512_store_ps(g_sq2, _mm512_mul_ps(_mm512_set1_ps(2.0f), _mm512_div_ps(t, _mm512_set1_ps(static_cast<float>(D)))));
  for (int64_t i = 0; i < n; ++i) {
    const __m512 rvi = _mm512_set1_ps(r[i]), g_sq2v = _mm512_set1_ps(g_sq2[i]);
    for (int64_t j = 0; j < D; j += 16) {
      const __m512 gy = round16<T>(_mm512_mul_ps(load16(g[i] + j), _mm512_loadu_ps(w + j)));
      store16(gx[i] + j, _mm512_fmadd_ps(g_sq2v, load16(x[i] + j), _mm512_mul_ps(gy, rvi)));
    }
  }
}

}  // namespace uplvsm::kernels::qk_norm_rows
