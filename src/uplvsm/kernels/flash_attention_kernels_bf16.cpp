// The bf16 fused attention kernels: every matmul is an AVX-512 BF16 dot product of bf16 pairs with fp32
// accumulation (twice the fp32 FMA rate); softmax, running max/sum and gradients accumulate in fp32. Operands are
// packed per head into pair layouts (O(L d) work) so that the micro-kernel only streams.
#include "uplvsm/kernels/bf16_micro_kernel.h"
#include "uplvsm/kernels/bf16_simd.h"
#include "uplvsm/kernels/flash_attention_packing_bf16.h"
#include "uplvsm/kernels/flash_attention_simd.h"

namespace uplvsm::kernels::flash::detail {
namespace {

using namespace bf16_packing;

// Scratch slots (fp32 kernels use 0..9).
enum Slot : int {
  kKp = 10,
  kVp,
  kQ,
  kS,
  kO,
  kP,
  kQrows,
  kQtp,
  kDOrows,
  kDOtp,
  kVtp,
  kKrp,
  kDQ,
  kDP,
  kPpairs,
  kDSpairs,
  kDSrows,
  kDKt,
  kDVt,
  kQnorm,
  kKnorm,
  kRq,
  kRk,
  kGrows
};

// C[M x N] (+)= A[M x 2 K2] B[2 K2 x N], N a multiple of 16, in 64-column panels: A rows are bf16 pairs (one uint32
// each) lda words apart; B is packed in pairs, word (p2, n) = (B[2 p2][n], B[2 p2 + 1][n]), rows ldb words apart.
void gemm_bf16(int64_t M, int64_t N, int64_t K2, const uint32_t* A, int64_t lda, const uint32_t* B, int64_t ldb,
               float* C, int64_t ldc, bool accumulate) {
  for (int64_t n0 = 0; n0 < N; n0 += 64) {
    const int64_t nv = std::min<int64_t>(4, (N - n0) / 16);
    for (int64_t m0 = 0; m0 < M; m0 += kRows)
      bf16_tile::kernel_for<bf16_tile::ALayout::kRowMajor>(std::min(kRows, M - m0), nv)(
          K2, A + m0 * lda, lda, B + n0, ldb, C + m0 * ldc + n0, ldc, accumulate);
  }
}

// ---- fp32 tiles -> bf16 operands ----

// One online-softmax step of the bf16 forward, in base 2: scores S (rows x keys, fp32, unscaled) -> P = 2^(c S - m)
// with c = scale log2(e), written straight as bf16 rows (ld_p apart, column `keys` zeroed when odd) for the P v
// matmul; the running max m (base-2 units) and sum l updated, the output accumulator O (rows x D) rescaled.
UPLVSM_AVX512_BF16 void online_softmax_step_bf16(int64_t rows, int64_t keys, float c, const float* S, int64_t ld_s,
                                                 uint16_t* P, int64_t ld_p, float* m, float* l, float* O, int64_t D) {
  const __m512 vc = _mm512_set1_ps(c);
  const int64_t cols = round_up(keys, 2);
  for (int64_t r = 0; r < rows; ++r) {
    const float* s = S + r * ld_s;
    __m512 vmax = _mm512_set1_ps(-std::numeric_limits<float>::infinity());
    int64_t j = 0;
    for (; j + 16 <= keys; j += 16) vmax = _mm512_max_ps(vmax, _mm512_loadu_ps(s + j));
    if (j < keys)
      vmax = _mm512_mask_max_ps(vmax, tail_mask(keys - j), vmax, _mm512_maskz_loadu_ps(tail_mask(keys - j), s + j));
    const float m_new = std::max(m[r], c * _mm512_reduce_max_ps(vmax));  // c > 0: max(c s) = c max(s)
    const __m512 vm = _mm512_set1_ps(m_new);
    __m512 vsum = _mm512_setzero_ps();
    // Full blocks unmasked: Zen 4 runs masked 16-bit stores far slower than plain ones.
    for (j = 0; j + 16 <= keys; j += 16) {
      const __m512 e = exp2_ps(_mm512_fmsub_ps(_mm512_loadu_ps(s + j), vc, vm));
      vsum = _mm512_add_ps(vsum, e);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(P + r * ld_p + j), (__m256i)_mm512_cvtneps_pbh(e));
    }
    for (; j < cols; j += 16) {
      const __mmask16 mask = tail_mask(keys - j);
      const __m512 e = _mm512_maskz_mov_ps(mask, exp2_ps(_mm512_fmsub_ps(_mm512_maskz_loadu_ps(mask, s + j), vc, vm)));
      vsum = _mm512_add_ps(vsum, e);
      _mm256_mask_storeu_epi16(P + r * ld_p + j, tail_mask(cols - j), (__m256i)_mm512_cvtneps_pbh(e));
    }
    const float alpha = std::exp2(m[r] - m_new);  // 0 on the first tile (m = -inf)
    l[r] = l[r] * alpha + _mm512_reduce_add_ps(vsum);
    m[r] = m_new;
    if (alpha != 1.0f)
      for (int64_t d = 0; d < D; d += 16)
        _mm512_storeu_ps(O + r * D + d, _mm512_mul_ps(_mm512_loadu_ps(O + r * D + d), _mm512_set1_ps(alpha)));
  }
}

// Two rows' bf16 values as pair words: word n = (lo[n], hi[n]).
UPLVSM_AVX512_BF16 inline __m512i bf16_pair_words(__m512 lo, __m512 hi) {
  const __m512i wlo = _mm512_cvtepu16_epi32((__m256i)_mm512_cvtneps_pbh(lo));
  return _mm512_or_si512(wlo, _mm512_slli_epi32(_mm512_cvtepu16_epi32((__m256i)_mm512_cvtneps_pbh(hi)), 16));
}

// Row r, columns [j, j + 16) of the softmax backward: P = exp(scale S - lse) = 2^(c S - lse log2 e) with
// c = scale log2 e, dS = P (dP - delta), zero off `mask`.
UPLVSM_AVX512_BF16 inline void softmax_gradient(const float* S, const float* dP, int64_t offset, __mmask16 mask,
                                                __m512 vc, float lse, float delta, __m512& P, __m512& dS) {
  const __m512 s = _mm512_maskz_loadu_ps(mask, S + offset);
  P = _mm512_maskz_mov_ps(mask, exp2_ps(_mm512_fmsub_ps(s, vc, _mm512_set1_ps(lse * kLog2e))));
  dS = _mm512_maskz_mul_ps(mask, P, _mm512_sub_ps(_mm512_maskz_loadu_ps(mask, dP + offset), _mm512_set1_ps(delta)));
}

// The backward's element-wise middle of one tile in a single pass over row pairs: P and dS in fp32, written
// straight into the bf16 operands the three following matmuls read (P and dS in row pairs, dS row-major), all with
// leading dimension `ld`; `cols` (a multiple of 16) columns, zero at and beyond `keys` and in a missing odd row.
// S and dP are only read, so no fp32 tile is stored and read again.
UPLVSM_AVX512_BF16 void softmax_backward_to_bf16(int64_t rows, int64_t keys, int64_t cols, float scale, const float* S,
                                                 const float* dP, int64_t ld, const float* lse, const float* delta,
                                                 uint32_t* Ppairs, uint32_t* dSpairs, uint16_t* dSrows) {
  const __m512 vc = _mm512_set1_ps(scale * kLog2e);
  for (int64_t r = 0; r < rows; r += 2) {
    const bool pair_complete = r + 1 < rows;
    for (int64_t j = 0; j < cols; j += 16) {
      const __mmask16 mask = keys > j ? tail_mask(keys - j) : __mmask16(0);
      __m512 P0, dS0, P1 = _mm512_setzero_ps(), dS1 = _mm512_setzero_ps();
      softmax_gradient(S, dP, r * ld + j, mask, vc, lse[r], delta[r], P0, dS0);
      if (pair_complete) softmax_gradient(S, dP, (r + 1) * ld + j, mask, vc, lse[r + 1], delta[r + 1], P1, dS1);
      _mm512_storeu_si512(Ppairs + r / 2 * ld + j, bf16_pair_words(P0, P1));
      _mm512_storeu_si512(dSpairs + r / 2 * ld + j, bf16_pair_words(dS0, dS1));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(dSrows + r * ld + j), (__m256i)_mm512_cvtneps_pbh(dS0));
      if (pair_complete)
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(dSrows + (r + 1) * ld + j), (__m256i)_mm512_cvtneps_pbh(dS1));
    }
  }
}

