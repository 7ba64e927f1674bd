// The dispatch of ops.h: each op's plain LibTorch reference, and the choice of the fused CPU kernel where it computes
// the same (layer_norm_to_bf16.h, qk_norm.h, flash_attention.h).
#include "uplvsm/kernels/ops.h"

#include <cmath>

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/cpu_isa.h"
#include "uplvsm/kernels/bf16_linear.h"
#include "uplvsm/kernels/flash_attention.h"
#include "uplvsm/kernels/gelu.h"
#include "uplvsm/kernels/layer_norm_to_bf16.h"
#include "uplvsm/kernels/qk_norm.h"

namespace uplvsm::kernels {

torch::Tensor layer_norm(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias, double eps,
                         bool into_linear) {
  if (into_linear && autocast_active(x.device()) && layer_norm_to_bf16_fuses(x, weight, bias))
    return layer_norm_to_bf16(x, weight, bias, eps);
  return torch::layer_norm(x, {x.size(-1)}, weight, bias, eps);
}

std::pair<torch::Tensor, torch::Tensor> add_layer_norm(const torch::Tensor& x, const torch::Tensor& branch,
                                                       const torch::Tensor& weight, const torch::Tensor& bias,
                                                       double eps, bool into_linear) {
  if (into_linear && autocast_active(x.device()) && add_layer_norm_to_bf16_fuses(x, branch, weight, bias))
    return add_layer_norm_to_bf16(x, branch, weight, bias, eps);
  auto h = x + branch;
  return {h, layer_norm(h, weight, bias, eps, into_linear)};
}

torch::Tensor rms_norm(const torch::Tensor& x, const torch::Tensor& weight, double eps, torch::ScalarType out_dtype) {
  return qk_norm(x, weight, eps, out_dtype);  // fused where qk_norm_fuses, else qk_norm_unfused (the reference)
}

torch::ScalarType qk_norm_output_dtype(const torch::Tensor& projected, int64_t d_head) {
  // The dtype `attention` casts to under autocast (bf16 for the fused kernel) saves that pass; otherwise RMSNorm's
  // own result dtype (that of x times an fp32 weight).
  const auto device = projected.device();
  if (autocast_active(device) && fused_attention_applies(device, torch::kBFloat16, d_head)) return torch::kBFloat16;
  return torch::promote_types(projected.scalar_type(), torch::kFloat32);
}

namespace {

// softmax(q k^T / sqrt(d_head)) v in the operands' dtype, materialising the scores (LibTorch's own ops).
torch::Tensor attention_reference(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
#if TORCH_VERSION_MAJOR >= 2
  return at::scaled_dot_product_attention(q, k, v);
#else
  const double scale = 1.0 / std::sqrt(static_cast<double>(q.size(-1)));
  auto scores = torch::matmul(q, k.transpose(-2, -1)).mul_(scale);
  return torch::matmul(torch::softmax(scores, -1), v);
#endif
}

// Attention under CPU autocast where the fused kernel does not run, with the fused kernel's numerics: q, k and v
// rounded to bf16, every product and sum in fp32, the result rounded once to bf16. Autocast's own matmuls would
// round the scores and accumulate P v in bf16 (LibTorch 1.13 on CPUs without AVX-512 BF16: 1.2-1.3 % error where one
// rounding gives at most 0.39 %), and run several times slower there than fp32.
torch::Tensor attention_bf16_operands_fp32_sums(const torch::Tensor& q, const torch::Tensor& k,
                                                const torch::Tensor& v) {
  const c10::impl::ExcludeDispatchKeyGuard no_autocast(c10::DispatchKey::AutocastCPU);
  auto rounded = [](const torch::Tensor& t) { return t.to(torch::kBFloat16).to(torch::kFloat32); };
  return attention_reference(rounded(q), rounded(k), rounded(v)).to(torch::kBFloat16);
}

}  // namespace

torch::Tensor attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  // Under autocast the fused kernel takes bf16 operands (as autocast's matmuls would) and accumulates in fp32.
  const bool autocast = autocast_active(q.device());
  const auto dtype = autocast ? torch::kBFloat16 : q.scalar_type();
  if (q.dim() == 4 && fused_attention_applies(q.device(), dtype, q.size(3)))
    return fused_attention(q.to(dtype), k.to(dtype), v.to(dtype));
  if (autocast && q.device().is_cpu()) return attention_bf16_operands_fp32_sums(q, k, v);
  return attention_reference(q, k, v);
}

