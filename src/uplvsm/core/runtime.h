// Process-wide compute setup: threads, the OpenMP wait policy, BLAS detection and device selection.
#pragma once
#include <torch/torch.h>

#include <optional>
#include <string>

namespace uplvsm {

struct RuntimeInfo {
  std::string torch_version;
  std::string blas_library;  // path of the loaded libblas.so.3 (or "unknown")
  std::string blas_config;   // openblas_get_config() when OpenBLAS is loaded
  std::string blas_core;     // openblas_get_corename(): the kernel family OpenBLAS picked for this CPU
  int threads = 0;
  int interop_threads = 0;
  std::string omp_wait_policy;
  std::string allocator;     // how large host allocations are served (init_runtime tunes glibc malloc)
  std::string cpu_features;  // the vector extensions the kernels choose by ("AVX2+FMA AVX-512 ...", or "-")
  bool cuda_available = false;
  int cuda_devices = 0;
};

// libgomp reads OMP_WAIT_POLICY when it is loaded, before main(); so when the variable is unset we set it to
// PASSIVE and re-exec the same binary once. Spinning workers would otherwise burn the cores the data loader needs.
// The same re-exec fixes OpenBLAS's kernel choice (see openblas_core_for_cpu). UPLVSM_NO_REEXEC=1 disables both.
void ensure_passive_openmp(char** argv);

// Debian's OpenBLAS 0.3.21 (DYNAMIC_ARCH) does not recognise CPUs newer than it (Sapphire Rapids, Zen 4, ...) and
// falls back to its SSE3 "Prescott" kernels, ~3x slower than the AVX-512 ones. Given the core OpenBLAS picked and
// what the CPU supports, this names the core to ask for through OPENBLAS_CORETYPE, or "" when the pick is fine.
struct CpuFeatures {
  bool avx2_fma = false;
  bool avx512 = false;  // F, VL, BW and DQ: what OpenBLAS's SkylakeX kernels use
  bool avx512_bf16 = false;
  bool amx_bf16 = false;  // AMX tiles with BF16 products, enabled by the OS (XCR0): oneDNN's fastest bf16 matmuls
};
CpuFeatures detect_cpu_features();
std::string describe_cpu_features(const CpuFeatures& cpu);  // "AVX2+FMA AVX-512 AVX-512-BF16 AMX-BF16", or "-"
std::string openblas_core_for_cpu(const std::string& picked_core, const CpuFeatures& cpu);

// Threads default to the cores this process may run on (sched affinity); 0 means "all of them".
void init_runtime(int threads = 0);
int available_cores();

// What a host process that loads the library (the Python module, on import) gets by default: the allocator
// thresholds of init_runtime and, when set_threads, intra-op threads = available_cores(). Inter-op threads are left
// alone: a host may set those only once, before any parallel work, and that choice is its own.
void init_library_runtime(bool set_threads);

// The OpenBLAS kernel family best suited to this CPU (Cooperlake with AVX-512 BF16, SkylakeX with AVX-512, Haswell
// with AVX2 + FMA), or "" when none of those applies.
std::string best_openblas_core(const CpuFeatures& cpu);

// When the loaded BLAS computes slower than this CPU allows, a warning naming the cause and the fix (the environment
// variable to unset or set before the process starts); "" when it is fine. Cases: the reference BLAS; OpenBLAS on
// fallback kernels it picked itself (a CPU newer than it); OpenBLAS held to weaker kernels by OPENBLAS_CORETYPE
// (env_coretype, nullptr when unset). A binary can re-exec to fix the second case (ensure_passive_openmp); a Python
// process cannot, once torch has loaded OpenBLAS.
std::string blas_warning(const RuntimeInfo& info, const CpuFeatures& cpu, const char* env_coretype);

RuntimeInfo runtime_info();
std::string format_runtime_info(const RuntimeInfo& info);

// Memory a new allocation on `device` can get, and where the figure comes from: MemAvailable of /proc/meminfo for
// the CPU, the free memory the CUDA runtime reports for a GPU. Empty when it cannot be told (no /proc, no runtime).
struct AvailableMemory {
  int64_t bytes = 0;
  std::string source;  // "MemAvailable in /proc/meminfo", "free memory of cuda:0"
};
std::optional<AvailableMemory> available_memory(const torch::Device& device);

// "12.3 GiB", "512.0 MiB": byte counts for messages.
std::string format_bytes(double bytes);

// "cpu", "cuda", "cuda:N" or "auto" (cuda when available); a clear error otherwise.
torch::Device parse_device(const std::string& name);

}  // namespace uplvsm
