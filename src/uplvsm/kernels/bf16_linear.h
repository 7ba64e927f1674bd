// A linear layer's training step on bf16 operands (autocast training on CPU), with the weight gradient from our own
// AVX-512 BF16 product. That gradient, X^T dY over every token of the batch, is a product with a long inner
// dimension (tens of thousands of rows) and a small output (d x 4d at most at the demo size); on a CPU with AVX-512
// BF16 and no AMX, oneDNN runs it at 46-63 % of the bf16 peak on the operands as a training step leaves them (out of
// cache), about half of a demo step's backward matmul time. Here it runs at 69-78 % (`WeightGradient` benchmark): each
// slice of rows is interleaved into bf16 pairs while the next slice is prefetched, and the slices' sums are added in a
// fixed order.
#pragma once
#include <torch/torch.h>

#include "uplvsm/core/runtime.h"

namespace uplvsm::kernels {

// Whose weight gradient bf16 training uses. Ours is faster where oneDNN has AVX-512 BF16 only (above); on a CPU with
// AMX-BF16 oneDNN's tile kernels win (0.73-0.82 TFLOP/s against ours 0.19 on a 2-core Xeon with AMX, the
// `WeightGradient` benchmark; docs/performance.md), so there ATen's is the default. UPLVSM_WEIGHT_GRADIENT=aten or
// =ours chooses at start-up, set_weight_gradient_path later (tests, benchmarks).
enum class WeightGradientPath { Ours, Aten };
WeightGradientPath default_weight_gradient_path(const CpuFeatures& cpu);
void set_weight_gradient_path(WeightGradientPath path);
WeightGradientPath weight_gradient_path();

// Whether `bf16_linear` serves these operands (our path chosen, CPU, AVX-512 BF16, bf16 input and weight, the
// weight's input width a multiple of 16, at most 512 x 512 weights: at the paper's widths oneDNN is as fast);
// elsewhere callers use ATen's linear.
bool bf16_linear_applies(const torch::Tensor& input, const torch::Tensor& weight);

// ATen's linear(input, weight, bias) on bf16 operands, as one autograd node: the same output and input gradient
// (the same ATen calls), the bias gradient the same sum, and the weight gradient X^T dY from
// `weight_gradient_bf16` — fp32 sums rounded once to bf16, as oneDNN's, in another order.
torch::Tensor bf16_linear(const torch::Tensor& input, const torch::Tensor& weight, const torch::Tensor& bias);

// dY^T X for dY [K x O] and X [K x I] (bf16, contiguous, I a multiple of 16): [O x I], summed in fp32 over fixed
// slices of the K rows whatever the thread count (up to 16 slices, O x I floats each), rounded once to bf16.
torch::Tensor weight_gradient_bf16(const torch::Tensor& grad_output, const torch::Tensor& input);

}  // namespace uplvsm::kernels