namespace {

// The reference: split the heads, QK-Norm q (of the kept rows) and k, attend.
torch::Tensor qk_norm_attention_reference(const torch::Tensor& qkv, int64_t heads, const torch::Tensor& q_weight,
                                          double q_eps, const torch::Tensor& k_weight, double k_eps, int64_t row_start,
                                          int64_t row_count) {
  const int64_t B = qkv.size(0), L = qkv.size(1), d_head = qkv.size(2) / (3 * heads);
  // unbind, not three selects: its backward stacks the three gradients in one pass instead of zero-filling and
  // copying into the whole qkv gradient three times.
  auto split = qkv.view({B, L, 3, heads, d_head}).permute({2, 0, 3, 1, 4}).unbind(0);  // 3 x [B, heads, L, d_head]
  auto q = row_count == L ? split[0] : split[0].narrow(2, row_start, row_count), k = split[1];
  if (q_weight.defined()) {
    const auto dtype = qk_norm_output_dtype(qkv, d_head);
    q = rms_norm(q, q_weight, q_eps, dtype);
    k = rms_norm(k, k_weight, k_eps, dtype);
  }
  return attention(q, k, split[2]);
}

}  // namespace

torch::Tensor qk_norm_attention(const torch::Tensor& qkv, int64_t heads, const torch::Tensor& q_weight, double q_eps,
                                const torch::Tensor& k_weight, double k_eps, int64_t row_start, int64_t row_count) {
  const int64_t B = qkv.size(0), L = qkv.size(1), d_head = qkv.size(2) / (3 * heads);
  if (row_count < 0) row_start = 0, row_count = L;
  TORCH_CHECK(row_start >= 0 && row_start + row_count <= L, "qk_norm_attention: rows [", row_start, ", ",
              row_start + row_count, ") outside a sequence of ", L);
  // The fused node computes the same bits (under autocast, or fp32 without gradients) without storing q and k
  // normalised or three separate gradients (flash_attention.h).
  const bool fused_dtype = autocast_active(qkv.device()) || qkv.scalar_type() == torch::kFloat32;
  torch::Tensor o;  // [B, heads, rows, d_head]
  if (q_weight.defined() && row_count > 0 && q_eps == k_eps && fused_dtype &&
      fused_qk_norm_attention_applies(qkv, q_weight, d_head))
    o = fused_qk_norm_attention(qkv, heads, q_weight, k_weight, q_eps, row_start, row_count);
  else
    o = qk_norm_attention_reference(qkv, heads, q_weight, q_eps, k_weight, k_eps, row_start, row_count);
  return o.transpose(1, 2).reshape({B, row_count, heads * d_head});
}

namespace {
std::string vector_name() { return isa_at_least(Isa::Avx512) ? "AVX-512" : "AVX2"; }
// The row kernels of QK-Norm and LayerNorm: AVX-512 or scalar loops.
std::string vector_or_scalar() { return isa_at_least(Isa::Avx512) ? "AVX-512" : "scalar"; }
}  // namespace

std::string describe_kernel_paths() {
  const auto cap = max_isa();
  const torch::Device cpu(torch::kCPU);
  const auto f32 = torch::TensorOptions().dtype(torch::kFloat32), bf16 = f32.dtype(torch::kBFloat16);
  const auto row = torch::zeros({1, 64}, f32), weight = torch::ones({64}, f32);
  const auto bf16_row = torch::zeros({16, 64}, bf16), bf16_weight = torch::zeros({64, 64}, bf16);
  const bool fused_bf16 = fused_attention_applies(cpu, torch::kBFloat16, 64);
  std::string s = "ISA " + isa_name(active_isa()) + " (CPU " + isa_name(detected_isa()) +
                  (cap ? ", UPLVSM_MAX_ISA=" + isa_name(*cap) : std::string()) + "): attention fp32 ";
  s += fused_attention_applies(cpu, torch::kFloat32, 64) ? "fused " + vector_name() : std::string("LibTorch");
  s += fused_bf16 ? ", bf16 fused AVX-512 BF16" : ", bf16 LibTorch fp32 sums of bf16 operands";
  s += "; QK-Norm ";
  s += qk_norm_fuses(row, weight) ? "fused " + vector_or_scalar() : std::string("LibTorch");
  s += "; layer norm to bf16 ";
  s += layer_norm_to_bf16_fuses(row, weight, torch::Tensor()) ? "fused " + vector_or_scalar() : std::string("LibTorch");
  s += "; GELU bf16 ";
  s += gelu_fuses(bf16_row) ? "fused AVX-512" : "LibTorch in fp32, rounded once";
  s += "; linear bf16 weight gradient ";
  s += bf16_linear_applies(bf16_row, bf16_weight) ? "ours AVX-512 BF16" : "LibTorch";
  s += "; AdamW ";
  s += adamw_update_fuses(weight, weight, weight, weight) ? "fused AVX-512" : "LibTorch";
  s += "; --amp bf16 ";
  s += bf16_autocast_pays(cpu) ? "bf16" : "runs fp32 (no native bf16 dot product)";
  return s;
}

}  // namespace uplvsm::kernels
