// The operations the paper's modules (model/) are written in, and the optimiser's update (train/). Each op computes
// what its plain LibTorch reference computes (written out in ops.cpp, or the *_unfused functions of the kernel
// headers); where device, dtype, shape and autograd allow, a fused CPU kernel of this folder computes the same bits
// faster (tests/kernels compare the two in fp32 and bf16, and on CUDA where present). This is the one kernels/ header
// included outside kernels/: which path runs is decided here, never by a caller.
#pragma once
#include <torch/torch.h>

#include <memory>
#include <string>
#include <utility>

namespace uplvsm::kernels {

// LayerNorm over the last dimension (bias may be undefined). into_linear: the result only feeds linear layers, so
// under bf16 autocast it may come out in bf16, the dtype those layers cast to, from one fused pass.
torch::Tensor layer_norm(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias, double eps,
                         bool into_linear = false);

// A residual add and the norm after it: {h = x + branch, layer_norm(h, weight, bias, eps, into_linear)}, one pass
// forward and backward where it fuses.
std::pair<torch::Tensor, torch::Tensor> add_layer_norm(const torch::Tensor& x, const torch::Tensor& branch,
                                                       const torch::Tensor& weight, const torch::Tensor& bias,
                                                       double eps, bool into_linear = false);

// The official RMSNorm: (x_fp32 * rsqrt(mean(x_fp32^2, -1) + eps)) cast to x's dtype, times weight, cast to out_dtype.
torch::Tensor rms_norm(const torch::Tensor& x, const torch::Tensor& weight, double eps, torch::ScalarType out_dtype);

// softmax(q k^T / sqrt(d_head)) v for q, k, v [B, heads, L, d_head]; under autocast the operands are bf16.
torch::Tensor attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v);

// The dtype in which QK-Norm hands q and k to `attention` for a projection `projected` of head size d_head.
torch::ScalarType qk_norm_output_dtype(const torch::Tensor& projected, int64_t d_head);

// Attention from one projection qkv [B, L, 3 heads d_head] (q | k | v, each head-major), with QK-Norm:
// attention(rms_norm(q, q_weight, q_eps), rms_norm(k, k_weight, k_eps), v) for the query rows [row_start, row_start
// + row_count) (row_count < 0: all rows; every row is a key and value); undefined norm weights: no QK-Norm.
// Returns the heads merged, [B, rows, heads d_head].
torch::Tensor qk_norm_attention(const torch::Tensor& qkv, int64_t heads, const torch::Tensor& q_weight, double q_eps,
                                const torch::Tensor& k_weight, double k_eps, int64_t row_start = 0,
                                int64_t row_count = -1);

// GELU, the exact (erf) form.
torch::Tensor gelu(const torch::Tensor& x);

// y = x W^T + b, what ATen's linear (PyTorch's nn.Linear) computes. `cache` holds a bf16 copy of the weights for
// bf16 inference, made once and remade when they change (a module keeps one per linear layer).
class LinearWeightCache;
std::shared_ptr<LinearWeightCache> make_linear_weight_cache();
torch::Tensor linear(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias,
                     LinearWeightCache& cache);

// AdamW's update of one parameter at (1-based) step `step`, in place: exactly what torch::optim::AdamW::step does to
// it (every intermediate rounded to fp32 as its tensor ops round), in one pass. Only where adamw_update_fuses: fp32
// contiguous CPU tensors of one size, a CPU with AVX-512 (train/optimizer.cpp falls back to AdamW::step elsewhere).
bool adamw_update_fuses(const torch::Tensor& p, const torch::Tensor& grad, const torch::Tensor& exp_avg,
                        const torch::Tensor& exp_avg_sq);
void adamw_update(const torch::Tensor& p, const torch::Tensor& grad, const torch::Tensor& exp_avg,
                  const torch::Tensor& exp_avg_sq, int64_t step, const torch::optim::AdamWOptions& options);

// One line naming the path each op takes on the CPU at the active ISA level (core/cpu_isa) for the model's shapes
// (head width 64, widths multiples of 16), with the overrides of the environment applied: for logs and `uplvsm info`.
std::string describe_kernel_paths();

}  // namespace uplvsm::kernels
