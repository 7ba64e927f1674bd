// The fp32 attention kernels for CPUs with AVX2 and FMA but no AVX-512 (Intel's consumer CPUs since 2021, AMD's
// before Zen 4): the tiles, online softmax and backward of flash_attention_kernels.cpp's fp32 kernels with 8-wide
// vectors. Each output's products are summed in the same order there and here; only the softmax's vector-width
// partial sums differ. Without them attention on these CPUs materialises its L x L scores through LibTorch.
#include <immintrin.h>

#include "uplvsm/kernels/flash_attention_simd.h"

#define UPLVSM_AVX2 __attribute__((target("avx2,fma")))

namespace uplvsm::kernels::flash::detail {
namespace {

constexpr int64_t kWidth = 8;     // floats per __m256
constexpr int64_t kAvx2Rows = 6;  // micro-kernel rows: 6 x 2 accumulators + 2 B vectors + 1 broadcast of 16 ymm

// C[R x 8*NV] (+)= A[R x K] B[K x 8*NV]; A element (r, p) at A[r * a_rs + p * a_cs], B rows ldb apart.
template <int R, int NV>
UPLVSM_AVX2 void micro_kernel_avx2(int64_t K, const float* A, int64_t a_rs, int64_t a_cs, const float* B, int64_t ldb,
                                   float* C, int64_t ldc, bool accumulate) {
  __m256 acc[R][NV];
#pragma GCC unroll 8
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 2
    for (int v = 0; v < NV; ++v) acc[r][v] = accumulate ? _mm256_loadu_ps(C + r * ldc + 8 * v) : _mm256_setzero_ps();
  const float* a_row[R];
#pragma GCC unroll 8
  for (int r = 0; r < R; ++r) a_row[r] = A + r * a_rs;
  for (int64_t p = 0; p < K; ++p) {
    __m256 b[NV];
#pragma GCC unroll 2
    for (int v = 0; v < NV; ++v) b[v] = _mm256_loadu_ps(B + p * ldb + 8 * v);
#pragma GCC unroll 8
    for (int r = 0; r < R; ++r) {
      const __m256 a = _mm256_broadcast_ss(a_row[r] + p * a_cs);
#pragma GCC unroll 2
      for (int v = 0; v < NV; ++v) acc[r][v] = _mm256_fmadd_ps(a, b[v], acc[r][v]);
    }
  }
#pragma GCC unroll 8
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 2
    for (int v = 0; v < NV; ++v) _mm256_storeu_ps(C + r * ldc + 8 * v, acc[r][v]);
}

using MicroKernel = void (*)(int64_t, const float*, int64_t, int64_t, const float*, int64_t, float*, int64_t, bool);

template <int NV>
constexpr MicroKernel avx2_kernels_for_rows[kAvx2Rows] = {micro_kernel_avx2<1, NV>, micro_kernel_avx2<2, NV>,
                                                          micro_kernel_avx2<3, NV>, micro_kernel_avx2<4, NV>,
                                                          micro_kernel_avx2<5, NV>, micro_kernel_avx2<6, NV>};

// C[M x N] (+)= A[M x K] B[K x N] for N a multiple of 8, in 16-column panels.
void gemm_avx2(int64_t M, int64_t N, int64_t K, const float* A, int64_t a_rs, int64_t a_cs, const float* B, int64_t ldb,
               float* C, int64_t ldc, bool accumulate) {
  static const MicroKernel* const table[2] = {avx2_kernels_for_rows<1>, avx2_kernels_for_rows<2>};
  for (int64_t n0 = 0; n0 < N; n0 += 2 * kWidth) {
    const int64_t nv = std::min<int64_t>(2, (N - n0) / kWidth);
    for (int64_t m0 = 0; m0 < M; m0 += kAvx2Rows) {
      const int64_t rows = std::min(kAvx2Rows, M - m0);
      table[nv - 1][rows - 1](K, A + m0 * a_rs, a_rs, a_cs, B + n0, ldb, C + m0 * ldc + n0, ldc, accumulate);
    }
  }
}

// exp(x) for x <= 0 as exp_simd.h's exp_ps (Cody-Waite, degree-7 Taylor); 2^n is built in the exponent field, so
// x below the smallest normal's log gives 0 (exp_ps gives a denormal there); NaN stays NaN.
UPLVSM_AVX2 inline __m256 exp_avx2(__m256 x) {
  const __m256 underflow = _mm256_cmp_ps(x, _mm256_set1_ps(-87.33f), _CMP_LT_OQ);
  x = _mm256_max_ps(_mm256_set1_ps(-87.33f), x);
  const __m256 n =
      _mm256_round_ps(_mm256_mul_ps(x, _mm256_set1_ps(kLog2e)), _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
  __m256 r = _mm256_fnmadd_ps(n, _mm256_set1_ps(0.693145751953125f), x);
  r = _mm256_fnmadd_ps(n, _mm256_set1_ps(1.428606765330187045e-06f), r);
  __m256 poly = _mm256_set1_ps(1.0f / 5040);
  for (float c : {1.0f / 720, 1.0f / 120, 1.0f / 24, 1.0f / 6, 0.5f, 1.0f, 1.0f})
    poly = _mm256_fmadd_ps(poly, r, _mm256_set1_ps(c));
  const __m256i exponent = _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23);
  return _mm256_andnot_ps(underflow, _mm256_mul_ps(poly, _mm256_castsi256_ps(exponent)));
}

UPLVSM_AVX2 inline float reduce_max_avx2(__m256 v) {
  __m128 m = _mm_max_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  m = _mm_max_ps(m, _mm_movehl_ps(m, m));
  return _mm_cvtss_f32(_mm_max_ss(m, _mm_movehdup_ps(m)));
}

UPLVSM_AVX2 inline float reduce_add_avx2(__m256 v) {
  __m128 s = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  s = _mm_add_ps(s, _mm_movehl_ps(s, s));
  return _mm_cvtss_f32(_mm_add_ss(s, _mm_movehdup_ps(s)));
}

// One online-softmax step (flash_attention_kernels.cpp's online_softmax_step): S -> P in place, m, l and O updated.
UPLVSM_AVX2 void online_softmax_step_avx2(int64_t rows, int64_t keys, int64_t ld_s, float* S, float* m, float* l,
                                          float* O, int64_t D) {
  const int64_t full = keys / kWidth * kWidth;
  for (int64_t r = 0; r < rows; ++r) {
    float* s = S + r * ld_s;
    __m256 vmax = _mm256_set1_ps(-std::numeric_limits<float>::infinity());
    for (int64_t j = 0; j < full; j += kWidth) vmax = _mm256_max_ps(vmax, _mm256_loadu_ps(s + j));
    float row_max = reduce_max_avx2(vmax);
    for (int64_t j = full; j < keys; ++j) row_max = std::max(row_max, s[j]);
    const float m_new = std::max(m[r], row_max);
    const __m256 vm = _mm256_set1_ps(m_new);
    __m256 vsum = _mm256_setzero_ps();
    for (int64_t j = 0; j < full; j += kWidth) {
      const __m256 e = exp_avx2(_mm256_sub_ps(_mm256_loadu_ps(s + j), vm));
      _mm256_storeu_ps(s + j, e);
      vsum = _mm256_add_ps(vsum, e);
    }
    float sum = reduce_add_avx2(vsum);
    for (int64_t j = full; j < keys; ++j) sum += (s[j] = std::exp(s[j] - m_new));
    const float alpha = std::exp(m[r] - m_new);  // 0 on the first tile (m = -inf)
    l[r] = l[r] * alpha + sum;
    m[r] = m_new;
    if (alpha != 1.0f)
      for (int64_t d = 0; d < D; ++d) O[r * D + d] *= alpha;
  }
}

// Backward of softmax for a tile (softmax_backward_tile): S becomes P = exp(S - lse), dP becomes P (dP - delta).
UPLVSM_AVX2 void softmax_backward_tile_avx2(int64_t rows, int64_t keys, int64_t ld, float* S, float* dP,
                                            const float* lse, const float* delta) {
  const int64_t full = keys / kWidth * kWidth;
  for (int64_t r = 0; r < rows; ++r) {
    float *s = S + r * ld, *dp = dP + r * ld;
    const __m256 vl = _mm256_set1_ps(lse[r]), vd = _mm256_set1_ps(delta[r]);
    for (int64_t j = 0; j < full; j += kWidth) {
      const __m256 P = exp_avx2(_mm256_sub_ps(_mm256_loadu_ps(s + j), vl));
      _mm256_storeu_ps(s + j, P);
      _mm256_storeu_ps(dp + j, _mm256_mul_ps(P, _mm256_sub_ps(_mm256_loadu_ps(dp + j), vd)));
    }
    for (int64_t j = full; j < keys; ++j) {
      s[j] = std::exp(s[j] - lse[r]);
      dp[j] = s[j] * (dp[j] - delta[r]);
    }
  }
}

// Rows [0, L) of head bh of an fp32 operand as a row-major [L x D] matrix, times `mul`.
void load_rows_fp32(const Problem& p, const void* base, Strides s, int64_t bh, int64_t L, float mul, float* dst) {
  for (int64_t i = 0; i < L; ++i) {
    const float* src = static_cast<const float*>(base) + head_offset(p, s, bh, i);
    for (int64_t d = 0; d < p.D; ++d) dst[i * p.D + d] = src[d] * mul;
  }
}

// Rows [row, row + count) of head bh from a row-major [count x D] matrix, row i times row_mul[i] (null: times mul).
void store_rows_fp32(const Problem& p, void* base, Strides s, int64_t bh, int64_t row, int64_t count, const float* src,
                     const float* row_mul, float mul = 1.0f) {
  for (int64_t i = 0; i < count; ++i) {
    float* dst = static_cast<float*>(base) + head_offset(p, s, bh, row + i);
    const float m = row_mul ? row_mul[i] : mul;
    for (int64_t d = 0; d < p.D; ++d) dst[d] = src[i * p.D + d] * m;
  }
}

// The transpose [D x ld] of a row-major [L x D] matrix (ld = round_up(L, 8)), columns L..ld zero.
UPLVSM_AVX2 void transpose_rows_avx2(const float* rows, int64_t L, int64_t D, int64_t ld, float* dst) {
  for (int64_t j0 = 0; j0 < ld; j0 += kWidth)
    for (int64_t d0 = 0; d0 < D; d0 += kWidth) {
      __m256 r[8], t[8];
      for (int64_t i = 0; i < 8; ++i)
        r[i] = j0 + i < L ? _mm256_loadu_ps(rows + (j0 + i) * D + d0) : _mm256_setzero_ps();
      for (int i = 0; i < 4; ++i) {  // 2x2 blocks of row pairs
        t[2 * i] = _mm256_unpacklo_ps(r[2 * i], r[2 * i + 1]);
        t[2 * i + 1] = _mm256_unpackhi_ps(r[2 * i], r[2 * i + 1]);
      }
      for (int i = 0; i < 2; ++i) {  // 4x4 blocks within each 128-bit lane
        r[4 * i] = _mm256_shuffle_ps(t[4 * i], t[4 * i + 2], 0x44);
        r[4 * i + 1] = _mm256_shuffle_ps(t[4 * i], t[4 * i + 2], 0xEE);
        r[4 * i + 2] = _mm256_shuffle_ps(t[4 * i + 1], t[4 * i + 3], 0x44);
        r[4 * i + 3] = _mm256_shuffle_ps(t[4 * i + 1], t[4 * i + 3], 0xEE);
      }
      for (int i = 0; i < 4; ++i) {  // the 128-bit lanes of rows 0-3 and 4-7
        t[i] = _mm256_permute2f128_ps(r[i], r[4 + i], 0x20);
        t[4 + i] = _mm256_permute2f128_ps(r[i], r[4 + i], 0x31);
      }
      for (int64_t k = 0; k < 8; ++k) _mm256_storeu_ps(dst + (d0 + k) * ld + j0, t[k]);
    }
}

}  // namespace

void pack_head_fp32_avx2(const Problem& p, int64_t bh) {
  const int64_t ld_kt = round_up(p.Lk, kWidth);
  float* Vf = scratch<float>(0, p.Lk * p.D);
  load_rows_fp32(p, p.k, p.sk, bh, p.Lk, 1.0f, Vf);
  transpose_rows_avx2(Vf, p.Lk, p.D, ld_kt, scratch<float>(1, p.D * ld_kt));
  load_rows_fp32(p, p.v, p.sv, bh, p.Lk, 1.0f, Vf);
}

void forward_rows_fp32_avx2(const Problem& p, int64_t bh, int64_t row_begin, int64_t row_end, void* o, Strides so,
                            float* lse) {
  const int64_t D = p.D, ld_kt = round_up(p.Lk, kWidth);
  const float* Vf = scratch<float>(0, p.Lk * D);
  const float* Kt = scratch<float>(1, D * ld_kt);
  float* Q = scratch<float>(2, kQueryTile * D);
  float* S = scratch<float>(3, kQueryTile * kKeyTile);
  float* O = scratch<float>(4, kQueryTile * D);
  float m[kQueryTile], l[kQueryTile], inv_l[kQueryTile];
  for (int64_t i0 = row_begin; i0 < row_end; i0 += kQueryTile) {
    const int64_t rows = std::min(kQueryTile, row_end - i0);
    for (int64_t r = 0; r < rows; ++r) {
      const float* src = static_cast<const float*>(p.q) + head_offset(p, p.sq, bh, i0 + r);
      for (int64_t d = 0; d < D; ++d) Q[r * D + d] = src[d] * p.scale;
    }
    std::fill(O, O + rows * D, 0.0f);
    std::fill(m, m + rows, -std::numeric_limits<float>::infinity());
    std::fill(l, l + rows, 0.0f);
    for (int64_t j0 = 0; j0 < p.Lk; j0 += kKeyTile) {
      const int64_t keys = std::min(kKeyTile, p.Lk - j0), key_pad = round_up(keys, kWidth);
      gemm_avx2(rows, key_pad, D, Q, D, 1, Kt + j0, ld_kt, S, kKeyTile, false);  // S = (scale q) k^T
      online_softmax_step_avx2(rows, keys, kKeyTile, S, m, l, O, D);
      gemm_avx2(rows, D, keys, S, kKeyTile, 1, Vf + j0 * D, D, O, D, true);  // O += P v
    }
    for (int64_t r = 0; r < rows; ++r) {
      inv_l[r] = 1.0f / l[r];
      lse[bh * p.Lq + i0 + r] = m[r] + std::log(l[r]);
    }
    store_rows_fp32(p, o, so, bh, i0, rows, O, inv_l);
  }
}

UPLVSM_AVX2 void backward_delta_fp32_avx2(const Problem& p, const void* o, Strides so, const void* dout, Strides sdo,
                                          int64_t bh, float* delta) {
  for (int64_t i = 0; i < p.Lq; ++i) {
    const float* a = static_cast<const float*>(o) + head_offset(p, so, bh, i);
    const float* b = static_cast<const float*>(dout) + head_offset(p, sdo, bh, i);
    __m256d sum = _mm256_setzero_pd();
    for (int64_t d = 0; d < p.D; d += 4)
      sum = _mm256_fmadd_pd(_mm256_cvtps_pd(_mm_loadu_ps(a + d)), _mm256_cvtps_pd(_mm_loadu_ps(b + d)), sum);
    const __m128d half = _mm_add_pd(_mm256_castpd256_pd128(sum), _mm256_extractf128_pd(sum, 1));
    delta[bh * p.Lq + i] = static_cast<float>(_mm_cvtsd_f64(_mm_add_sd(half, _mm_unpackhi_pd(half, half))));
  }
}

void backward_head_fp32_avx2(const Problem& p, int64_t bh, const void* dout, Strides sdo, const float* lse,
                             const float* delta, void* dq, Strides sdq, void* dk, Strides sdk, void* dv, Strides sdv) {
  const int64_t D = p.D, Lq = p.Lq, Lk = p.Lk, ld_t = round_up(Lk, kWidth);
  float* Qs = scratch<float>(0, Lq * D);  // q * scale, row-major
  float* dO = scratch<float>(1, Lq * D);
  float* Kf = scratch<float>(2, Lk * D);
  float* Kt = scratch<float>(3, D * ld_t);
  float* Vt = scratch<float>(4, D * ld_t);
  float* dQ = scratch<float>(5, Lq * D);
  float* S = scratch<float>(6, kBwdQueryTile * kBwdKeyTile);
  float* dP = scratch<float>(7, kBwdQueryTile * kBwdKeyTile);
  float* dK = scratch<float>(8, kBwdKeyTile * D);
  float* dV = scratch<float>(9, kBwdKeyTile * D);
  load_rows_fp32(p, p.q, p.sq, bh, Lq, p.scale, Qs);
  load_rows_fp32(p, dout, sdo, bh, Lq, 1.0f, dO);
  load_rows_fp32(p, p.v, p.sv, bh, Lk, 1.0f, Kf);
  transpose_rows_avx2(Kf, Lk, D, ld_t, Vt);
  load_rows_fp32(p, p.k, p.sk, bh, Lk, 1.0f, Kf);
  transpose_rows_avx2(Kf, Lk, D, ld_t, Kt);
  std::fill(dQ, dQ + Lq * D, 0.0f);
  for (int64_t j0 = 0; j0 < Lk; j0 += kBwdKeyTile) {
    const int64_t keys = std::min(kBwdKeyTile, Lk - j0), key_pad = round_up(keys, kWidth);
    std::fill(dK, dK + keys * D, 0.0f);
    std::fill(dV, dV + keys * D, 0.0f);
    for (int64_t i0 = 0; i0 < Lq; i0 += kBwdQueryTile) {
      const int64_t rows = std::min(kBwdQueryTile, Lq - i0);
      const float *Qi = Qs + i0 * D, *dOi = dO + i0 * D;
      gemm_avx2(rows, key_pad, D, Qi, D, 1, Kt + j0, ld_t, S, kBwdKeyTile, false);    // S = Qs K^T
      gemm_avx2(rows, key_pad, D, dOi, D, 1, Vt + j0, ld_t, dP, kBwdKeyTile, false);  // dP = dO V^T
      softmax_backward_tile_avx2(rows, keys, kBwdKeyTile, S, dP, lse + bh * Lq + i0, delta + bh * Lq + i0);
      gemm_avx2(keys, D, rows, S, 1, kBwdKeyTile, dOi, D, dV, D, true);                    // dV += P^T dO
      gemm_avx2(keys, D, rows, dP, 1, kBwdKeyTile, Qi, D, dK, D, true);                    // dK += dS^T Qs
      gemm_avx2(rows, D, keys, dP, kBwdKeyTile, 1, Kf + j0 * D, D, dQ + i0 * D, D, true);  // dQ += dS K
    }
    store_rows_fp32(p, dk, sdk, bh, j0, keys, dK, nullptr);
    store_rows_fp32(p, dv, sdv, bh, j0, keys, dV, nullptr);
  }
  store_rows_fp32(p, dq, sdq, bh, 0, Lq, dQ, nullptr, p.scale);
}

}  // namespace uplvsm::kernels::flash::detail
