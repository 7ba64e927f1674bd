// Test entry point: the same runtime set-up as the binary (threads, passive OpenMP), then GoogleTest.
#include <gtest/gtest.h>

#include "uplvsm/core/runtime.h"

int main(int argc, char** argv) {
  uplvsm::ensure_passive_openmp(argv);
  uplvsm::init_runtime();
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