// dst[d] = bf16(src[d] * mul) for d < D (a multiple of 16), rounded as c10::BFloat16 (denormals kept).
UPLVSM_AVX512 void store_row_bf16(uint16_t* dst, const float* src, int64_t D, float mul) {
  const __m512 vmul = _mm512_set1_ps(mul);
  for (int64_t d = 0; d < D; d += 16) row_simd::store16(dst + d, _mm512_mul_ps(_mm512_loadu_ps(src + d), vmul));
}

// Stores rows [0, keys) of a gradient kept transposed ([D x ld] fp32), times `mul`, as bf16 rows at row_ptr(k),
// 16 x 16 blocks at a time.
template <typename RowPtr>
UPLVSM_AVX512 void store_transposed(const float* t, int64_t ld, int64_t keys, int64_t D, float mul, RowPtr row_ptr) {
  const __m512 vmul = _mm512_set1_ps(mul);
  for (int64_t jb = 0; jb < keys; jb += 16)
    for (int64_t d0 = 0; d0 < D; d0 += 16) {
      __m512 block[16];
      for (int i = 0; i < 16; ++i) block[i] = _mm512_loadu_ps(t + (d0 + i) * ld + jb);  // ld >= round_up(keys, 16)
      transpose_16x16(block);
      for (int64_t k = 0; k < std::min<int64_t>(16, keys - jb); ++k)
        row_simd::store16(row_ptr(jb + k) + d0, _mm512_mul_ps(block[k], vmul));
    }
}

}  // namespace

