// Benchmarks of uplvsm (Google Benchmark), run with the same runtime set-up as the CLI: passive OpenMP, one intra-op
// thread per available core, OpenBLAS. `uplvsm_bench --benchmark_list_tests` lists them.
#include <benchmark/benchmark.h>

#include <iostream>

#include "uplvsm/core/runtime.h"

int main(int argc, char** argv) {
  uplvsm::ensure_passive_openmp(argv);
  uplvsm::init_runtime();
  std::cerr << uplvsm::format_runtime_info(uplvsm::runtime_info()) << "\n";
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
