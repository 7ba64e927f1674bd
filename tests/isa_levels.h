// Tests parameterised over the kernels' ISA levels (core/cpu_isa): each TEST_P of a suite deriving from AtIsaLevel
// runs once per level with the kernels capped there, and a level this CPU lacks is skipped with its name.
#pragma once
#include <gtest/gtest.h>

#include <optional>
#include <string>

#include "uplvsm/core/cpu_isa.h"

namespace uplvsm::test {

class AtIsaLevel : public ::testing::TestWithParam<Isa> {
 protected:
  void SetUp() override {
    if (GetParam() > detected_isa())
      GTEST_SKIP() << "this CPU lacks " << isa_name(GetParam()) << " (it has " << isa_name(detected_isa()) << ")";
    cap_.emplace(GetParam());
  }
  void TearDown() override { cap_.reset(); }

 private:
  std::optional<ScopedMaxIsa> cap_;
};

inline std::string isa_test_name(const ::testing::TestParamInfo<Isa>& info) {
  std::string name = isa_name(info.param);
  for (auto& c : name)
    if (c == '-') c = '_';
  return name;
}

}  // namespace uplvsm::test

// Every level, scalar to AVX-512 BF16, for the suite `suite` (a subclass of uplvsm::test::AtIsaLevel).
#define UPLVSM_AT_EVERY_ISA_LEVEL(suite)                                                                       \
  INSTANTIATE_TEST_SUITE_P(                                                                                    \
      Isa, suite,                                                                                              \
      ::testing::Values(uplvsm::Isa::Scalar, uplvsm::Isa::Avx2, uplvsm::Isa::Avx512, uplvsm::Isa::Avx512Bf16), \
      uplvsm::test::isa_test_name)
