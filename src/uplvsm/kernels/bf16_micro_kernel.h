// The AVX-512 BF16 register tile shared by the bf16 attention kernels (flash_attention_kernels_bf16.cpp) and the
// bf16 weight gradient (bf16_linear.cpp): C[R x 16 NV] (+)= A B with A and B in bf16 pairs (one uint32 word per two
// consecutive elements along the summed dimension) and fp32 accumulation, one `vdpbf16ps` per pair and vector.
// Callers compile it in their own translation unit and call it only where the CPU has AVX-512 BF16.
#pragma once
#include <immintrin.h>

#include <cstdint>

#define UPLVSM_AVX512_BF16_TILE __attribute__((target("avx512f,avx512bw,avx512vl,avx512dq,avx512bf16")))

namespace uplvsm::kernels::bf16_tile {

// Where A's word for output row r and pair p sits: kRowMajor at A[r * lda + p] (the attention's q rows, pairs along
// the head dimension), kPairMajor at A[p * lda + r] (the weight gradient's interleaved rows).
enum class ALayout { kRowMajor, kPairMajor };

// C[R x 16 NV] (+)= sum over pairs p < K2 of A(r, p) B(p, :), B's pair p a row of words ldb apart.
template <int R, int NV, ALayout kLayout>
UPLVSM_AVX512_BF16_TILE void micro_kernel(int64_t K2, const uint32_t* A, int64_t lda, const uint32_t* B, int64_t ldb,
                                          float* C, int64_t ldc, bool accumulate) {
  __m512 acc[R][NV];
#pragma GCC unroll 8
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) acc[r][v] = accumulate ? _mm512_loadu_ps(C + r * ldc + 16 * v) : _mm512_setzero_ps();
  for (int64_t p = 0; p < K2; ++p) {
    __m512bh b[NV];
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) b[v] = (__m512bh)_mm512_loadu_si512(B + p * ldb + 16 * v);
#pragma GCC unroll 8
    for (int r = 0; r < R; ++r) {
      const uint32_t word = kLayout == ALayout::kRowMajor ? A[r * lda + p] : A[p * lda + r];
      const __m512bh a = (__m512bh)_mm512_set1_epi32(static_cast<int>(word));
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) acc[r][v] = _mm512_dpbf16_ps(acc[r][v], a, b[v]);
    }
  }
#pragma GCC unroll 8
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) _mm512_storeu_ps(C + r * ldc + 16 * v, acc[r][v]);
}

using MicroKernel = void (*)(int64_t, const uint32_t*, int64_t, const uint32_t*, int64_t, float*, int64_t, bool);

constexpr int kMaxRows = 6;  // 6 x 4 accumulators + 4 B vectors fit the 32 zmm registers

// The kernels for 1..6 rows at NV vectors, indexed by rows - 1.
template <int NV, ALayout kLayout>
constexpr MicroKernel kernels_for_rows[kMaxRows] = {micro_kernel<1, NV, kLayout>, micro_kernel<2, NV, kLayout>,
                                                    micro_kernel<3, NV, kLayout>, micro_kernel<4, NV, kLayout>,
                                                    micro_kernel<5, NV, kLayout>, micro_kernel<6, NV, kLayout>};

// The kernel for `rows` (1..6) rows and `vectors` (1..4) vectors of 16 columns.
template <ALayout kLayout>
MicroKernel kernel_for(int64_t rows, int64_t vectors) {
  static const MicroKernel* const table[4] = {kernels_for_rows<1, kLayout>, kernels_for_rows<2, kLayout>,
                                              kernels_for_rows<3, kLayout>, kernels_for_rows<4, kLayout>};
  return table[vectors - 1][rows - 1];
}

}  // namespace uplvsm::kernels::bf16_tile
