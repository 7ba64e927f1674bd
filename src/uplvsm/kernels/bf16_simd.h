// Internal to the fused row-wise kernels (qk_norm.cpp, layer_norm_to_bf16.cpp, gelu.cpp) and the one-pass AdamW step
// (train/optimizer.cpp): AVX-512 loads and stores of 16 fp32 or bf16 features, rounding to bf16 exactly as
// c10::BFloat16 does. Files that include it compile their AVX-512 functions with UPLVSM_ROW_AVX512 and call them only
// when isa_at_least(Isa::Avx512) (core/cpu_isa.h).
#pragma once
#include <c10/util/BFloat16.h>
#include <immintrin.h>

#include <type_traits>

#include "uplvsm/core/cpu_isa.h"

// GCC 12's AVX-512 intrinsics (reductions, extracts, shuffles, masked forms) start from _mm512_undefined_*, which
// -Wmaybe-uninitialized (and, once inlined into loops, -Wuninitialized) misreads in every file using these helpers.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

#define UPLVSM_ROW_AVX512 __attribute__((target("avx512f,avx512bw,avx512vl,avx512dq")))

namespace uplvsm::kernels::row_simd {

// The lanes of a 16-wide block that `remaining` elements fill (all 16 when at least 16 remain).
UPLVSM_ROW_AVX512 inline __mmask16 tail_mask(int64_t remaining) {
  return remaining >= 16 ? __mmask16(0xFFFF) : __mmask16((1u << remaining) - 1);
}

template <typename T>
UPLVSM_ROW_AVX512 inline __m512 load16(const T* p) {
  if constexpr (std::is_same_v<T, float>) {
    return _mm512_loadu_ps(p);
  } else {
    const __m512i wide = _mm512_cvtepu16_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(p)));
    return _mm512_castsi512_ps(_mm512_slli_epi32(wide, 16));
  }
}

// fp32 -> fp32 bits rounded to bf16's as c10::BFloat16 rounds (to nearest even, NaN to 0x7FC0), low half zero.
UPLVSM_ROW_AVX512 inline __m512i rounded_bits(__m512 v) {
  const __m512i bits = _mm512_castps_si512(v);
  const __m512i lsb = _mm512_and_si512(_mm512_srli_epi32(bits, 16), _mm512_set1_epi32(1));
  const __m512i rounded = _mm512_and_si512(_mm512_add_epi32(bits, _mm512_add_epi32(lsb, _mm512_set1_epi32(0x7FFF))),
                                           _mm512_set1_epi32(static_cast<int>(0xFFFF0000u)));
  const __mmask16 nan = _mm512_cmp_ps_mask(v, v, _CMP_UNORD_Q);
  return _mm512_mask_mov_epi32(rounded, nan, _mm512_set1_epi32(0x7FC00000));
}

// fp32 -> bf16 bits as c10::BFloat16 rounds, with integer instructions only.
UPLVSM_ROW_AVX512 inline __m256i to_bf16_bits_integer(__m512 v) {
  return _mm512_cvtepi32_epi16(_mm512_srli_epi32(rounded_bits(v), 16));
}

// fp32 -> bf16 bits as c10::BFloat16 rounds: to nearest even, NaN to 0x7FC0, denormals kept. vcvtneps2bf16 rounds
// the same way but flushes denormals and keeps a NaN's sign and payload, so it serves only blocks without either
// (one vfpclassps decides); the integer rounding serves the rest and CPUs without AVX-512 BF16. The instruction is
// written as assembly so that these helpers keep their AVX-512F target (GCC will not inline a function of a wider
// target into them).
UPLVSM_ROW_AVX512 inline __m256i to_bf16_bits(__m512 v) {
  constexpr int kNanOrDenormal = 0x01 | 0x20 | 0x80;  // vfpclassps classes: quiet NaN, denormal, signalling NaN
  if (isa_at_least(Isa::Avx512Bf16) && _mm512_fpclass_ps_mask(v, kNanOrDenormal) == 0) {
    __m256i bits;
    asm("vcvtneps2bf16 %g1, %t0" : "=v"(bits) : "v"(v));
    return bits;
  }
  return to_bf16_bits_integer(v);
}

// v rounded to T and back to fp32.
template <typename T>
UPLVSM_ROW_AVX512 inline __m512 round16(__m512 v) {
  if constexpr (std::is_same_v<T, float>) {
    return v;
  } else {
    return _mm512_castsi512_ps(rounded_bits(v));
  }
}

template <typename T>
UPLVSM_ROW_AVX512 inline void store16(T* p, __m512 v) {
  if constexpr (std::is_same_v<T, float>) {
    _mm512_storeu_ps(p, v);
  } else {
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(p), to_bf16_bits(v));
  }
}

}  // namespace uplvsm::kernels::row_simd
