#include "uplvsm/model/flash_attention.h"

#include <ATen/Parallel.h>
#include <ATen/record_function.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include "uplvsm/model/flash_attention_kernels.h"

namespace uplvsm::model {
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
    auto delta = torch::empty_like(lse);
    auto dq = empty_heads_view(p.B, p.H, p.Lq, p.D, q.options());
    auto dk = empty_heads_view(p.B, p.H, p.Lk, p.D, k.options());
    auto dv = empty_heads_view(p.B, p.H, p.Lk, p.D, v.options());
    at::parallel_for(0, p.B * p.H, 1, [&](int64_t begin, int64_t end) {
      flash::backward_delta(p, o.data_ptr(), strides_of(o), dout.data_ptr(), strides_of(dout), begin, end,
                            delta.data_ptr<float>());
      flash::backward_tasks(p, dout.data_ptr(), strides_of(dout), lse.data_ptr<float>(), delta.data_ptr<float>(), begin,
                            end, dq.data_ptr(), strides_of(dq), dk.data_ptr(), strides_of(dk), dv.data_ptr(),
                            strides_of(dv));
    });
    return {dq, dk, dv};
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
              ") and a CPU with AVX-512 (bf16: AVX-512 BF16); attention() falls back to LibTorch otherwise");
  return FusedAttentionFunction::apply(q, k, v);
}

}  // namespace uplvsm::model
