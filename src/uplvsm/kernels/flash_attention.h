// Fused attention for CPU as a LibTorch autograd function: softmax(q k^T / sqrt(d)) v with the flash kernels of
// flash_attention_kernels.h (O(L) memory, fp32 accumulation), forward and backward. `attention()` in
// ops.h picks it when it applies; everything else (CUDA, other head sizes, fp32 below AVX2, bf16 below AVX-512 BF16)
// keeps the unfused LibTorch path.
#pragma once
#include <torch/torch.h>

namespace uplvsm::kernels {

enum class AttentionKernel { Fused, Unfused };

// Process-wide choice (default Fused; the environment variable UPLVSM_ATTENTION=unfused overrides at start-up),
// for comparisons in tests and benchmarks.
void set_attention_kernel(AttentionKernel kernel);
AttentionKernel attention_kernel();

// Whether the fused kernel serves operands of this device, dtype and head size on this CPU.
bool fused_attention_applies(torch::Device device, torch::ScalarType dtype, int64_t d_head);

// q [B, H, Lq, D], k and v [B, H, Lk, D], one dtype (fp32 or bf16), last dimension contiguous; any other strides.
// Returns o [B, H, Lq, D] as a view of a [B, Lq, H, D] tensor, so merging the heads afterwards copies nothing.
torch::Tensor fused_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v);

// QK-Norm and attention from one projection, as one autograd node: qkv [B, L, 3 H D] (q | k | v, each head-major,
// bf16, or fp32 without gradients (inference); last dimension contiguous), queries rows [q_start, q_start +
// q_count) of it. Exactly qk_norm(q, q_weight, eps, qkv's dtype) and qk_norm(k, ...) (kernels/qk_norm) followed by
// fused_attention — the same bits, with the norm applied as the kernels read q and k and (bf16) a backward that
// writes qkv's gradient as one tensor, so neither the normalised q and k nor the three separate gradients are ever
// stored. Returns o [B, H, q_count, D] as fused_attention does. Applies where fused_qk_norm_attention_applies (fused
// kernels of that dtype on this CPU for this head size, fp32 weights of size D, the fused QK-Norm not switched off by
// UPLVSM_QK_NORM=unfused).
bool fused_qk_norm_attention_applies(const torch::Tensor& qkv, const torch::Tensor& q_weight, int64_t d_head);
torch::Tensor fused_qk_norm_attention(const torch::Tensor& qkv, int64_t heads, const torch::Tensor& q_weight,
                                      const torch::Tensor& k_weight, double eps, int64_t q_start, int64_t q_count);

}  // namespace uplvsm::kernels
