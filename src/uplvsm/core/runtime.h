// Process-wide compute setup: threads, the OpenMP wait policy, BLAS detection and device selection.
#pragma once
#include <torch/torch.h>
#include <string>

namespace uplvsm {

struct RuntimeInfo {
  std::string torch_version;
  std::string blas_library;  // path of the loaded libblas.so.3 (or "unknown")
  std::string blas_config;   // openblas_get_config() when OpenBLAS is loaded
  int threads = 0;
  int interop_threads = 0;
  std::string omp_wait_policy;
  bool cuda_available = false;
  int cuda_devices = 0;
};

// libgomp reads OMP_WAIT_POLICY when it is loaded, before main(); so when the variable is unset we set it to
// PASSIVE and re-exec the same binary once. Spinning workers would otherwise burn the cores the data loader needs.
void ensure_passive_openmp(char** argv);

// Threads default to the cores this process may run on (sched affinity); 0 means "all of them".
void init_runtime(int threads = 0);
int available_cores();

RuntimeInfo runtime_info();
std::string format_runtime_info(const RuntimeInfo& info);

// "cpu", "cuda", "cuda:N" or "auto" (cuda when available); a clear error otherwise.
torch::Device parse_device(const std::string& name);

}  // namespace uplvsm
