// Test entry point: the same runtime set-up as the binary (threads, passive OpenMP), then GoogleTest.
#include <gtest/gtest.h>

#include <cstdio>

#include "uplvsm/core/runtime.h"
#include "uplvsm/kernels/ops.h"

int main(int argc, char** argv) {
  uplvsm::ensure_passive_openmp(argv);
  uplvsm::init_runtime();
  std::printf("kernels: %s\n", uplvsm::kernels::describe_kernel_paths().c_str());
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
