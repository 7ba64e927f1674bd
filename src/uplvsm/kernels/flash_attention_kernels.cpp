#include "uplvsm/kernels/flash_attention_kernels.h"

#include "uplvsm/core/cpu_isa.h"
#include "uplvsm/kernels/bf16_simd.h"
#include "uplvsm/kernels/flash_attention_simd.h"
#include "uplvsm/kernels/qk_norm_rows.h"

#include <stdexcept>

namespace uplvsm::kernels::flash {
namespace {

using namespace detail;

// C[R x 16*NV] (+)= A[R x K] B[K x 16*NV]; A element (r, p) at A[r * a_rs + p * a_cs], B rows ldb apart.
template <int R, int NV>
UPLVSM_AVX512 void micro_kernel(int64_t K, const float* A, int64_t a_rs, int64_t a_cs, const float* B, int64_t ldb,
                                float* C, int64_t ldc, bool accumulate) {
  __m512 acc[R][NV];
#pragma GCC unroll 8
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) acc[r][v] = accumulate ? _mm512_loadu_ps(C + r * ldc + 16 * v) : _mm512_setzero_ps();
  const float* a_row[R];
#pragma GCC unroll 8
  for (int r = 0; r < R; ++r) a_row[r] = A + r * a_rs;
  for (int64_t p = 0; p < K; ++p) {
    __m512 b[NV];
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) b[v] = _mm512_loadu_ps(B + p * ldb + 16 * v);
#pragma GCC unroll 8
    for (int r = 0; r < R; ++r) {
      const __m512 a = _mm512_set1_ps(a_row[r][p * a_cs]);
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) acc[r][v] = _mm512_fmadd_ps(a, b[v], acc[r][v]);
    }
  }
#pragma GCC unroll 8
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) _mm512_storeu_ps(C + r * ldc + 16 * v, acc[r][v]);
}

using MicroKernel = void (*)(int64_t, const float*, int64_t, int64_t, const float*, int64_t, float*, int64_t, bool);

template <int NV>
constexpr MicroKernel kernels_for_rows[kRows] = {micro_kernel<1, NV>, micro_kernel<2, NV>, micro_kernel<3, NV>,
                                                 micro_kernel<4, NV>, micro_kernel<5, NV>, micro_kernel<6, NV>};

// C[M x N] (+)= A[M x K] B[K x N] for N a multiple of 16, in 64-column panels (a K x 64 panel of B stays in L1).
void gemm(int64_t M, int64_t N, int64_t K, const float* A, int64_t a_rs, int64_t a_cs, const float* B, int64_t ldb,
          float* C, int64_t ldc, bool accumulate) {
  static const MicroKernel* const table[4] = {kernels_for_rows<1>, kernels_for_rows<2>, kernels_for_rows<3>,
                                              kernels_for_rows<4>};
  for (int64_t n0 = 0; n0 < N; n0 += 64) {
    const int64_t nv = std::min<int64_t>(4, (N - n0) / 16);
    for (int64_t m0 = 0; m0 < M; m0 += kRows) {
      const int64_t rows = std::min(kRows, M - m0);
      table[nv - 1][rows - 1](K, A + m0 * a_rs, a_rs, a_cs, B + n0, ldb, C + m0 * ldc + n0, ldc, accumulate);
    }
  }
}

// ---- fp32 rows and softmax steps ----

// Row `row` of head `bh` of an fp32 operand (length D), times `mul`.
void load_row(const Problem& p, const void* base, Strides s, int64_t bh, int64_t row, float mul, float* dst) {
  const float* src = static_cast<const float*>(base) + head_offset(p, s, bh, row);
  for (int64_t d = 0; d < p.D; ++d) dst[d] = src[d] * mul;
}

void store_row(const Problem& p, void* base, Strides s, int64_t bh, int64_t row, const float* src, float mul) {
  float* dst = static_cast<float*>(base) + head_offset(p, s, bh, row);
  for (int64_t d = 0; d < p.D; ++d) dst[d] = src[d] * mul;
}

