// A linear layer's training step on bf16 operands (autocast training on CPU), with the weight gradient from our own
// AVX-512 BF16 product. That gradient, X^T dY over every token of the batch, is a product with a long inner
// dimension (tens of thousands of rows) and a small output (d x 4d at most at the demo size); oneDNN runs it at
// 46-63 % of the bf16 peak on the operands as a training step leaves them (out of cache), about half of a demo
// step's backward matmul time. Here it runs at 69-78 % (`WeightGradient` benchmark): each slice of rows is
// interleaved into bf16 pairs while the next slice is prefetched, and the slices' sums are added in a fixed order.
#pragma once
#include <torch/torch.h>

namespace uplvsm::model {

// Whether `bf16_linear` serves these operands (CPU, AVX-512 BF16, bf16 input and weight, the weight's input width
// a multiple of 16, at most 512 x 512 weights: at the paper's widths oneDNN is as fast); elsewhere callers use ATen's
// linear. UPLVSM_WEIGHT_GRADIENT=aten forces ATen (benchmarks).
bool bf16_linear_applies(const torch::Tensor& input, const torch::Tensor& weight);

// ATen's linear(input, weight, bias) on bf16 operands, as one autograd node: the same output and input gradient
// (the same ATen calls), the bias gradient the same sum, and the weight gradient X^T dY from
// `weight_gradient_bf16` — fp32 sums rounded once to bf16, as oneDNN's, in another order.
torch::Tensor bf16_linear(const torch::Tensor& input, const torch::Tensor& weight, const torch::Tensor& bias);

// dY^T X for dY [K x O] and X [K x I] (bf16, contiguous, I a multiple of 16): [O x I], summed in fp32 over fixed
// slices of the K rows whatever the thread count (up to 16 slices, O x I floats each), rounded once to bf16.
torch::Tensor weight_gradient_bf16(const torch::Tensor& grad_output, const torch::Tensor& input);

}  // namespace uplvsm::model