void pack_head_bf16(const Problem& p, int64_t bh) {
  const int64_t D = p.D, ld_k = round_up(p.Lk, 16);
  const HeadRows k = read_through_norm(p, head_rows(p, p.k, p.sk, bh), p.Lk, p.norm.k_weight, kKnorm, nullptr);
  pack_transposed(k, p.Lk, D, ld_k, scratch<uint32_t>(kKp, D / 2 * ld_k));
  pack_row_pairs(head_rows(p, p.v, p.sv, bh), p.Lk, D, scratch<uint32_t>(kVp, (p.Lk + 1) / 2 * D));
}

void forward_rows_bf16(const Problem& p, int64_t bh, int64_t row_begin, int64_t row_end, void* o, Strides so,
                       float* lse) {
  const int64_t D = p.D, ld_k = round_up(p.Lk, 16);
  const uint32_t* Kp = scratch<uint32_t>(kKp, D / 2 * ld_k);
  const uint32_t* Vp = scratch<uint32_t>(kVp, (p.Lk + 1) / 2 * D);
  float* S = scratch<float>(kS, kBf16QueryTile * kBf16KeyTile);
  float* O = scratch<float>(kO, kBf16QueryTile * D);
  uint16_t* P = scratch<uint16_t>(kP, kBf16QueryTile * kBf16KeyTile);
  float m[kBf16QueryTile], l[kBf16QueryTile];
  for (int64_t i0 = row_begin; i0 < row_end; i0 += kBf16QueryTile) {
    const int64_t rows = std::min(kBf16QueryTile, row_end - i0);
    RowOperand Q;
    if (p.norm.active()) {
      uint16_t* normalized = scratch<uint16_t>(kQ, kBf16QueryTile * D);
      normalize_rows(head_rows(p, p.q, p.sq, bh), i0, rows, D, p.norm.q_weight, p.norm.eps, normalized, nullptr);
      Q = {words(normalized), D / 2};
    } else {
      Q = row_operand(head_rows(p, p.q, p.sq, bh), i0, rows, D, kQ);
    }
    std::fill(O, O + rows * D, 0.0f);
    std::fill(m, m + rows, -std::numeric_limits<float>::infinity());
    std::fill(l, l + rows, 0.0f);
    for (int64_t j0 = 0; j0 < p.Lk; j0 += kBf16KeyTile) {
      const int64_t keys = std::min(kBf16KeyTile, p.Lk - j0);
      gemm_bf16(rows, round_up(keys, 16), D / 2, Q.words, Q.ld, Kp + j0, ld_k, S, kBf16KeyTile, false);  // q k^T
      online_softmax_step_bf16(rows, keys, p.scale * kLog2e, S, kBf16KeyTile, P, kBf16KeyTile, m, l, O, D);
      gemm_bf16(rows, D, round_up(keys, 2) / 2, words(P), kBf16KeyTile / 2, Vp + j0 / 2 * D, D, O, D,
                true);  // O += P v
    }
    for (int64_t r = 0; r < rows; ++r) {
      store_row_bf16(static_cast<uint16_t*>(o) + head_offset(p, so, bh, i0 + r), O + r * D, D, 1.0f / l[r]);
      lse[bh * p.Lq + i0 + r] = m[r] / kLog2e + std::log(l[r]);  // m is in base-2 units
    }
  }
}

