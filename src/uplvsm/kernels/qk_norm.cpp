#include "uplvsm/kernels/qk_norm.h"

#include <ATen/Parallel.h>
#include <ATen/record_function.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "uplvsm/kernels/bf16_simd.h"
#include "uplvsm/kernels/block_sums.h"
#include "uplvsm/kernels/qk_norm_rows.h"

namespace uplvsm::kernels {
namespace {

using torch::autograd::AutogradContext;
using torch::autograd::variable_list;

// Rows of the weight gradient's partial sums: fixed blocks summed in order, so the result does not depend on the
// number of threads (training runs are deterministic).
constexpr int64_t kRowsPerBlock = 256;

bool forced_unfused() {
  static const bool unfused = [] {
    const char* env = std::getenv("UPLVSM_QK_NORM");
    return env && std::strcmp(env, "unfused") == 0;
  }();
  return unfused;
}

// Element offsets of x's rows viewed as [rows, D] (x's last dimension contiguous, any outer strides), walked as an
// odometer from any row: a division per row and dimension would cost as much as the row's arithmetic.
class RowWalker {
 public:
  static constexpr int64_t kMaxOuterDims = 8;

  RowWalker(const torch::Tensor& x, int64_t row) : dims_(x.dim() - 1) {
    for (int64_t d = dims_ - 1; d >= 0; --d) {
      size_[d] = x.size(d), stride_[d] = x.stride(d);
      index_[d] = row % size_[d], row /= size_[d];
      offset_ += index_[d] * stride_[d];
    }
  }

  // This row's offset; moves to the next row.
  int64_t next() {
    const int64_t current = offset_;
    for (int64_t d = dims_ - 1; d >= 0; --d) {
      offset_ += stride_[d];
      if (++index_[d] < size_[d]) break;
      offset_ -= index_[d] * stride_[d];
      index_[d] = 0;
    }
    return current;
  }

