// Internal to the fused attention kernels (flash_attention_kernels*.cpp): tile sizes, the AVX-512 exp / exp2 and the
// row-wise softmax steps shared by the fp32 and bf16 kernels, operand rows <-> fp32, per-thread scratch.
#pragma once
#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "uplvsm/model/flash_attention_kernels.h"

// GCC 12's AVX-512 reduction intrinsics start from _mm512_undefined_ps, which -Wmaybe-uninitialized misreads.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#define UPLVSM_AVX512 __attribute__((target("avx512f,avx512bw,avx512vl,avx512dq")))
#define UPLVSM_AVX512_BF16 __attribute__((target("avx512f,avx512bw,avx512vl,avx512dq,avx512bf16")))

namespace uplvsm::model::flash::detail {

constexpr int64_t kRows = 6;           // micro-kernel rows: 6 x 4 accumulators + 4 B vectors fit 32 zmm registers
constexpr int64_t kQueryTile = 48;     // forward: query rows per online-softmax step
constexpr int64_t kKeyTile = 128;      // forward: keys per step (S tile 48 x 128 fp32 = 24 KiB, L1-resident)
constexpr int64_t kBwdQueryTile = 48;  // backward: even, so bf16 row pairs never straddle tiles
constexpr int64_t kBwdKeyTile = 64;
constexpr int64_t kRowsPerTask = 192;  // forward tasks: query rows per (batch, head) task

inline int64_t round_up(int64_t x, int64_t m) { return (x + m - 1) / m * m; }
inline int64_t row_chunks(const Problem& p) { return (p.Lq + kRowsPerTask - 1) / kRowsPerTask; }
inline int64_t head_offset(const Problem& p, Strides s, int64_t bh, int64_t row) {
  return (bh / p.H) * s.b + (bh % p.H) * s.h + row * s.l;
}

// exp(x) for x <= 0 (scores minus their running max / log-sum-exp): Cody-Waite reduction x = n ln2 + r and a
// degree-7 Taylor polynomial on |r| <= ln2 / 2 (relative error < 1e-8 before rounding); -inf gives 0 and NaN
// stays NaN (vmaxps returns its second operand when either is NaN), so a diverged model still yields NaN outputs.
UPLVSM_AVX512 inline __m512 exp_ps(__m512 x) {
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

// 2^t for t <= 0 in the bf16 kernels: t = n + f with n an integer and |f| <= 1/2, 2^f by a degree-5 fit of
// relative error 1.4e-7 (their P is rounded to bf16's 2^-9 right after, so exp_ps's Cody-Waite reduction and degree
// 7 are not needed). t <= -160 and -inf give 0, NaN stays NaN (vmaxps returns its second operand when either is NaN).
UPLVSM_AVX512 inline __m512 exp2_ps(__m512 t) {
  t = _mm512_max_ps(_mm512_set1_ps(-160.0f), t);
  const __m512 n = _mm512_roundscale_ps(t, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
  const __m512 f = _mm512_sub_ps(t, n);
  __m512 poly = _mm512_set1_ps(1.3266970636323094e-3f);
  poly = _mm512_fmadd_ps(poly, f, _mm512_set1_ps(9.675459936261177e-3f));
  poly = _mm512_fmadd_ps(poly, f, _mm512_set1_ps(5.550742521882057e-2f));
  poly = _mm512_fmadd_ps(poly, f, _mm512_set1_ps(2.4022121727466583e-1f));
  poly = _mm512_fmadd_ps(poly, f, _mm512_set1_ps(6.931469440460205e-1f));
  poly = _mm512_fmadd_ps(poly, f, _mm512_set1_ps(1.0000001192092896f));
  return _mm512_scalef_ps(poly, n);
}

constexpr float kLog2e = 1.44269504088896341f;

UPLVSM_AVX512 inline __mmask16 tail_mask(int64_t remaining) {
  return remaining >= 16 ? __mmask16(0xFFFF) : __mmask16((1u << remaining) - 1);
}

// One online-softmax step for a query tile: scores S (rows x keys, fp32, times `score_scale`) -> P in place, the
// running max m and sum l updated and the output accumulator O (rows x D) rescaled.
UPLVSM_AVX512 inline void online_softmax_step(int64_t rows, int64_t keys, int64_t ld_s, float score_scale, float* S,
                                              float* m, float* l, float* O, int64_t D) {
  const __m512 vscale = _mm512_set1_ps(score_scale);
  for (int64_t r = 0; r < rows; ++r) {
    float* s = S + r * ld_s;
    __m512 vmax = _mm512_set1_ps(-std::numeric_limits<float>::infinity());
    for (int64_t j = 0; j < keys; j += 16) {
      const __mmask16 mask = tail_mask(keys - j);
      vmax = _mm512_mask_max_ps(vmax, mask, vmax, _mm512_mul_ps(_mm512_maskz_loadu_ps(mask, s + j), vscale));
    }
    const float m_new = std::max(m[r], _mm512_reduce_max_ps(vmax));
    const __m512 vm = _mm512_set1_ps(m_new);
    __m512 vsum = _mm512_setzero_ps();
    for (int64_t j = 0; j < keys; j += 16) {
      const __mmask16 mask = tail_mask(keys - j);
      const __m512 e = exp_ps(_mm512_fmsub_ps(_mm512_maskz_loadu_ps(mask, s + j), vscale, vm));
      _mm512_mask_storeu_ps(s + j, mask, e);
      vsum = _mm512_add_ps(vsum, _mm512_maskz_mov_ps(mask, e));
    }
    const float alpha = std::exp(m[r] - m_new);  // 0 on the first tile (m = -inf)
    l[r] = l[r] * alpha + _mm512_reduce_add_ps(vsum);
    m[r] = m_new;
    if (alpha != 1.0f)
      for (int64_t d = 0; d < D; ++d) O[r * D + d] *= alpha;
  }
}

// Backward of softmax for a tile: P = exp(score_scale S - lse) recomputed, dS = P (dP - delta) row-wise; S is
// overwritten with P, dP with dS.
UPLVSM_AVX512 inline void softmax_backward_tile(int64_t rows, int64_t keys, int64_t ld, float score_scale, float* S,
                                                float* dP, const float* lse, const float* delta) {
  const __m512 vscale = _mm512_set1_ps(score_scale);
  for (int64_t r = 0; r < rows; ++r) {
    const __m512 vl = _mm512_set1_ps(lse[r]), vd = _mm512_set1_ps(delta[r]);
    for (int64_t j = 0; j < keys; j += 16) {
      const __mmask16 mask = tail_mask(keys - j);
      const __m512 s = _mm512_maskz_loadu_ps(mask, S + r * ld + j);
      const __m512 P = exp_ps(_mm512_fmsub_ps(s, vscale, vl));
      _mm512_mask_storeu_ps(S + r * ld + j, mask, P);
      const __m512 g = _mm512_sub_ps(_mm512_maskz_loadu_ps(mask, dP + r * ld + j), vd);
      _mm512_mask_storeu_ps(dP + r * ld + j, mask, _mm512_mul_ps(P, g));
    }
  }
}

inline float bf16_to_float(uint16_t h) {
  const uint32_t bits = static_cast<uint32_t>(h) << 16;
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

// Round to nearest even, NaN kept quiet (as c10::BFloat16).
inline uint16_t float_to_bf16(float f) {
  uint32_t bits;
  std::memcpy(&bits, &f, sizeof bits);
  if (std::isnan(f)) return 0x7FC0;
  bits += 0x7FFF + ((bits >> 16) & 1);
  return static_cast<uint16_t>(bits >> 16);
}

// Row `row` of head `bh` of operand `base` (length D) as fp32, times `mul`.
inline void load_row(const Problem& p, const void* base, Strides s, int64_t bh, int64_t row, float mul, float* dst) {
  const int64_t offset = head_offset(p, s, bh, row);
  if (p.precision == Precision::Fp32) {
    const float* src = static_cast<const float*>(base) + offset;
    for (int64_t d = 0; d < p.D; ++d) dst[d] = src[d] * mul;
  } else {
    const uint16_t* src = static_cast<const uint16_t*>(base) + offset;
    for (int64_t d = 0; d < p.D; ++d) dst[d] = bf16_to_float(src[d]) * mul;
  }
}

inline void store_row(const Problem& p, void* base, Strides s, int64_t bh, int64_t row, const float* src, float mul) {
  const int64_t offset = head_offset(p, s, bh, row);
  if (p.precision == Precision::Fp32) {
    float* dst = static_cast<float*>(base) + offset;
    for (int64_t d = 0; d < p.D; ++d) dst[d] = src[d] * mul;
  } else {
    uint16_t* dst = static_cast<uint16_t*>(base) + offset;
    for (int64_t d = 0; d < p.D; ++d) dst[d] = float_to_bf16(src[d] * mul);
  }
}

// Per-thread scratch, grown on demand and reused across calls; slots keep simultaneously live buffers apart.
template <typename T>
T* scratch(int slot, int64_t count) {
  thread_local std::vector<uint32_t> buffers[32];
  auto& b = buffers[slot];
  const size_t words = (static_cast<size_t>(count) * sizeof(T) + 3) / 4;
  if (b.size() < words) b.resize(words);
  return reinterpret_cast<T*>(b.data());
}

// bf16 kernels (flash_attention_kernels_bf16.cpp): pack one head's K and V; forward rows of a packed head; the
// whole backward of one head.
void pack_head_bf16(const Problem& p, int64_t bh);
void forward_rows_bf16(const Problem& p, int64_t bh, int64_t row_begin, int64_t row_end, void* o, Strides so,
                       float* lse);
void backward_head_bf16(const Problem& p, int64_t bh, const void* dout, Strides sdo, const float* lse,
                        const float* delta, void* dq, Strides sdq, void* dk, Strides sdk, void* dv, Strides sdv);

}  // namespace uplvsm::model::flash::detail