namespace {

// One head's operands of the backward, packed: q and k read through the norm when it is on (their raw rows and r
// kept for the gradient's way back through it), K and V transposed, K in row pairs, q and dO transposed in row pairs
// and as rows.
struct BackwardOperands {
  int64_t ld_k, ld_q2;
  HeadRows q_raw, k_raw;
  float *r_q = nullptr, *r_k = nullptr;
  uint32_t *Qtp, *dOtp, *Kp, *Vtp, *Krp;
  RowOperand Qrows, dOrows;
};

BackwardOperands pack_backward_operands(const Problem& p, int64_t bh, const void* dout, Strides sdo) {
  const int64_t D = p.D, Lq = p.Lq, Lk = p.Lk;
  BackwardOperands b;
  b.ld_k = round_up(Lk, 16), b.ld_q2 = round_up((Lq + 1) / 2, 16);
  b.q_raw = head_rows(p, p.q, p.sq, bh), b.k_raw = head_rows(p, p.k, p.sk, bh);
  if (p.norm.active()) b.r_q = scratch<float>(kRq, Lq), b.r_k = scratch<float>(kRk, Lk);
  const HeadRows q = read_through_norm(p, b.q_raw, Lq, p.norm.q_weight, kQnorm, b.r_q);
  const HeadRows k = read_through_norm(p, b.k_raw, Lk, p.norm.k_weight, kKnorm, b.r_k);
  pack_transposed(head_rows(p, p.v, p.sv, bh), Lk, D, b.ld_k, b.Vtp = scratch<uint32_t>(kVtp, D / 2 * b.ld_k));
  pack_transposed(k, Lk, D, b.ld_k, b.Kp = scratch<uint32_t>(kKp, D / 2 * b.ld_k));
  pack_row_pairs(k, Lk, D, b.Krp = scratch<uint32_t>(kKrp, (Lk + 1) / 2 * D));
  pack_transposed_row_pairs(q, Lq, D, b.ld_q2, b.Qtp = scratch<uint32_t>(kQtp, D * b.ld_q2));
  pack_transposed_row_pairs(head_rows(p, dout, sdo, bh), Lq, D, b.ld_q2,
                            b.dOtp = scratch<uint32_t>(kDOtp, D * b.ld_q2));
  b.Qrows = row_operand(q, 0, Lq, D, kQrows);
  b.dOrows = row_operand(head_rows(p, dout, sdo, bh), 0, Lq, D, kDOrows);
  return b;
}

uint16_t* head_row(const Problem& p, void* base, Strides s, int64_t bh, int64_t row) {
  return static_cast<uint16_t*>(base) + head_offset(p, s, bh, row);
}

// dK for keys [j0, j0 + keys) from its transposed tile (times scale), back through the norm when it is on.
void store_key_gradient(const Problem& p, int64_t bh, const BackwardOperands& b, int64_t j0, int64_t keys,
                        const float* dKt, int64_t ld, void* dk, Strides sdk) {
  if (!p.norm.active()) {
    store_transposed(dKt, ld, keys, p.D, p.scale, [&](int64_t j) { return head_row(p, dk, sdk, bh, j0 + j); });
    return;
  }
  uint16_t* g = scratch<uint16_t>(kGrows, std::max(p.Lq, ld) * p.D);  // the normalised keys' gradient
  store_transposed(dKt, ld, keys, p.D, p.scale, [&](int64_t j) { return g + j * p.D; });
  norm_backward_rows(p, bh, b.k_raw, b.r_k, p.norm.k_weight, g, j0, keys, dk, sdk, p.norm.k_weight_grad + bh * p.D);
}

// dq from its fp32 rows (times scale), back through the norm when it is on.
void store_query_gradient(const Problem& p, int64_t bh, const BackwardOperands& b, const float* dQ, void* dq,
                          Strides sdq) {
  const int64_t D = p.D;
  if (!p.norm.active()) {
    for (int64_t i = 0; i < p.Lq; ++i) store_row_bf16(head_row(p, dq, sdq, bh, i), dQ + i * D, D, p.scale);
    return;
  }
  uint16_t* g = scratch<uint16_t>(kGrows, std::max(p.Lq, kBf16BwdKeyTile) * D);
  for (int64_t i = 0; i < p.Lq; ++i) store_row_bf16(g + i * D, dQ + i * D, D, p.scale);
  norm_backward_rows(p, bh, b.q_raw, b.r_q, p.norm.q_weight, g, 0, p.Lq, dq, sdq, p.norm.q_weight_grad + bh * D);
}

}  // namespace

