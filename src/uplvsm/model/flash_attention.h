// Fused attention for CPU as a LibTorch autograd function: softmax(q k^T / sqrt(d)) v with the flash kernels of
// flash_attention_kernels.h (O(L) memory, fp32 accumulation), forward and backward. `attention()` in
// transformer.h picks it when it applies; everything else (CUDA, other head sizes, CPUs without AVX-512) keeps the
// unfused LibTorch path.
#pragma once
#include <torch/torch.h>

namespace uplvsm::model {

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

}  // namespace uplvsm::model
