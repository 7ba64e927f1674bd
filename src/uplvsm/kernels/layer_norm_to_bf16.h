// A transformer block's pre-norm under bf16 autocast, fused: LayerNorm computed in fp32 and rounded once to bf16,
// the dtype the linear layer after it would cast to. The unfused chain is LibTorch's fp32 layer_norm (autocast
// leaves it in fp32 on the CPU), then the linear's cast to bf16, and in backward the gradient's cast back to fp32
// before layer_norm_backward: four passes over the activations where this does two. The residual add before the
// norm can join the same pass (add_layer_norm_to_bf16).
#pragma once
#include <torch/torch.h>

namespace uplvsm::kernels {

// Whether `layer_norm_to_bf16` runs fused for this input (CPU, fp32 x with a contiguous last dimension, fp32
// weight and optional bias of x's last size); elsewhere it computes the unfused chain. UPLVSM_LAYER_NORM=unfused
// forces the unfused chain (benchmarks, tests).
bool layer_norm_to_bf16_fuses(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias);

// torch::layer_norm(x, {D}, weight, bias, eps).to(bf16): the same values up to fp32 rounding before the one
// rounding to bf16, and gradients for x (fp32), weight and bias, as one autograd node. x is [..., D]; the result
// is contiguous, of x's shape. bias may be undefined.
torch::Tensor layer_norm_to_bf16(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias,
                                 double eps);

// A residual connection and the pre-norm after it: h = x + branch (x fp32, branch bf16 or fp32 of x's shape; h fp32,
// exactly LibTorch's add) and layer_norm_to_bf16(h), in one pass forward and one backward, where the unfused chain
// adds, casts the branch, normalises, and in backward sums the two gradients of h and casts one for the branch.
// Returns {h, normalised h}; fused where add_layer_norm_to_bf16_fuses (where layer_norm_to_bf16 fuses for x and the
// branch is a CPU tensor of x's shape).
bool add_layer_norm_to_bf16_fuses(const torch::Tensor& x, const torch::Tensor& branch, const torch::Tensor& weight,
                                  const torch::Tensor& bias);
std::pair<torch::Tensor, torch::Tensor> add_layer_norm_to_bf16(const torch::Tensor& x, const torch::Tensor& branch,
                                                               const torch::Tensor& weight, const torch::Tensor& bias,
                                                               double eps);

// The unfused chains, the references the fused kernels are tested against.
torch::Tensor layer_norm_to_bf16_unfused(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias,
                                         double eps);
std::pair<torch::Tensor, torch::Tensor> add_layer_norm_to_bf16_unfused(const torch::Tensor& x,
                                                                       const torch::Tensor& branch,
                                                                       const torch::Tensor& weight,
                                                                       const torch::Tensor& bias, double eps);

}  // namespace uplvsm::kernels
