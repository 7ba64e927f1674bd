// Mixed precision as `torch.autocast(device_type, dtype=torch.bfloat16)` for a C++ scope: matmuls, linear layers and
// convolutions run in bf16 while weights stay fp32 (master weights) and autocast's fp32 ops (softmax, norms, losses)
// stay fp32. Works on CPU (where AVX-512 BF16 makes bf16 matmuls ~2x faster) and CUDA.
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

}  // namespace uplvsm
