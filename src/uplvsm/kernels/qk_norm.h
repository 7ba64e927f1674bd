// QK-Norm (the transformer's per-head RMSNorm of queries and keys) fused into one pass per row on the CPU, forward
// and backward. The unfused chain (RMSNormImpl::forward, then the cast to the attention operands' dtype) is seven
// element-wise passes over q and k and, under bf16 autocast, four casts; this computes the same roundings in one.
#pragma once
#include <torch/torch.h>

namespace uplvsm::kernels {

// Whether `qk_norm` runs fused for this input (CPU, fp32 or bf16 x with a contiguous last dimension, fp32 weight);
// elsewhere it computes the unfused chain. UPLVSM_QK_NORM=unfused forces the unfused chain (benchmarks, tests).
bool qk_norm_fuses(const torch::Tensor& x, const torch::Tensor& weight);

// ((x_fp32 * rsqrt(mean(x_fp32^2, -1) + eps)) cast to x's dtype) * weight, cast to `out_dtype`: exactly
// RMSNormImpl::forward(x).to(out_dtype), values and gradients (x and weight), as one autograd node. x is
// [..., d_head]; the result is contiguous, of x's shape.
torch::Tensor qk_norm(const torch::Tensor& x, const torch::Tensor& weight, double eps, torch::ScalarType out_dtype);

// The unfused chain, the reference the fused kernel is tested against.
torch::Tensor qk_norm_unfused(const torch::Tensor& x, const torch::Tensor& weight, double eps,
                              torch::ScalarType out_dtype);

}  // namespace uplvsm::kernels
