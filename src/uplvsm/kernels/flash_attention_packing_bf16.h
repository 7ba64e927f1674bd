// Internal to the bf16 attention kernels (flash_attention_kernels_bf16.cpp): one head's bf16 operands packed into
// the pair layouts the AVX-512 BF16 micro-kernel streams, read straight from their strided rows, and QK-Norm applied
// as q and k are read (Problem::norm) with qk_norm_rows.h's arithmetic, forward and backward.
#pragma once
#include <cstdint>
#include <cstring>

#include "uplvsm/kernels/flash_attention_simd.h"
#include "uplvsm/kernels/qk_norm_rows.h"

namespace uplvsm::kernels::flash::detail::bf16_packing {

inline const uint16_t* row_ptr(const Problem& p, const void* base, Strides s, int64_t bh, int64_t row) {
  return static_cast<const uint16_t*>(base) + head_offset(p, s, bh, row);
}

inline const uint32_t* words(const uint16_t* x) { return reinterpret_cast<const uint32_t*>(x); }

// ---- packing one head's operand straight from its strided rows (AVX-512) ----

// Rows of one head's bf16 operand: row i at first + i * stride.
struct HeadRows {
  const uint16_t* first;
  int64_t stride;
};

inline HeadRows head_rows(const Problem& p, const void* base, Strides s, int64_t bh) {
  return {row_ptr(p, base, s, bh, 0), s.l};
}

// Rows [row, row + count) as an A operand with pairs along D: the operand itself where its rows start on whole
// words, else a copy into scratch `slot`.
struct RowOperand {
  const uint32_t* words;
  int64_t ld;
};

inline RowOperand row_operand(HeadRows x, int64_t row, int64_t count, int64_t D, int slot) {
  const uint16_t* first = x.first + row * x.stride;
  if (x.stride % 2 == 0 && reinterpret_cast<uintptr_t>(first) % 4 == 0) return {words(first), x.stride / 2};
  uint16_t* rows = scratch<uint16_t>(slot, count * D);
  for (int64_t i = 0; i < count; ++i) std::memcpy(rows + i * D, first + i * x.stride, D * sizeof(uint16_t));
  return {words(rows), D / 2};
}

// Words (X[lo][d] | X[hi][d] << 16) for 16 columns d; hi null gives zero high halves (a missing odd row).
UPLVSM_AVX512 inline __m512i pair_words(const uint16_t* lo, const uint16_t* hi) {
  const __m512i low = _mm512_cvtepu16_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(lo)));
  if (!hi) return low;
  return _mm512_or_si512(
      low, _mm512_slli_epi32(_mm512_cvtepu16_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(hi))), 16));
}

// B = X^T with pairs along D: word (d2, j) = (X[j][2 d2], X[j][2 d2 + 1]); [D/2 x ld], ld = round_up(L, 16),
// columns >= L zero. 16 x 16 blocks of words transposed in registers.
UPLVSM_AVX512 inline void pack_transposed(HeadRows x, int64_t L, int64_t D, int64_t ld, uint32_t* dst) {
  const int64_t W = D / 2;
  for (int64_t j0 = 0; j0 < ld; j0 += 16)
    for (int64_t w0 = 0; w0 < W; w0 += 16) {
      const int64_t width = std::min<int64_t>(16, W - w0);
      __m512 block[16];
      for (int64_t i = 0; i < 16; ++i) {
        const uint16_t* src = x.first + (j0 + i) * x.stride + 2 * w0;
        block[i] = j0 + i >= L   ? _mm512_setzero_ps()
                   : width == 16 ? _mm512_loadu_ps(src)
                                 : _mm512_castsi512_ps(_mm512_maskz_loadu_epi32(tail_mask(width), src));
      }
      transpose_16x16(block);
      for (int64_t k = 0; k < width; ++k)
        _mm512_storeu_ps(reinterpret_cast<float*>(dst + (w0 + k) * ld + j0), block[k]);
    }
}

// B = X with pairs along rows: word (i2, d) = (X[2 i2][d], X[2 i2 + 1][d]); [ceil(L/2) x D], a missing row zero.
UPLVSM_AVX512 inline void pack_row_pairs(HeadRows x, int64_t L, int64_t D, uint32_t* dst) {
  for (int64_t i2 = 0; i2 < (L + 1) / 2; ++i2) {
    const uint16_t* lo = x.first + 2 * i2 * x.stride;
    const uint16_t* hi = 2 * i2 + 1 < L ? lo + x.stride : nullptr;
    for (int64_t d = 0; d < D; d += 16)
      _mm512_storeu_si512(dst + i2 * D + d, pair_words(lo + d, hi ? hi + d : nullptr));
  }
}

