// Internal to the fused attention kernels (flash_attention_kernels*.cpp): tile sizes, the AVX-512 exp2 (bf16
// kernels; exp is exp_simd.h's), tail masks, per-thread scratch, the bf16 kernels' entry points.
#pragma once
#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "uplvsm/kernels/exp_simd.h"
#include "uplvsm/kernels/flash_attention_kernels.h"

// GCC 12's AVX-512 reduction intrinsics start from _mm512_undefined_ps, which -Wmaybe-uninitialized misreads.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#define UPLVSM_AVX512 __attribute__((target("avx512f,avx512bw,avx512vl,avx512dq")))
#define UPLVSM_AVX512_BF16 __attribute__((target("avx512f,avx512bw,avx512vl,avx512dq,avx512bf16")))

namespace uplvsm::kernels::flash::detail {

using row_simd::exp_ps;
using row_simd::tail_mask;

constexpr int64_t kRows = 6;        // micro-kernel rows: 6 x 4 accumulators + 4 B vectors fit 32 zmm registers
constexpr int64_t kQueryTile = 48;  // forward: query rows per online-softmax step
constexpr int64_t kKeyTile = 128;   // forward: keys per step (S tile 48 x 128 fp32 = 24 KiB, L1-resident)
// The bf16 forward's tile: 12 queries x 768 keys takes a demo sequence (544) or an x224 one (1280) in one or two
// key steps, so the online softmax's per-step reductions and rescales are few: 8-16 % faster than 48 x 128 at
// both shapes (`AttentionDemo`, `Attention/L:1280`), its 36-KiB score tile in L2. The fp32 kernels keep theirs
// (their sums' order is part of what the official-code comparisons check).
constexpr int64_t kBf16QueryTile = 12;
constexpr int64_t kBf16KeyTile = 768;
constexpr int64_t kBwdQueryTile = 48;  // backward: even, so bf16 row pairs never straddle tiles
constexpr int64_t kBwdKeyTile = 64;
constexpr int64_t kBf16BwdQueryTile = 96;  // the bf16 backward's tile (even, as kBwdQueryTile): 3-5 % faster
constexpr int64_t kBf16BwdKeyTile = 128;
constexpr int64_t kRowsPerTask = 192;  // forward tasks: query rows per (batch, head) task

inline int64_t round_up(int64_t x, int64_t m) { return (x + m - 1) / m * m; }
inline int64_t row_chunks(const Problem& p) { return (p.Lq + kRowsPerTask - 1) / kRowsPerTask; }
inline int64_t head_offset(const Problem& p, Strides s, int64_t bh, int64_t row) {
  return (bh / p.H) * s.b + (bh % p.H) * s.h + row * s.l;
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

// In-register transpose of 16 rows of 16 floats: afterwards r[k][i] is the old r[i][k].
UPLVSM_AVX512 inline void transpose_16x16(__m512 r[16]) {
  __m512 t[16];
  for (int i = 0; i < 8; ++i) {  // interleave row pairs: 2x2 blocks
    t[2 * i] = _mm512_unpacklo_ps(r[2 * i], r[2 * i + 1]);
    t[2 * i + 1] = _mm512_unpackhi_ps(r[2 * i], r[2 * i + 1]);
  }
  for (int i = 0; i < 4; ++i) {  // 4x4 blocks within each 128-bit lane
    r[4 * i] = _mm512_shuffle_ps(t[4 * i], t[4 * i + 2], 0x44);
    r[4 * i + 1] = _mm512_shuffle_ps(t[4 * i], t[4 * i + 2], 0xEE);
    r[4 * i + 2] = _mm512_shuffle_ps(t[4 * i + 1], t[4 * i + 3], 0x44);
    r[4 * i + 3] = _mm512_shuffle_ps(t[4 * i + 1], t[4 * i + 3], 0xEE);
  }
  for (int i = 0; i < 4; ++i) {  // 128-bit lanes across row groups 0/1 and 2/3
    t[i] = _mm512_shuffle_f32x4(r[i], r[4 + i], 0x88);
    t[4 + i] = _mm512_shuffle_f32x4(r[i], r[4 + i], 0xDD);
    t[8 + i] = _mm512_shuffle_f32x4(r[8 + i], r[12 + i], 0x88);
    t[12 + i] = _mm512_shuffle_f32x4(r[8 + i], r[12 + i], 0xDD);
  }
  for (int i = 0; i < 4; ++i) {
    r[i] = _mm512_shuffle_f32x4(t[i], t[8 + i], 0x88);
    r[8 + i] = _mm512_shuffle_f32x4(t[i], t[8 + i], 0xDD);
    r[4 + i] = _mm512_shuffle_f32x4(t[4 + i], t[12 + i], 0x88);
    r[12 + i] = _mm512_shuffle_f32x4(t[4 + i], t[12 + i], 0xDD);
  }
}

constexpr float kLog2e = 1.44269504088896341f;

// Per-thread scratch, grown on demand and reused across calls; slots keep simultaneously live buffers apart.
template <typename T>
T* scratch(int slot, int64_t count) {
  thread_local std::vector<uint32_t> buffers[40];
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

// fp32 kernels for CPUs with AVX2 and no AVX-512 (flash_attention_kernels_avx2.cpp): the fp32 entry points of
// flash_attention_kernels.cpp with 8-wide vectors (QK-Norm on read not served: Problem::norm must be off).
void pack_head_fp32_avx2(const Problem& p, int64_t bh);
void forward_rows_fp32_avx2(const Problem& p, int64_t bh, int64_t row_begin, int64_t row_end, void* o, Strides so,
                            float* lse);
void backward_delta_fp32_avx2(const Problem& p, const void* o, Strides so, const void* dout, Strides sdo, int64_t bh,
                              float* delta);
void backward_head_fp32_avx2(const Problem& p, int64_t bh, const void* dout, Strides sdo, const float* lse,
                             const float* delta, void* dq, Strides sdq, void* dk, Strides sdk, void* dv, Strides sdv);

}  // namespace uplvsm::kernels::flash::detail
