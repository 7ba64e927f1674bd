#include "uplvsm/core/autocast.h"

#include <ATen/Context.h>
#include <ATen/autocast_mode.h>

#include <spdlog/spdlog.h>

#include <cstdlib>
#include <cstring>
#include <mutex>
#include <stdexcept>

#include "uplvsm/core/cpu_isa.h"

namespace uplvsm {
namespace {

// LibTorch 2.4 replaced the per-device setters with device-type arguments (the old ones are deprecated there).
#if TORCH_VERSION_MAJOR > 2 || (TORCH_VERSION_MAJOR == 2 && TORCH_VERSION_MINOR >= 4)
bool is_enabled_on(bool cuda) { return at::autocast::is_autocast_enabled(cuda ? at::kCUDA : at::kCPU); }
void set_enabled_on(bool cuda, bool on) { at::autocast::set_autocast_enabled(cuda ? at::kCUDA : at::kCPU, on); }
at::ScalarType dtype_on(bool cuda) { return at::autocast::get_autocast_dtype(cuda ? at::kCUDA : at::kCPU); }
void set_dtype_on(bool cuda, at::ScalarType t) { at::autocast::set_autocast_dtype(cuda ? at::kCUDA : at::kCPU, t); }
#else
bool is_enabled_on(bool cuda) { return cuda ? at::autocast::is_enabled() : at::autocast::is_cpu_enabled(); }
void set_enabled_on(bool cuda, bool on) { cuda ? at::autocast::set_enabled(on) : at::autocast::set_cpu_enabled(on); }
at::ScalarType dtype_on(bool cuda) {
  return cuda ? at::autocast::get_autocast_gpu_dtype() : at::autocast::get_autocast_cpu_dtype();
}
void set_dtype_on(bool cuda, at::ScalarType t) {
  cuda ? at::autocast::set_autocast_gpu_dtype(t) : at::autocast::set_autocast_cpu_dtype(t);
}
#endif

}  // namespace

bool set_cuda_tf32(torch::Device device, bool on) {
  if (!device.is_cuda()) return false;
  at::globalContext().setAllowTF32CuBLAS(on);
  at::globalContext().setAllowTF32CuDNN(on);
  return true;
}

bool bf16_autocast_pays(torch::Device device) { return !device.is_cpu() || isa_at_least(Isa::Avx512Bf16); }

bool use_bf16_autocast(bool requested, torch::Device device) {
  if (!requested || bf16_autocast_pays(device)) return requested;
  const char* force = std::getenv("UPLVSM_FORCE_BF16");
  if (force != nullptr && std::strcmp(force, "1") == 0) return true;
  static std::once_flag said;
  std::call_once(said, [] {
    spdlog::warn(
        "bf16 autocast asked for, running fp32: this CPU's kernels have no native bf16 dot product (need AVX-512 "
        "BF16; here {}), where LibTorch's bf16 matmuls are many times slower than fp32 and sum in bf16. "
        "UPLVSM_FORCE_BF16=1 runs bf16 anyway",
        isa_name(active_isa()));
  });
  return false;
}

bool autocast_active(torch::Device device) { return is_enabled_on(device.is_cuda()); }

at::ScalarType autocast_dtype(torch::Device device) { return dtype_on(device.is_cuda()); }

AutocastGuard::AutocastGuard(torch::Device device, bool enabled) {
  if (!enabled) return;
  active_ = true;
  cuda_ = device.is_cuda();
  previous_enabled_ = is_enabled_on(cuda_);
  previous_dtype_ = dtype_on(cuda_);
  set_enabled_on(cuda_, true);
  set_dtype_on(cuda_, at::kBFloat16);
  at::autocast::increment_nesting();
}

AutocastGuard::~AutocastGuard() {
  if (!active_) return;
  // The cache of bf16 weight copies lives as long as the outermost autocast region, as in Python.
  if (at::autocast::decrement_nesting() == 0) at::autocast::clear_cache();
  set_enabled_on(cuda_, previous_enabled_);
  set_dtype_on(cuda_, previous_dtype_);
}

}  // namespace uplvsm
