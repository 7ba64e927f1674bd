// Tests of model/bf16_simd (internal): the row kernels' rounding of fp32 to bf16 against c10::BFloat16 itself, bit
// for bit — on a sweep over all fp32 bit patterns, on the cases where vcvtneps2bf16 and c10 disagree (denormals,
// NaNs with a sign or payload), and on blocks that mix them with ordinary values.
#include "uplvsm/kernels/bf16_simd.h"

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <cstring>
#include <vector>

namespace {

using namespace uplvsm::model;
using namespace uplvsm::kernels;

uint16_t c10_bits(uint32_t pattern) {
  float f;
  std::memcpy(&f, &pattern, sizeof f);
  return c10::BFloat16(f).x;
}

// Each of the three roundings of one block of 16 patterns, as bf16 bits.
struct Rounded {
  std::array<uint16_t, 16> bits, integer, round_trip;
};

UPLVSM_ROW_AVX512 Rounded round_block(const uint32_t* patterns) {
  const __m512 v = _mm512_castsi512_ps(_mm512_loadu_si512(patterns));
  Rounded out;
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.bits.data()), row_simd::to_bf16_bits(v));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.integer.data()), row_simd::to_bf16_bits_integer(v));
  uint32_t back[16];
  _mm512_storeu_si512(back, _mm512_castps_si512(row_simd::round16<c10::BFloat16>(v)));
  for (int i = 0; i < 16; ++i) {
    EXPECT_EQ(back[i] & 0xFFFFu, 0u) << "round16 leaves low bits in lane " << i;
    out.round_trip[i] = static_cast<uint16_t>(back[i] >> 16);
  }
  return out;
}

// Counts the lanes where any of the three roundings differs from c10::BFloat16 (reporting the first few).
int64_t mismatches(const std::vector<uint32_t>& patterns) {
  int64_t bad = 0;
  for (size_t i = 0; i + 16 <= patterns.size(); i += 16) {
    const Rounded r = round_block(patterns.data() + i);
    for (int lane = 0; lane < 16; ++lane) {
      const uint16_t want = c10_bits(patterns[i + lane]);
      if (r.bits[lane] == want && r.integer[lane] == want && r.round_trip[lane] == want) continue;
      if (++bad <= 5)
        ADD_FAILURE() << std::hex << "pattern 0x" << patterns[i + lane] << ": c10 0x" << want << ", to_bf16_bits 0x"
                      << r.bits[lane] << ", integer 0x" << r.integer[lane] << ", round16 0x" << r.round_trip[lane];
    }
  }
  return bad;
}

TEST(Bf16Simd, RoundsEveryStrideOfTheFp32PatternsAsC10) {
  if (!isa_at_least(Isa::Avx512)) GTEST_SKIP() << "no AVX-512 at this ISA level";
  std::vector<uint32_t> patterns;
  // A prime stride walks every exponent, both signs, and low halves of every residue (ties included).
  for (uint64_t u = 0; u <= 0xFFFFFFFFull; u += 251) patterns.push_back(static_cast<uint32_t>(u));
  patterns.resize(patterns.size() / 16 * 16);
  EXPECT_EQ(mismatches(patterns), 0);
}

TEST(Bf16Simd, RoundsDenormalsNansTiesAndInfinitiesAsC10EvenAmongOrdinaryValues) {
  if (!isa_at_least(Isa::Avx512)) GTEST_SKIP() << "no AVX-512 at this ISA level";
  const std::vector<uint32_t> special = {
      0x00000000, 0x80000000, 0x00000001, 0x80000001,
      0x00008000, 0x00018000, 0x007FFFFF, 0x807FFFFF,  // zeros, denormals
      0x007F8000, 0x00800000, 0x7F800000, 0xFF800000,
      0x7F7FFFFF, 0xFF7FFFFF, 0x7F7F8000, 0x7F7F7FFF,  // infinities, max
      0x7FC00000, 0xFFC00000, 0x7F800001, 0xFF800001,
      0x7FFFFFFF, 0xFFFFFFFF, 0x7FC12345, 0x7FA00000,  // NaNs
      0x3F808000, 0x3F818000, 0x3F807FFF, 0x3F818001,
      0xBF808000, 0xBF818000, 0x3F800000, 0x40490FDB,  // ties, ordinary
  };
  std::vector<uint32_t> patterns = special;
  // Each special value alone in a block of ordinary ones, in every lane: the fast path must give way per block.
  for (uint32_t s : special)
    for (int lane = 0; lane < 16; ++lane)
      for (int i = 0; i < 16; ++i) patterns.push_back(i == lane ? s : 0x3F800000u + 0x1234u * static_cast<uint32_t>(i));
  EXPECT_EQ(mismatches(patterns), 0);
}

}  // namespace
