// Mixed precision as `torch.autocast(device_type, dtype=torch.bfloat16)` for a C++ scope: matmuls, linear layers and
// convolutions run in bf16 while weights stay fp32 (master weights) and autocast's fp32 ops (softmax, norms, losses)
// stay fp32. Works on CPU and CUDA; on a CPU it pays only with native bf16 dot products (bf16_autocast_pays).
#pragma once
#include <torch/torch.h>

#include <string>

namespace uplvsm {

// Whether an autocast region for `device`'s type is open on this thread (recomputations re-enter the same state).
bool autocast_active(torch::Device device);

// The lower-precision dtype autocast uses on `device`'s type (bf16 in every region AutocastGuard opens).
at::ScalarType autocast_dtype(torch::Device device);

// The official `use_tf32` (torch.backends.cuda.matmul.allow_tf32 and cudnn.allow_tf32, process-wide): on a CUDA
// `device` both switches are set to `on` and true is returned; on any other device nothing changes (TF32 is a CUDA
// tensor-core mode) and false is returned.
bool set_cuda_tf32(torch::Device device, bool on);

// Whether bf16 autocast makes `device` faster: CUDA, or a CPU whose kernels may use AVX-512 BF16 (core/cpu_isa).
// Without it LibTorch's bf16 matmuls run in emulation (about 40x slower than fp32 for 4096 x 768 x 768 on an AVX2
// EPYC) and accumulate in bf16.
bool bf16_autocast_pays(torch::Device device);

// `requested` where bf16 pays; elsewhere false (fp32), said once per process in a warning that names the reason.
// UPLVSM_FORCE_BF16=1 keeps bf16 anyway (numerics checks).
bool use_bf16_autocast(bool requested, torch::Device device);

class AutocastGuard {
 public:
  // Inactive (a no-op) when `enabled` is false.
  AutocastGuard(torch::Device device, bool enabled);
  ~AutocastGuard();
  AutocastGuard(const AutocastGuard&) = delete;
  AutocastGuard& operator=(const AutocastGuard&) = delete;

 private:
  bool active_ = false, cuda_ = false, previous_enabled_ = false;
  at::ScalarType previous_dtype_ = at::kFloat;
};

// A user's bf16 request as a scope: autocast where it pays (use_bf16_autocast), fp32 elsewhere.
class Bf16Autocast : public AutocastGuard {
 public:
  Bf16Autocast(torch::Device device, bool requested) : AutocastGuard(device, use_bf16_autocast(requested, device)) {}
};

}  // namespace uplvsm