// One online-softmax step for a query tile: scores S (rows x keys, fp32, already scaled: q carries the scale) -> P in
// place, the running max m and sum l updated and the output accumulator O (rows x D) rescaled.
UPLVSM_AVX512 void online_softmax_step(int64_t rows, int64_t keys, int64_t ld_s, float* S, float* m, float* l, float* O,
                                       int64_t D) {
  for (int64_t r = 0; r < rows; ++r) {
    float* s = S + r * ld_s;
    __m512 vmax = _mm512_set1_ps(-std::numeric_limits<float>::infinity());
    for (int64_t j = 0; j < keys; j += 16) {
      const __mmask16 mask = tail_mask(keys - j);
      vmax = _mm512_mask_max_ps(vmax, mask, vmax, _mm512_maskz_loadu_ps(mask, s + j));
    }
    const float m_new = std::max(m[r], _mm512_reduce_max_ps(vmax));
    const __m512 vm = _mm512_set1_ps(m_new);
    __m512 vsum = _mm512_setzero_ps();
    for (int64_t j = 0; j < keys; j += 16) {
      const __mmask16 mask = tail_mask(keys - j);
      const __m512 e = exp_ps(_mm512_sub_ps(_mm512_maskz_loadu_ps(mask, s + j), vm));
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

// Backward of softmax for a tile of scaled scores: P = exp(S - lse) recomputed, dS = P (dP - delta) row-wise; S is
// overwritten with P, dP with dS.
UPLVSM_AVX512 void softmax_backward_tile(int64_t rows, int64_t keys, int64_t ld, float* S, float* dP, const float* lse,
                                         const float* delta) {
  for (int64_t r = 0; r < rows; ++r) {
    const __m512 vl = _mm512_set1_ps(lse[r]), vd = _mm512_set1_ps(delta[r]);
    for (int64_t j = 0; j < keys; j += 16) {
      const __mmask16 mask = tail_mask(keys - j);
      const __m512 P = exp_ps(_mm512_sub_ps(_mm512_maskz_loadu_ps(mask, S + r * ld + j), vl));
      _mm512_mask_storeu_ps(S + r * ld + j, mask, P);
      const __m512 g = _mm512_sub_ps(_mm512_maskz_loadu_ps(mask, dP + r * ld + j), vd);
      _mm512_mask_storeu_ps(dP + r * ld + j, mask, _mm512_mul_ps(P, g));
    }
  }
}

// ---- forward ----

// Rows [0, L) of an operand as a row-major [L x D] fp32 matrix, times `mul`.
void load_rows(const Problem& p, const void* base, Strides s, int64_t bh, int64_t L, float mul, float* dst) {
  for (int64_t i = 0; i < L; ++i) load_row(p, base, s, bh, i, mul, dst + i * p.D);
}

// The transpose [D x ld] of a row-major [L x D] matrix (ld = round_up(L, 16)), columns L..ld zero (so key tiles can
// be padded to 16), 16 x 16 blocks at a time in registers.
UPLVSM_AVX512 void transpose_rows(const float* rows, int64_t L, int64_t D, int64_t ld, float* dst) {
  for (int64_t j0 = 0; j0 < ld; j0 += 16)
    for (int64_t d0 = 0; d0 < D; d0 += 16) {
      __m512 block[16];
      for (int64_t i = 0; i < 16; ++i)
        block[i] = j0 + i < L ? _mm512_loadu_ps(rows + (j0 + i) * D + d0) : _mm512_setzero_ps();
      transpose_16x16(block);
      for (int64_t k = 0; k < 16; ++k) _mm512_storeu_ps(dst + (d0 + k) * ld + j0, block[k]);
    }
}

// Rows [row, row + count) of head bh of an fp32 operand through QK-Norm with weight w (Problem::norm: kernels/qk_norm's
// fp32 bits, qk_norm_rows.h), times `mul` as load_row multiplies, into dst ([count x D]).
UPLVSM_AVX512 void load_rows_through_norm(const Problem& p, const void* base, Strides s, int64_t bh, int64_t row,
                                          int64_t count, const float* w, float mul, float* dst) {
  using qk_norm_rows::kGroup;
  const float* x[kGroup];  // entries [0, n) of each group are set and read
  float* out[kGroup];
  float r[kGroup];
  for (int64_t i0 = 0; i0 < count; i0 += kGroup) {
    const int64_t n = std::min(kGroup, count - i0);
    for (int64_t i = 0; i < n; ++i) {
      x[i] = static_cast<const float*>(base) + head_offset(p, s, bh, row + i0 + i);
      out[i] = dst + (i0 + i) * p.D;
    }
    qk_norm_rows::forward_group<float, float>(x, n, w, p.norm.eps, p.D, out, r);
    for (int64_t e = i0 * p.D; e < (i0 + n) * p.D; ++e) dst[e] *= mul;
  }
}

// fp32 forward, per thread: K^T (scratch 1) and V (scratch 0) of the head being worked on.
void pack_head_fp32(const Problem& p, int64_t bh) {
  const int64_t ld_kt = round_up(p.Lk, 16);
  float* Vf = scratch<float>(0, p.Lk * p.D);
  if (p.norm.active())
    load_rows_through_norm(p, p.k, p.sk, bh, 0, p.Lk, p.norm.k_weight, 1.0f, Vf);
  else
    load_rows(p, p.k, p.sk, bh, p.Lk, 1.0f, Vf);
  transpose_rows(Vf, p.Lk, p.D, ld_kt, scratch<float>(1, p.D * ld_kt));
  load_rows(p, p.v, p.sv, bh, p.Lk, 1.0f, Vf);
}

void forward_rows_fp32(const Problem& p, int64_t bh, int64_t row_begin, int64_t row_end, void* o, Strides so,
                       float* lse) {
  const int64_t D = p.D, ld_kt = round_up(p.Lk, 16);
  const float* Vf = scratch<float>(0, p.Lk * D);
  const float* Kt = scratch<float>(1, D * ld_kt);
  float* Q = scratch<float>(2, kQueryTile * D);
  float* S = scratch<float>(3, kQueryTile * kKeyTile);
  float* O = scratch<float>(4, kQueryTile * D);
  float m[kQueryTile], l[kQueryTile];
  for (int64_t i0 = row_begin; i0 < row_end; i0 += kQueryTile) {
    const int64_t rows = std::min(kQueryTile, row_end - i0);
    if (p.norm.active())
      load_rows_through_norm(p, p.q, p.sq, bh, i0, rows, p.norm.q_weight, p.scale, Q);
    else
      for (int64_t r = 0; r < rows; ++r) load_row(p, p.q, p.sq, bh, i0 + r, p.scale, Q + r * D);
    std::fill(O, O + rows * D, 0.0f);
    std::fill(m, m + rows, -std::numeric_limits<float>::infinity());
    std::fill(l, l + rows, 0.0f);
    for (int64_t j0 = 0; j0 < p.Lk; j0 += kKeyTile) {
      const int64_t keys = std::min(kKeyTile, p.Lk - j0), key_pad = round_up(keys, 16);
      gemm(rows, key_pad, D, Q, D, 1, Kt + j0, ld_kt, S, kKeyTile, false);  // S = (scale q) k^T
      online_softmax_step(rows, keys, kKeyTile, S, m, l, O, D);
      gemm(rows, D, keys, S, kKeyTile, 1, Vf + j0 * D, D, O, D, true);  // O += P v
    }
    for (int64_t r = 0; r < rows; ++r) {
      store_row(p, o, so, bh, i0 + r, O + r * D, 1.0f / l[r]);
      lse[bh * p.Lq + i0 + r] = m[r] + std::log(l[r]);
    }
  }
}

void backward_head_fp32(const Problem& p, int64_t bh, const void* dout, Strides sdo, const float* lse,
                        const float* delta, void* dq, Strides sdq, void* dk, Strides sdk, void* dv, Strides sdv) {
  const int64_t D = p.D, Lq = p.Lq, Lk = p.Lk, ld_t = round_up(Lk, 16);
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
  load_rows(p, p.q, p.sq, bh, Lq, p.scale, Qs);
  load_rows(p, dout, sdo, bh, Lq, 1.0f, dO);
  load_rows(p, p.v, p.sv, bh, Lk, 1.0f, Kf);
  transpose_rows(Kf, Lk, D, ld_t, Vt);
  load_rows(p, p.k, p.sk, bh, Lk, 1.0f, Kf);
  transpose_rows(Kf, Lk, D, ld_t, Kt);
  std::fill(dQ, dQ + Lq * D, 0.0f);
  const float* lse_h = lse + bh * Lq;
  const float* delta_h = delta + bh * Lq;
  for (int64_t j0 = 0; j0 < Lk; j0 += kBwdKeyTile) {
    const int64_t keys = std::min(kBwdKeyTile, Lk - j0), key_pad = round_up(keys, 16);
    std::fill(dK, dK + keys * D, 0.0f);
    std::fill(dV, dV + keys * D, 0.0f);
    for (int64_t i0 = 0; i0 < Lq; i0 += kBwdQueryTile) {
      const int64_t rows = std::min(kBwdQueryTile, Lq - i0);
      const float* Qi = Qs + i0 * D;
      const float* dOi = dO + i0 * D;
      gemm(rows, key_pad, D, Qi, D, 1, Kt + j0, ld_t, S, kBwdKeyTile, false);    // S = Qs K^T
      gemm(rows, key_pad, D, dOi, D, 1, Vt + j0, ld_t, dP, kBwdKeyTile, false);  // dP = dO V^T
      softmax_backward_tile(rows, keys, kBwdKeyTile, S, dP, lse_h + i0, delta_h + i0);
      gemm(keys, D, rows, S, 1, kBwdKeyTile, dOi, D, dV, D, true);                    // dV += P^T dO
      gemm(keys, D, rows, dP, 1, kBwdKeyTile, Qi, D, dK, D, true);                    // dK += dS^T Qs
      gemm(rows, D, keys, dP, kBwdKeyTile, 1, Kf + j0 * D, D, dQ + i0 * D, D, true);  // dQ += dS K
    }
    for (int64_t j = 0; j < keys; ++j) {
      store_row(p, dk, sdk, bh, j0 + j, dK + j * D, 1.0f);
      store_row(p, dv, sdv, bh, j0 + j, dV + j * D, 1.0f);
    }
  }
  for (int64_t i = 0; i < Lq; ++i) store_row(p, dq, sdq, bh, i, dQ + i * D, p.scale);
}

}  // namespace

bool flash_kernels_available(Precision precision, int64_t d_head) {
  if (d_head <= 0 || d_head % 16 != 0 || d_head > 256) return false;
  return isa_at_least(precision == Precision::Fp32 ? Isa::Avx2 : Isa::Avx512Bf16);
}

bool qk_norm_on_read_available() { return isa_at_least(Isa::Avx512); }

int64_t forward_task_count(const Problem& p) { return p.B * p.H * row_chunks(p); }

namespace {
// The kernels of one precision and vector width: bf16 (AVX-512 BF16), fp32 with AVX-512, fp32 with AVX2.
enum class Flavour { Bf16, Fp32Avx512, Fp32Avx2 };
Flavour flavour_of(const Problem& p) {
  if (p.precision == Precision::Bf16) return Flavour::Bf16;
  return isa_at_least(Isa::Avx512) ? Flavour::Fp32Avx512 : Flavour::Fp32Avx2;
}
}  // namespace

void forward_tasks(const Problem& p, int64_t begin, int64_t end, void* o, Strides so, float* lse) {
  const Flavour flavour = flavour_of(p);
  const auto pack = flavour == Flavour::Bf16         ? pack_head_bf16
                    : flavour == Flavour::Fp32Avx512 ? pack_head_fp32
                                                     : pack_head_fp32_avx2;
  const auto rows = flavour == Flavour::Bf16         ? forward_rows_bf16
                    : flavour == Flavour::Fp32Avx512 ? forward_rows_fp32
                                                     : forward_rows_fp32_avx2;
  if (flavour == Flavour::Fp32Avx2 && p.norm.active())
    throw std::logic_error("flash::forward_tasks: the AVX2 kernels do not apply QK-Norm on read");
  const int64_t chunks = row_chunks(p);
  int64_t packed_head = -1;
  for (int64_t t = begin; t < end; ++t) {
    const int64_t bh = t / chunks, chunk = t % chunks;
    if (bh != packed_head) {  // consecutive tasks of one head share its packed K and V
      pack(p, bh);
      packed_head = bh;
    }
    const int64_t row_begin = chunk * kRowsPerTask, row_end = std::min(p.Lq, row_begin + kRowsPerTask);
    rows(p, bh, row_begin, row_end, o, so, lse);
  }
}

// 16 elements of row `row` of an fp32 or bf16 operand, from column d, as fp32.
UPLVSM_AVX512 inline __m512 load16(const Problem& p, const void* base, Strides s, int64_t bh, int64_t row, int64_t d) {
  const int64_t offset = head_offset(p, s, bh, row) + d;
  return p.precision == Precision::Fp32 ? row_simd::load16(static_cast<const float*>(base) + offset)
                                        : row_simd::load16(static_cast<const uint16_t*>(base) + offset);
}

// delta = rowsum(dout * o), accumulated in double (D is a multiple of 16).
UPLVSM_AVX512 void backward_delta_avx512(const Problem& p, const void* o, Strides so, const void* dout, Strides sdo,
                                         int64_t begin, int64_t end, float* delta) {
  for (int64_t bh = begin; bh < end; ++bh)
    for (int64_t i = 0; i < p.Lq; ++i) {
      __m512d sum = _mm512_setzero_pd();
      for (int64_t d = 0; d < p.D; d += 16) {
        const __m512 a = load16(p, o, so, bh, i, d), b = load16(p, dout, sdo, bh, i, d);
        sum = _mm512_fmadd_pd(_mm512_cvtps_pd(_mm512_castps512_ps256(a)), _mm512_cvtps_pd(_mm512_castps512_ps256(b)),
                              sum);
        sum = _mm512_fmadd_pd(_mm512_cvtps_pd(_mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(a), 1))),
                              _mm512_cvtps_pd(_mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(b), 1))), sum);
      }
      delta[bh * p.Lq + i] = static_cast<float>(_mm512_reduce_add_pd(sum));
    }
}

void backward_delta(const Problem& p, const void* o, Strides so, const void* dout, Strides sdo, int64_t begin,
                    int64_t end, float* delta) {
  if (flavour_of(p) != Flavour::Fp32Avx2) return backward_delta_avx512(p, o, so, dout, sdo, begin, end, delta);
  for (int64_t bh = begin; bh < end; ++bh) backward_delta_fp32_avx2(p, o, so, dout, sdo, bh, delta);
}

void backward_tasks(const Problem& p, const void* dout, Strides sdo, const float* lse, const float* delta,
                    int64_t begin, int64_t end, void* dq, Strides sdq, void* dk, Strides sdk, void* dv, Strides sdv) {
  const Flavour flavour = flavour_of(p);
  const auto head = flavour == Flavour::Bf16         ? backward_head_bf16
                    : flavour == Flavour::Fp32Avx512 ? backward_head_fp32
                                                     : backward_head_fp32_avx2;
  for (int64_t bh = begin; bh < end; ++bh) head(p, bh, dout, sdo, lse, delta, dq, sdq, dk, sdk, dv, sdv);
}

}  // namespace uplvsm::kernels::flash
