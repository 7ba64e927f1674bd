#include "uplvsm/core/runtime.h"

#include "uplvsm/core/cpu_isa.h"

#include <dlfcn.h>
#include <link.h>
#include <malloc.h>
#include <sched.h>
#include <unistd.h>

#include <cctype>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

namespace uplvsm {

namespace {
std::string loaded_openblas_core() {
  using GetCorename = char* (*)();
  auto fn = reinterpret_cast<GetCorename>(dlsym(RTLD_DEFAULT, "openblas_get_corename"));
  return fn ? std::string(fn()) : std::string();
}
}  // namespace

CpuFeatures detect_cpu_features() {
  // The CPU's own levels (core/cpu_isa), whatever cap UPLVSM_MAX_ISA sets on the kernels: OpenBLAS's choice and the
  // report are about the machine.
  const Isa isa = detected_isa();
  CpuFeatures cpu;
  cpu.avx2_fma = isa >= Isa::Avx2;
  cpu.avx512 = isa >= Isa::Avx512;
  cpu.avx512_bf16 = isa >= Isa::Avx512Bf16;
  cpu.amx_bf16 = cpu_has_amx_bf16();
  return cpu;
}

std::string openblas_core_for_cpu(const std::string& picked_core, const CpuFeatures& cpu) {
  // Only a fallback pick is overridden: a core OpenBLAS recognised (Haswell, SkylakeX, Zen, ...) is its choice.
  std::string core = picked_core;
  for (auto& c : core) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (core != "prescott" && core != "core2" && core != "nehalem" && core != "sandybridge") return "";
  if (cpu.avx512_bf16) return "Cooperlake";
  if (cpu.avx512) return "SkylakeX";
  if (cpu.avx2_fma && core != "sandybridge") return "Haswell";
  return "";
}

void ensure_passive_openmp(char** argv) {
  if (std::getenv("UPLVSM_NO_REEXEC") != nullptr) return;
  bool reexec = false;
  if (std::getenv("OMP_WAIT_POLICY") == nullptr) {
    setenv("OMP_WAIT_POLICY", "PASSIVE", 1);
    reexec = true;
  }
  // A user's OPENBLAS_CORETYPE always wins; OpenBLAS reads it only when it is loaded, hence the re-exec.
  if (std::getenv("OPENBLAS_CORETYPE") == nullptr) {
    std::string core = openblas_core_for_cpu(loaded_openblas_core(), detect_cpu_features());
    if (!core.empty()) {
      setenv("OPENBLAS_CORETYPE", core.c_str(), 1);
      reexec = true;
    }
  }
  if (!reexec) return;
  setenv("UPLVSM_NO_REEXEC", "1", 1);
  execv("/proc/self/exe", argv);
  // execv only returns on failure: carry on with the current set-up rather than refuse to run.
}

int available_cores() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) == 0) {
    int n = CPU_COUNT(&set);
    if (n > 0) return n;
  }
  long n = sysconf(_SC_NPROCESSORS_ONLN);
  return n > 0 ? static_cast<int>(n) : 1;
}

namespace {
// glibc serves blocks above its mmap threshold (at most 32 MiB by its dynamic rule) with fresh mmap()s and unmaps
// them on free, so every op producing a large tensor (the decoder's MLP activations are 47-94 MiB) page-faults its
// whole output again: measured 90 ms instead of 1.2 ms for one fp32 add of 3840x3072. Keeping such blocks in the
// heap (and not trimming it) removes that. A user's MALLOC_*_ / GLIBC_TUNABLES settings win.
std::string tune_allocator() {
  if (std::getenv("MALLOC_MMAP_THRESHOLD_") || std::getenv("MALLOC_TRIM_THRESHOLD_") ||
      (std::getenv("GLIBC_TUNABLES") && std::strstr(std::getenv("GLIBC_TUNABLES"), "threshold")))
    return "glibc malloc, thresholds from the environment";
  constexpr int kThreshold = 1 << 30;
  if (mallopt(M_MMAP_THRESHOLD, kThreshold) == 1 && mallopt(M_TRIM_THRESHOLD, kThreshold) == 1)
    return "glibc malloc, blocks < 1 GiB reused from the heap (mmap/trim thresholds 1 GiB)";
  return "glibc malloc, default thresholds (mallopt refused)";
}

// What init_runtime did to the allocator, for `uplvsm info` (tuned once per process; reading it changes nothing).
std::string& allocator_description() {
  static std::string description = "glibc malloc, default thresholds";
  return description;
}
void configure_allocator() {
  static const bool done = (allocator_description() = tune_allocator(), true);
  (void)done;
}
}  // namespace

