#include "uplvsm/kernels/flash_attention.h"

#include <ATen/Parallel.h>
#include <ATen/record_function.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include "uplvsm/kernels/block_sums.h"
#include "uplvsm/kernels/flash_attention_kernels.h"
#include "uplvsm/kernels/qk_norm.h"

namespace uplvsm::kernels {
namespace {

using torch::autograd::AutogradContext;
using torch::autograd::variable_list;

AttentionKernel kernel_from_environment() {
  const char* env = std::getenv("UPLVSM_ATTENTION");
  return env && std::strcmp(env, "unfused") == 0 ? AttentionKernel::Unfused : AttentionKernel::Fused;
}

std::atomic<AttentionKernel>& kernel_choice() {
  static std::atomic<AttentionKernel> choice{kernel_from_environment()};
  return choice;
}

flash::Precision precision_of(const torch::Tensor& t) {
  return t.scalar_type() == torch::kBFloat16 ? flash::Precision::Bf16 : flash::Precision::Fp32;
}

flash::Strides strides_of(const torch::Tensor& t) { return {t.stride(0), t.stride(1), t.stride(2)}; }

torch::Tensor last_dim_contiguous(const torch::Tensor& t) { return t.stride(-1) == 1 ? t : t.contiguous(); }

// [B, H, L, D] view of a fresh [B, L, H, D] tensor.
torch::Tensor empty_heads_view(int64_t B, int64_t H, int64_t L, int64_t D, const torch::TensorOptions& options) {
  return torch::empty({B, L, H, D}, options).transpose(1, 2);
}

flash::Problem make_problem(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  flash::Problem p;
  p.B = q.size(0), p.H = q.size(1), p.Lq = q.size(2), p.Lk = k.size(2), p.D = q.size(3);
  p.scale = static_cast<float>(1.0 / std::sqrt(static_cast<double>(p.D)));
  p.precision = precision_of(q);
  p.q = q.data_ptr(), p.k = k.data_ptr(), p.v = v.data_ptr();
  p.sq = strides_of(q), p.sk = strides_of(k), p.sv = strides_of(v);
  return p;
}

// The backward over every (batch, head), each head's delta = rowsum(dout * o) computed right before its gradients,
// so the rows of dout it reads are still in cache when the head's operands are packed from them.
void run_backward(const flash::Problem& p, const torch::Tensor& o, const torch::Tensor& dout, const torch::Tensor& lse,
                  void* dq, flash::Strides sdq, void* dk, flash::Strides sdk, void* dv, flash::Strides sdv) {
  auto delta = torch::empty_like(lse);
  at::parallel_for(0, p.B * p.H, 1, [&](int64_t begin, int64_t end) {
    for (int64_t bh = begin; bh < end; ++bh) {
      flash::backward_delta(p, o.data_ptr(), strides_of(o), dout.data_ptr(), strides_of(dout), bh, bh + 1,
                            delta.data_ptr<float>());
      flash::backward_tasks(p, dout.data_ptr(), strides_of(dout), lse.data_ptr<float>(), delta.data_ptr<float>(), bh,
                            bh + 1, dq, sdq, dk, sdk, dv, sdv);
    }
  });
}

struct FusedAttentionFunction : torch::autograd::Function<FusedAttentionFunction> {
  static torch::Tensor forward(AutogradContext* ctx, torch::Tensor q, torch::Tensor k, torch::Tensor v) {
    RECORD_FUNCTION("uplvsm::fused_attention", std::vector<c10::IValue>());
    q = last_dim_contiguous(q), k = last_dim_contiguous(k), v = last_dim_contiguous(v);
    const auto p = make_problem(q, k, v);
    auto o = empty_heads_view(p.B, p.H, p.Lq, p.D, q.options());
    auto lse = torch::empty({p.B, p.H, p.Lq}, q.options().dtype(torch::kFloat32));
    at::parallel_for(0, flash::forward_task_count(p), 1, [&](int64_t begin, int64_t end) {
      flash::forward_tasks(p, begin, end, o.data_ptr(), strides_of(o), lse.data_ptr<float>());
    });
    ctx->save_for_backward({q, k, v, o, lse});
    return o;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grad_outputs) {
    RECORD_FUNCTION("uplvsm::fused_attention_backward", std::vector<c10::IValue>());
    auto saved = ctx->get_saved_variables();
    const auto &q = saved[0], &k = saved[1], &v = saved[2], &o = saved[3], &lse = saved[4];
    auto dout = last_dim_contiguous(grad_outputs[0].to(q.scalar_type()));
    const auto p = make_problem(q, k, v);
    auto dq = empty_heads_view(p.B, p.H, p.Lq, p.D, q.options());
    auto dk = empty_heads_view(p.B, p.H, p.Lk, p.D, k.options());
    auto dv = empty_heads_view(p.B, p.H, p.Lk, p.D, v.options());
    run_backward(p, o, dout, lse, dq.data_ptr(), strides_of(dq), dk.data_ptr(), strides_of(dk), dv.data_ptr(),
                 strides_of(dv));
    return {dq, dk, dv};
  }
};

// The attention problem of a qkv projection [B, L, 3 H D]: q rows [q_start, q_start + q_count), k and v all rows.
flash::Problem qkv_problem(const torch::Tensor& qkv, int64_t H, int64_t q_start, int64_t q_count) {
  flash::Problem p;
  const int64_t HD = qkv.size(2) / 3;
  p.B = qkv.size(0), p.H = H, p.Lq = q_count, p.Lk = qkv.size(1), p.D = HD / H;
  p.scale = static_cast<float>(1.0 / std::sqrt(static_cast<double>(p.D)));
  p.precision = precision_of(qkv);
  const auto* base = static_cast<const char*>(qkv.data_ptr());
  const int64_t bytes = qkv.element_size();
  p.q = base + q_start * qkv.stride(1) * bytes, p.k = base + HD * bytes, p.v = base + 2 * HD * bytes;
  p.sq = p.sk = p.sv = {qkv.stride(0), p.D, qkv.stride(1)};
  return p;
}

struct FusedQKNormAttentionFunction : torch::autograd::Function<FusedQKNormAttentionFunction> {
  static torch::Tensor forward(AutogradContext* ctx, torch::Tensor qkv, torch::Tensor q_weight, torch::Tensor k_weight,
                               double eps, int64_t heads, int64_t q_start, int64_t q_count) {
    RECORD_FUNCTION("uplvsm::fused_qk_norm_attention", std::vector<c10::IValue>());
    auto p = qkv_problem(qkv, heads, q_start, q_count);
    p.norm = {q_weight.data_ptr<float>(), k_weight.data_ptr<float>(), static_cast<float>(eps)};
    auto o = empty_heads_view(p.B, p.H, p.Lq, p.D, qkv.options());
    auto lse = torch::empty({p.B, p.H, p.Lq}, qkv.options().dtype(torch::kFloat32));
    at::parallel_for(0, flash::forward_task_count(p), 1, [&](int64_t begin, int64_t end) {
      flash::forward_tasks(p, begin, end, o.data_ptr(), strides_of(o), lse.data_ptr<float>());
    });
    ctx->save_for_backward({qkv, q_weight, k_weight, o, lse});
    ctx->saved_data["eps"] = eps, ctx->saved_data["heads"] = heads;
    ctx->saved_data["q_start"] = q_start, ctx->saved_data["q_count"] = q_count;
    return o;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grad_outputs) {
    RECORD_FUNCTION("uplvsm::fused_qk_norm_attention_backward", std::vector<c10::IValue>());
    auto saved = ctx->get_saved_variables();
    TORCH_CHECK(saved[0].scalar_type() == torch::kBFloat16,
                "fused_qk_norm_attention: the fp32 kernels apply QK-Norm in the forward only (inference)");
    const auto &qkv = saved[0], &q_weight = saved[1], &k_weight = saved[2], &o = saved[3], &lse = saved[4];
    const int64_t q_start = ctx->saved_data["q_start"].toInt(), q_count = ctx->saved_data["q_count"].toInt();
    auto dout = last_dim_contiguous(grad_outputs[0].to(torch::kBFloat16));
    auto p = qkv_problem(qkv, ctx->saved_data["heads"].toInt(), q_start, q_count);
    // Rows of q outside the queries get no gradient; every row of k and v does.
    auto dqkv = q_count == p.Lk ? torch::empty(qkv.sizes(), qkv.options()) : torch::zeros(qkv.sizes(), qkv.options());
    auto q_weight_grad = torch::zeros({p.B * p.H, p.D}, q_weight.options());
    auto k_weight_grad = torch::zeros({p.B * p.H, p.D}, k_weight.options());
    p.norm = {q_weight.data_ptr<float>(), k_weight.data_ptr<float>(),
              static_cast<float>(ctx->saved_data["eps"].toDouble()), q_weight_grad.data_ptr<float>(),
              k_weight_grad.data_ptr<float>()};
    auto* d = static_cast<c10::BFloat16*>(dqkv.data_ptr());
    const flash::Strides sd{dqkv.stride(0), p.D, dqkv.stride(1)};
    const int64_t HD = p.H * p.D;
    run_backward(p, o, dout, lse, d + q_start * dqkv.stride(1), sd, d + HD, sd, d + 2 * HD, sd);
    return {dqkv, sum_blocks_in_order(q_weight_grad), sum_blocks_in_order(k_weight_grad), {}, {}, {}, {}};
  }
};

}  // namespace

void set_attention_kernel(AttentionKernel kernel) { kernel_choice() = kernel; }
AttentionKernel attention_kernel() { return kernel_choice(); }

bool fused_attention_applies(torch::Device device, torch::ScalarType dtype, int64_t d_head) {
  if (attention_kernel() != AttentionKernel::Fused || !device.is_cpu()) return false;
  if (dtype != torch::kFloat32 && dtype != torch::kBFloat16) return false;
  return flash::flash_kernels_available(dtype == torch::kBFloat16 ? flash::Precision::Bf16 : flash::Precision::Fp32,
                                        d_head);
}

torch::Tensor fused_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  TORCH_CHECK(q.dim() == 4 && k.dim() == 4 && v.dim() == 4, "fused_attention: q, k, v must be [B, H, L, D]");
  TORCH_CHECK(q.scalar_type() == k.scalar_type() && q.scalar_type() == v.scalar_type(),
              "fused_attention: q, k, v must share one dtype");
  TORCH_CHECK(k.sizes() == v.sizes() && q.size(0) == k.size(0) && q.size(1) == k.size(1) && q.size(3) == k.size(3),
              "fused_attention: shapes q ", q.sizes(), ", k ", k.sizes(), ", v ", v.sizes(), " do not match");
  TORCH_CHECK(q.device().is_cpu() && (q.scalar_type() == torch::kFloat32 || q.scalar_type() == torch::kBFloat16) &&
                  flash::flash_kernels_available(precision_of(q), q.size(3)),
              "fused_attention: needs CPU fp32/bf16 tensors, d_head a multiple of 16 (got ", q.size(3),
              ") and kernels at AVX2 or above (bf16: AVX-512 BF16; core/cpu_isa); attention() falls back to LibTorch "
              "otherwise");
  return FusedAttentionFunction::apply(q, k, v);
}