 private:
  int64_t dims_;
  int64_t size_[kMaxOuterDims] = {}, stride_[kMaxOuterDims] = {}, index_[kMaxOuterDims] = {};
  int64_t offset_ = 0;
};

template <typename T>
T round_to(float v) {
  return static_cast<T>(v);
}

// out = ((x * r) rounded to T) * w rounded to TOut, r = 1 / sqrt(mean(x^2) + eps), per row; r kept for backward.
template <typename T, typename TOut>
void forward_rows(const T* x, RowWalker walk, const float* w, float eps, int64_t D, int64_t begin, int64_t end,
                  TOut* out, float* r) {
  for (int64_t row = begin; row < end; ++row) {
    const T* xr = x + walk.next();
    float sum_sq = 0.0f;
    for (int64_t j = 0; j < D; ++j) sum_sq += static_cast<float>(xr[j]) * static_cast<float>(xr[j]);
    const float rr = 1.0f / std::sqrt(sum_sq / static_cast<float>(D) + eps);
    r[row] = rr;
    TOut* o = out + row * D;
    for (int64_t j = 0; j < D; ++j)
      o[j] = round_to<TOut>(static_cast<float>(round_to<T>(static_cast<float>(xr[j]) * rr)) * w[j]);
  }
}

// The autograd chain of the unfused forward, per row: g_y = (g_out * w) rounded to T; g_x = g_y r + x (2 / D)
// (-0.5 g_r r^3) with g_r = sum(g_y x), rounded to T; the weight gradient adds g_out * y (y rounded to T).
template <typename T, typename TOut>
void backward_rows(const T* x, RowWalker walk, const float* w, const float* r, const TOut* gout, int64_t D,
                   int64_t begin, int64_t end, T* gx, float* gw) {
  for (int64_t row = begin; row < end; ++row) {
    const T* xr = x + walk.next();
    const TOut* g = gout + row * D;
    const float rr = r[row];
    float g_r = 0.0f;
    for (int64_t j = 0; j < D; ++j) {
      const float gy = static_cast<float>(round_to<T>(static_cast<float>(g[j]) * w[j]));
      g_r += gy * static_cast<float>(xr[j]);
      if (gw) gw[j] += static_cast<float>(g[j]) * static_cast<float>(round_to<T>(static_cast<float>(xr[j]) * rr));
    }
    const float g_sq = -0.5f * g_r * (rr * rr * rr) / static_cast<float>(D);
    T* o = gx + row * D;
    for (int64_t j = 0; j < D; ++j) {
      const float gy = static_cast<float>(round_to<T>(static_cast<float>(g[j]) * w[j]));
      o[j] = round_to<T>(gy * rr + g_sq * (2.0f * static_cast<float>(xr[j])));
    }
  }
}

// ---- AVX-512 rows (D a multiple of 16): the same arithmetic, 16 features at a time ----

using qk_norm_rows::kGroup;

template <typename T, typename TOut>
UPLVSM_ROW_AVX512 void forward_rows_avx512(const T* x, RowWalker walk, const float* w, float eps, int64_t D,
                                           int64_t begin, int64_t end, TOut* out, float* r) {
  const T* xr[kGroup];  // entries [0, n) of each group are set and read
  TOut* o[kGroup];
  for (int64_t row0 = begin; row0 < end; row0 += kGroup) {
    const int64_t n = std::min(kGroup, end - row0);
    for (int64_t i = 0; i < n; ++i) xr[i] = x + walk.next(), o[i] = out + (row0 + i) * D;
    qk_norm_rows::forward_group<T, TOut>(xr, n, w, eps, D, o, r + row0);
  }
}

template <typename T, typename TOut>
UPLVSM_ROW_AVX512 void backward_rows_avx512(const T* x, RowWalker walk, const float* w, const float* r,
                                            const TOut* gout, int64_t D, int64_t begin, int64_t end, T* gx, float* gw) {
  const T* xr[kGroup];  // entries [0, n) of each group are set and read
  const TOut* g[kGroup];
  T* gxr[kGroup];
  for (int64_t row0 = begin; row0 < end; row0 += kGroup) {
    const int64_t n = std::min(kGroup, end - row0);
    for (int64_t i = 0; i < n; ++i) xr[i] = x + walk.next(), g[i] = gout + (row0 + i) * D, gxr[i] = gx + (row0 + i) * D;
    qk_norm_rows::backward_group<T, TOut>(xr, g, n, w, r + row0, D, gxr, gw);
  }
}

// Calls f with (T*)-typed null pointers selecting x's and the output's element types.
template <typename F>
void dispatch_types(torch::ScalarType in, torch::ScalarType out, F&& f) {
  using BF = c10::BFloat16;
  if (in == torch::kFloat32 && out == torch::kFloat32)
    return f(static_cast<float*>(nullptr), static_cast<float*>(nullptr));
  if (in == torch::kFloat32) return f(static_cast<float*>(nullptr), static_cast<BF*>(nullptr));
  if (out == torch::kFloat32) return f(static_cast<BF*>(nullptr), static_cast<float*>(nullptr));
  return f(static_cast<BF*>(nullptr), static_cast<BF*>(nullptr));
}

struct QKNormFunction : torch::autograd::Function<QKNormFunction> {
  static torch::Tensor forward(AutogradContext* ctx, torch::Tensor x, torch::Tensor weight, double eps,
                               int64_t out_dtype) {
    RECORD_FUNCTION("uplvsm::qk_norm", std::vector<c10::IValue>());
    const int64_t D = x.size(-1), rows = x.numel() / D;
    const auto out_type = static_cast<torch::ScalarType>(out_dtype);
    auto out = torch::empty(x.sizes(), x.options().dtype(out_type));
    auto r = torch::empty({rows}, x.options().dtype(torch::kFloat32));
    dispatch_types(x.scalar_type(), out_type, [&](auto* in_tag, auto* out_tag) {
      using T = std::remove_pointer_t<decltype(in_tag)>;
      using TOut = std::remove_pointer_t<decltype(out_tag)>;
      at::parallel_for(0, rows, 64, [&](int64_t begin, int64_t end) {
        const auto rows_kernel =
            D % 16 == 0 && isa_at_least(Isa::Avx512) ? forward_rows_avx512<T, TOut> : forward_rows<T, TOut>;
        rows_kernel(x.data_ptr<T>(), RowWalker(x, begin), weight.data_ptr<float>(), static_cast<float>(eps), D, begin,
                    end, out.data_ptr<TOut>(), r.data_ptr<float>());
      });
    });
    ctx->save_for_backward({x, weight, r});
    return out;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grad_outputs) {
    RECORD_FUNCTION("uplvsm::qk_norm_backward", std::vector<c10::IValue>());
    auto saved = ctx->get_saved_variables();
    const auto &x = saved[0], &weight = saved[1], &r = saved[2];
    const auto gout = grad_outputs[0].contiguous();
    const int64_t D = x.size(-1), rows = x.numel() / D, blocks = (rows + kRowsPerBlock - 1) / kRowsPerBlock;
    const bool weight_grad = ctx->needs_input_grad(1);
    auto gx = torch::empty(x.sizes(), x.options().memory_format(torch::MemoryFormat::Contiguous));
    auto partial = torch::zeros({weight_grad ? blocks : 0, D}, weight.options());
    dispatch_types(x.scalar_type(), gout.scalar_type(), [&](auto* in_tag, auto* out_tag) {
      using T = std::remove_pointer_t<decltype(in_tag)>;
      using TOut = std::remove_pointer_t<decltype(out_tag)>;
      const auto rows_kernel =
          D % 16 == 0 && isa_at_least(Isa::Avx512) ? backward_rows_avx512<T, TOut> : backward_rows<T, TOut>;
      at::parallel_for(0, blocks, 1, [&](int64_t block_begin, int64_t block_end) {
        for (int64_t b = block_begin; b < block_end; ++b)
          rows_kernel(x.data_ptr<T>(), RowWalker(x, b * kRowsPerBlock), weight.data_ptr<float>(), r.data_ptr<float>(),
                      gout.data_ptr<TOut>(), D, b * kRowsPerBlock, std::min(rows, (b + 1) * kRowsPerBlock),
                      gx.data_ptr<T>(), weight_grad ? partial.data_ptr<float>() + b * D : nullptr);
      });
    });
    return {gx, weight_grad ? sum_blocks_in_order(partial) : torch::Tensor(), torch::Tensor(), torch::Tensor()};
  }
};

}  // namespace

bool qk_norm_fuses(const torch::Tensor& x, const torch::Tensor& weight) {
  const auto t = x.scalar_type();
  return !forced_unfused() && x.device().is_cpu() && (t == torch::kFloat32 || t == torch::kBFloat16) && x.dim() >= 1 &&
         x.dim() <= RowWalker::kMaxOuterDims + 1 && x.size(-1) > 0 && x.stride(-1) == 1 &&
         weight.scalar_type() == torch::kFloat32 && weight.is_contiguous() && weight.dim() == 1 &&
         weight.size(0) == x.size(-1) && weight.device().is_cpu();
}

torch::Tensor qk_norm_unfused(const torch::Tensor& x, const torch::Tensor& weight, double eps,
                              torch::ScalarType out_dtype) {
  auto x32 = x.to(torch::kFloat32);
  auto y = x32 * torch::rsqrt(x32.pow(2).mean(-1, true) + eps);
  return (y.to(x.scalar_type()) * weight).to(out_dtype);
}

torch::Tensor qk_norm(const torch::Tensor& x, const torch::Tensor& weight, double eps, torch::ScalarType out_dtype) {
  const bool out_supported = out_dtype == torch::kFloat32 || out_dtype == torch::kBFloat16;
  if (!out_supported || !qk_norm_fuses(x, weight)) return qk_norm_unfused(x, weight, eps, out_dtype);
  return QKNormFunction::apply(x, weight, eps, static_cast<int64_t>(out_dtype));
}

}  // namespace uplvsm::kernels