// A = X^T with pairs along rows: word (d, i2) = (X[2 i2][d], X[2 i2 + 1][d]); [D x ld2], ld2 = round_up(ceil(L/2),
// 16), columns past ceil(L/2) zero.
UPLVSM_AVX512 inline void pack_transposed_row_pairs(HeadRows x, int64_t L, int64_t D, int64_t ld2, uint32_t* dst) {
  const int64_t L2 = (L + 1) / 2;
  for (int64_t i20 = 0; i20 < ld2; i20 += 16)
    for (int64_t d0 = 0; d0 < D; d0 += 16) {
      __m512 block[16];
      for (int64_t i = 0; i < 16; ++i) {
        const int64_t i2 = i20 + i;
        const uint16_t* lo = x.first + 2 * i2 * x.stride + d0;
        block[i] = i2 >= L2 ? _mm512_setzero_ps()
                            : _mm512_castsi512_ps(pair_words(lo, 2 * i2 + 1 < L ? lo + x.stride : nullptr));
      }
      transpose_16x16(block);
      for (int64_t k = 0; k < 16; ++k) _mm512_storeu_ps(reinterpret_cast<float*>(dst + (d0 + k) * ld2 + i20), block[k]);
    }
}

// ---- QK-Norm as q and k are read (Problem::norm), in qk_norm_rows.h's arithmetic ----

using BF16 = c10::BFloat16;
using qk_norm_rows::kGroup;

inline const BF16* bf16_ptr(const uint16_t* x) { return reinterpret_cast<const BF16*>(x); }
inline BF16* bf16_ptr(uint16_t* x) { return reinterpret_cast<BF16*>(x); }

// Asks for rows [begin, end) of x (D elements each) ahead of use. The norm is the first to read a head's q and k
// rows, a cache line or two each and a projection's width apart: fetched as they are needed, those reads stall.
inline void prefetch_rows(HeadRows x, int64_t begin, int64_t end, int64_t D) {
  for (int64_t i = begin; i < end; ++i)
    for (int64_t d = 0; d < D; d += 32)
      _mm_prefetch(reinterpret_cast<const char*>(x.first + i * x.stride + d), _MM_HINT_T0);
}

// Rows [row, row + count) of x normalised into dst ([count x D]); their r into r[0, count) unless r is null.
UPLVSM_AVX512 inline void normalize_rows(HeadRows x, int64_t row, int64_t count, int64_t D, const float* w, float eps,
                                         uint16_t* dst, float* r) {
  float group_r[kGroup];
  const BF16* xs[kGroup];  // entries [0, n) of each group are set and read
  BF16* out[kGroup];
  for (int64_t i0 = 0; i0 < count; i0 += kGroup) {
    const int64_t n = std::min(kGroup, count - i0);
    prefetch_rows(x, row + i0 + kGroup, row + std::min(count, i0 + 2 * kGroup), D);
    for (int64_t i = 0; i < n; ++i)
      xs[i] = bf16_ptr(x.first + (row + i0 + i) * x.stride), out[i] = bf16_ptr(dst + (i0 + i) * D);
    qk_norm_rows::forward_group<BF16, BF16>(xs, n, w, eps, D, out, r ? r + i0 : group_r);
  }
}

// A head's q or k (L rows) as the kernels read it: normalised into scratch `slot` when the norm is on (r into r),
// else itself.
inline HeadRows read_through_norm(const Problem& p, HeadRows x, int64_t L, const float* w, int slot, float* r) {
  if (!p.norm.active()) return x;
  uint16_t* dst = scratch<uint16_t>(slot, L * p.D);
  normalize_rows(x, 0, L, p.D, w, p.norm.eps, dst, r);
  return {dst, p.D};
}

// g ([count x D] bf16, the gradient of normalised rows [row, row + count) of the raw x, whose r is r[row, ...))
// taken back through the norm: the raw rows' gradient into the head's gradient dx (strides s), the weight's
// gradient added into gw.
UPLVSM_AVX512 inline void norm_backward_rows(const Problem& p, int64_t bh, HeadRows x, const float* r, const float* w,
                                             const uint16_t* g, int64_t row, int64_t count, void* dx, Strides s,
                                             float* gw) {
  const BF16 *xs[kGroup], *gs[kGroup];  // entries [0, n) of each group are set and read
  BF16* gx[kGroup];
  for (int64_t i0 = 0; i0 < count; i0 += kGroup) {
    const int64_t n = std::min(kGroup, count - i0);
    for (int64_t i = 0; i < n; ++i) {
      xs[i] = bf16_ptr(x.first + (row + i0 + i) * x.stride);
      gs[i] = bf16_ptr(g + (i0 + i) * p.D);
      gx[i] = bf16_ptr(static_cast<uint16_t*>(dx) + head_offset(p, s, bh, row + i0 + i));
    }
    qk_norm_rows::backward_group<BF16, BF16>(xs, gs, n, w, r + row + i0, p.D, gx, gw);
  }
}

}  // namespace uplvsm::kernels::flash::detail::bf16_packing
