// GELU, the transformer MLPs' activation in its exact (erf) form, on the bf16 activations of autocast, as one
// AVX-512 pass forward and one backward. LibTorch's bf16 kernels evaluate erf with a division and Sleef's exp
// (and the backward a second exp): two of the demo step's costlier element-wise passes and ~6 % of an x224
// render. Here erf comes from Abramowitz & Stegun 7.1.28 (absolute error <= 3e-7, no exp) and the backward's
// density from one exp; both are computed in fp32 and rounded once to bf16, as LibTorch's are.
#pragma once
#include <torch/torch.h>

namespace uplvsm::kernels {

// Whether `gelu` runs fused for this input (CPU, bf16, AVX-512); elsewhere — fp32 (whose results must match the
// official code's to the last bits), CUDA — it is torch::gelu, and bf16 on a CPU below AVX-512 torch::gelu in fp32
// rounded once. UPLVSM_GELU=aten forces torch::gelu itself (benchmarks).
bool gelu_fuses(const torch::Tensor& x);

// torch::gelu(x) (approximate = "none"): the same values to within one bf16 rounding, and its gradient, as one
// autograd node. The result is contiguous, of x's shape and dtype.
torch::Tensor gelu(const torch::Tensor& x);

}  // namespace uplvsm::kernels