void init_runtime(int threads) {
  configure_allocator();
  int n = threads > 0 ? threads : available_cores();
  torch::set_num_threads(n);
  static bool interop_set = false;  // LibTorch allows setting inter-op threads only once per process
  if (!interop_set) {
    try {
      torch::set_num_interop_threads(1);
    } catch (const c10::Error&) {
    }
    interop_set = true;
  }
}

void init_library_runtime(bool set_threads) {
  configure_allocator();
  if (set_threads) torch::set_num_threads(available_cores());
}

std::string describe_cpu_features(const CpuFeatures& cpu) {
  std::string names;
  for (auto [has, name] : {std::pair{cpu.avx2_fma, "AVX2+FMA"}, std::pair{cpu.avx512, "AVX-512"},
                           std::pair{cpu.avx512_bf16, "AVX-512-BF16"}, std::pair{cpu.amx_bf16, "AMX-BF16"}})
    if (has) names += (names.empty() ? "" : " ") + std::string(name);
  return names.empty() ? "-" : names;
}

std::string best_openblas_core(const CpuFeatures& cpu) {
  if (cpu.avx512_bf16) return "Cooperlake";
  if (cpu.avx512) return "SkylakeX";
  if (cpu.avx2_fma) return "Haswell";
  return "";
}

namespace {
// How wide OpenBLAS's kernels of a core family are: 0 SSE fallbacks, 1 AVX2, 2 AVX-512, 3 AVX-512 BF16; -1 unknown.
int core_tier(std::string core) {
  for (auto& c : core) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const char* name :
       {"prescott", "core2", "nehalem", "sandybridge", "katmai", "coppermine", "northwood", "atom", "penryn",
        "dunnington", "opteron", "barcelona", "bobcat", "bulldozer", "piledriver", "steamroller", "excavator"})
    if (core == name) return 0;
  if (core == "haswell" || core == "zen" || core == "skylake") return 1;
  if (core == "skylakex") return 2;
  if (core == "cooperlake" || core == "sapphirerapids") return 3;
  return -1;
}
}  // namespace

std::string blas_warning(const RuntimeInfo& info, const CpuFeatures& cpu, const char* env_coretype) {
  if (info.blas_config.empty() && info.blas_library.find("/blas/") != std::string::npos)
    return fmt::format(
        "LibTorch runs on the reference BLAS ({}), about 60x slower than OpenBLAS: import uplvsm "
        "before torch (it loads OpenBLAS first), or point libblas.so.3 at OpenBLAS (update-alternatives "
        "--config libblas.so.3-x86_64-linux-gnu)",
        info.blas_library);
  const std::string best = best_openblas_core(cpu);
  const int loaded = core_tier(info.blas_core), wanted = core_tier(best);
  if (info.blas_core.empty() || best.empty() || loaded < 0 || loaded >= wanted) return "";
  if (env_coretype != nullptr)
    return fmt::format(
        "OPENBLAS_CORETYPE={} in the environment holds OpenBLAS to its {} kernels, slower than this "
        "CPU allows: start Python without it (unset OPENBLAS_CORETYPE) or with OPENBLAS_CORETYPE={}",
        env_coretype, info.blas_core, best);
  if (loaded == 0)
    return fmt::format(
        "OpenBLAS does not recognise this CPU and runs its {} fallback kernels (about 3x slower): "
        "start Python with OPENBLAS_CORETYPE={} (the uplvsm binary sets it itself)",
        info.blas_core, best);
  return fmt::format("OpenBLAS runs its {} kernels, narrower than this CPU's: start Python with OPENBLAS_CORETYPE={}",
                     info.blas_core, best);
}

namespace {
int find_blas(struct dl_phdr_info* info, size_t, void* data) {
  auto* out = static_cast<std::string*>(data);
  if (info->dlpi_name && std::strstr(info->dlpi_name, "libblas.so")) *out = info->dlpi_name;
  if (info->dlpi_name && out->empty() && std::strstr(info->dlpi_name, "openblas")) *out = info->dlpi_name;
  return 0;
}
}  // namespace

