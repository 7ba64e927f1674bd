// The model family's norms, with the official state_dict names (`weight`, `bias`): the blocks' pre-LayerNorm and the
// per-head RMSNorm of QK-Norm. Both compute through kernels/ops.h.
#pragma once
#include <torch/torch.h>

namespace uplvsm::model {

// LayerNorm with an optional bias (torch >= 2.1's LayerNorm(bias=False) keeps only `weight`).
struct LayerNormImpl : torch::nn::Module {
  LayerNormImpl(int64_t dim, double eps, bool bias);
  torch::Tensor forward(const torch::Tensor& x);
  // For a norm whose result only feeds linear layers: under bf16 autocast it may come out in bf16, the dtype those
  // layers cast to (kernels/ops.h: layer_norm's into_linear).
  torch::Tensor forward_into_linear(const torch::Tensor& x);
  torch::Tensor weight, bias;
  int64_t dim;
  double eps;
};
TORCH_MODULE(LayerNorm);

// y = x_fp32 * rsqrt(mean(x_fp32^2) + eps), cast back, times weight (official RMSNorm).
struct RMSNormImpl : torch::nn::Module {
  RMSNormImpl(int64_t dim, double eps);
  torch::Tensor forward(const torch::Tensor& x);
  torch::Tensor weight;
  double eps;
};
TORCH_MODULE(RMSNorm);

}  // namespace uplvsm::model