// dV^T and dK^T (D x keys) accumulate as A = dO^T / Q^T (pairs along query rows) times B = P / dS packed in row
// pairs, so no tile is ever transposed; dQ += dS K uses dS row-major. Gradients of the scaled scores carry `scale`.
void backward_head_bf16(const Problem& p, int64_t bh, const void* dout, Strides sdo, const float* lse,
                        const float* delta, void* dq, Strides sdq, void* dk, Strides sdk, void* dv, Strides sdv) {
  const int64_t D = p.D, Lq = p.Lq, Lk = p.Lk;
  constexpr int64_t kTq = kBf16BwdQueryTile, kTk = kBf16BwdKeyTile;
  const BackwardOperands b = pack_backward_operands(p, bh, dout, sdo);
  float* dQ = scratch<float>(kDQ, Lq * D);
  float* S = scratch<float>(kS, kTq * kTk);
  float* dP = scratch<float>(kDP, kTq * kTk);
  uint32_t* Ppairs = scratch<uint32_t>(kPpairs, kTq / 2 * kTk);
  uint32_t* dSpairs = scratch<uint32_t>(kDSpairs, kTq / 2 * kTk);
  uint16_t* dSrows = scratch<uint16_t>(kDSrows, kTq * kTk);
  float* dKt = scratch<float>(kDKt, D * kTk);
  float* dVt = scratch<float>(kDVt, D * kTk);
  std::fill(dQ, dQ + Lq * D, 0.0f);
  const float* lse_h = lse + bh * Lq;
  const float* delta_h = delta + bh * Lq;
  for (int64_t j0 = 0; j0 < Lk; j0 += kTk) {
    const int64_t keys = std::min(kTk, Lk - j0), key_pad = round_up(keys, 16);
    std::fill(dKt, dKt + D * kTk, 0.0f);
    std::fill(dVt, dVt + D * kTk, 0.0f);
    for (int64_t i0 = 0; i0 < Lq; i0 += kTq) {
      const int64_t rows = std::min(kTq, Lq - i0), row_pairs = (rows + 1) / 2;
      const RowOperand &q = b.Qrows, &dO = b.dOrows;
      gemm_bf16(rows, key_pad, D / 2, q.words + i0 * q.ld, q.ld, b.Kp + j0, b.ld_k, S, kTk, false);       // q k^T
      gemm_bf16(rows, key_pad, D / 2, dO.words + i0 * dO.ld, dO.ld, b.Vtp + j0, b.ld_k, dP, kTk, false);  // dO v^T
      softmax_backward_to_bf16(rows, keys, key_pad, p.scale, S, dP, kTk, lse_h + i0, delta_h + i0, Ppairs, dSpairs,
                               dSrows);
      gemm_bf16(D, key_pad, row_pairs, b.dOtp + i0 / 2, b.ld_q2, Ppairs, kTk, dVt, kTk, true);  // dV^T += dO^T P
      gemm_bf16(D, key_pad, row_pairs, b.Qtp + i0 / 2, b.ld_q2, dSpairs, kTk, dKt, kTk, true);  // dK^T += q^T dS
      gemm_bf16(rows, D, round_up(keys, 2) / 2, words(dSrows), kTk / 2, b.Krp + j0 / 2 * D, D, dQ + i0 * D, D,
                true);  // dQ += dS k
    }
    store_key_gradient(p, bh, b, j0, keys, dKt, kTk, dk, sdk);
    store_transposed(dVt, kTk, keys, D, 1.0f, [&](int64_t j) { return head_row(p, dv, sdv, bh, j0 + j); });
  }
  store_query_gradient(p, bh, b, dQ, dq, sdq);
}

}  // namespace uplvsm::kernels::flash::detail