RuntimeInfo runtime_info() {
  RuntimeInfo info;
  info.torch_version = fmt::format("{}.{}.{}", TORCH_VERSION_MAJOR, TORCH_VERSION_MINOR, TORCH_VERSION_PATCH);
  dl_iterate_phdr(find_blas, &info.blas_library);
  if (info.blas_library.empty()) info.blas_library = "unknown";
  using GetConfig = char* (*)();
  if (auto fn = reinterpret_cast<GetConfig>(dlsym(RTLD_DEFAULT, "openblas_get_config"))) info.blas_config = fn();
  info.blas_core = loaded_openblas_core();
  info.threads = torch::get_num_threads();
  info.interop_threads = torch::get_num_interop_threads();
  const char* policy = std::getenv("OMP_WAIT_POLICY");
  info.omp_wait_policy = policy ? policy : "(unset: libgomp default, active spinning)";
  info.allocator = allocator_description();  // reporting only: the Python module's runtime_info() changes nothing
  info.cpu_features = describe_cpu_features(detect_cpu_features());
  info.cuda_available = torch::cuda::is_available();
  info.cuda_devices = info.cuda_available ? static_cast<int>(torch::cuda::device_count()) : 0;
  return info;
}

std::string format_runtime_info(const RuntimeInfo& info) {
  std::string blas_kind =
      info.blas_config.empty()
          ? (info.blas_library.find("/blas/") != std::string::npos ? "reference BLAS (slow!)" : "unknown BLAS")
          : "OpenBLAS";
  return fmt::format(
      "LibTorch     {}\nBLAS         {} ({})\nBLAS config  {}\nBLAS core    {}{}\nthreads      {} intra-op, {} "
      "inter-op "
      "(cores available: {})\nCPU          {}\nOpenMP wait  {}\nallocator    {}\nCUDA         {}\n",
      info.torch_version, blas_kind, info.blas_library, info.blas_config.empty() ? "-" : info.blas_config,
      info.blas_core.empty() ? "-" : info.blas_core,
      std::getenv("OPENBLAS_CORETYPE") ? fmt::format(" (OPENBLAS_CORETYPE={})", std::getenv("OPENBLAS_CORETYPE")) : "",
      info.threads, info.interop_threads, available_cores(), info.cpu_features.empty() ? "-" : info.cpu_features,
      info.omp_wait_policy, info.allocator,
      info.cuda_available ? fmt::format("available, {} device(s)", info.cuda_devices) : "not available");
}

std::optional<AvailableMemory> available_memory(const torch::Device& device) {
  if (device.is_cpu()) {
    std::ifstream in("/proc/meminfo");
    std::string line;
    while (std::getline(in, line)) {
      std::istringstream fields(line);
      std::string key;
      int64_t kib = 0;
      if (fields >> key >> kib && key == "MemAvailable:")
        return AvailableMemory{kib * 1024, "MemAvailable in /proc/meminfo"};
    }
    return std::nullopt;
  }
  if (!device.is_cuda()) return std::nullopt;
  // Looked up at run time: the CUDA runtime is loaded only by a CUDA LibTorch, and this file builds against both.
  using MemGetInfo = int (*)(size_t*, size_t*);
  using GetSetDevice = int (*)(int*);
  using SetDevice = int (*)(int);
  auto mem_get_info = reinterpret_cast<MemGetInfo>(dlsym(RTLD_DEFAULT, "cudaMemGetInfo"));
  auto get_device = reinterpret_cast<GetSetDevice>(dlsym(RTLD_DEFAULT, "cudaGetDevice"));
  auto set_device = reinterpret_cast<SetDevice>(dlsym(RTLD_DEFAULT, "cudaSetDevice"));
  if (!mem_get_info || !get_device || !set_device) return std::nullopt;
  int previous = 0;
  if (get_device(&previous) != 0) return std::nullopt;
  const int index = device.has_index() ? device.index() : previous;
  size_t free = 0, total = 0;
  const bool ok = set_device(index) == 0 && mem_get_info(&free, &total) == 0;
  set_device(previous);
  if (!ok) return std::nullopt;
  return AvailableMemory{static_cast<int64_t>(free), fmt::format("free memory of cuda:{}", index)};
}

std::string format_bytes(double bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB"};
  int u = 0;
  while (bytes >= 1024.0 && u < 5) bytes /= 1024.0, ++u;
  return fmt::format("{:.1f} {}", bytes, units[u]);
}

torch::Device parse_device(const std::string& name) {
  if (name == "auto") return torch::cuda::is_available() ? torch::Device(torch::kCUDA, 0) : torch::Device(torch::kCPU);
  if (name == "cpu") return torch::Device(torch::kCPU);
  if (name.rfind("cuda", 0) == 0) {
    if (!torch::cuda::is_available())
      throw std::runtime_error("--device " + name +
                               ": this LibTorch build has no CUDA device available "
                               "(build against a CUDA LibTorch via CMAKE_PREFIX_PATH, or use --device cpu)");
    try {
      return torch::Device(name);
    } catch (const c10::Error&) {
    }
  }
  throw std::runtime_error("--device: expected cpu, cuda, cuda:N or auto, got '" + name + "'");
}

}  // namespace uplvsm