bool fused_qk_norm_attention_applies(const torch::Tensor& qkv, const torch::Tensor& q_weight, int64_t d_head) {
  const auto t = qkv.scalar_type();
  const bool dtype_served = t == torch::kBFloat16 || (t == torch::kFloat32 && !torch::GradMode::is_enabled());
  if (qkv.dim() != 3 || !dtype_served || qkv.stride(-1) != 1 || d_head <= 0) return false;
  if (qkv.size(2) % (3 * d_head) != 0 || !fused_attention_applies(qkv.device(), t, d_head)) return false;
  if (!flash::qk_norm_on_read_available()) return false;
  return qk_norm_fuses(qkv.narrow(2, 0, d_head), q_weight);
}

torch::Tensor fused_qk_norm_attention(const torch::Tensor& qkv, int64_t heads, const torch::Tensor& q_weight,
                                      const torch::Tensor& k_weight, double eps, int64_t q_start, int64_t q_count) {
  TORCH_CHECK(heads > 0 && qkv.dim() == 3 && qkv.size(2) % (3 * heads) == 0,
              "fused_qk_norm_attention: qkv must be [B, L, 3 H D] for ", heads, " heads, got ", qkv.sizes());
  const int64_t d_head = qkv.size(2) / 3 / heads;
  TORCH_CHECK(
      fused_qk_norm_attention_applies(qkv, q_weight, d_head) && qk_norm_fuses(qkv.narrow(2, 0, d_head), k_weight),
      "fused_qk_norm_attention: needs bf16 qkv with AVX-512 BF16 (or fp32 qkv with AVX-512, gradients off), "
      "d_head a multiple of 16 (got ",
      d_head, ") and fp32 weights of size d_head");
  TORCH_CHECK(q_start >= 0 && q_count > 0 && q_start + q_count <= qkv.size(1), "fused_qk_norm_attention: query rows [",
              q_start, ", ", q_start + q_count, ") outside the ", qkv.size(1), " rows");
  return FusedQKNormAttentionFunction::apply(qkv, q_weight, k_weight, eps, heads, q_start, q_count);
}

}  // namespace uplvsm::kernels
