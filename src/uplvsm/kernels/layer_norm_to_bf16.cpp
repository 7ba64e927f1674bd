#include "uplvsm/kernels/layer_norm_to_bf16.h"

#include <ATen/Parallel.h>
#include <ATen/record_function.h>

#include <cmath>
#include <cstdlib>
#include <cstring>

#include "uplvsm/kernels/bf16_simd.h"
#include "uplvsm/kernels/block_sums.h"

namespace uplvsm::kernels {
namespace {

using torch::autograd::AutogradContext;
using torch::autograd::variable_list;
using BF16 = c10::BFloat16;

// Rows per block of the weight and bias gradients' partial sums: fixed blocks summed in order, so the result does
// not depend on the number of threads (training runs are deterministic).
constexpr int64_t kRowsPerBlock = 256;

bool forced_unfused() {
  static const bool unfused = [] {
    const char* env = std::getenv("UPLVSM_LAYER_NORM");
    return env && std::strcmp(env, "unfused") == 0;
  }();
  return unfused;
}

// Per row: with a residual branch, first x + branch into h (fp32, as LibTorch's add: the branch widened exactly,
// one rounding) and the rest on h; then mean and 1 / sqrt(var + eps) (biased variance, two passes over the row),
// y = (x - mean) rstd w + b rounded to bf16.
template <typename B>
void forward_rows(const float* x, const B* branch, float* h, const float* w, const float* b, float eps, int64_t D,
                  int64_t begin, int64_t end, BF16* y, float* mean, float* rstd) {
  for (int64_t row = begin; row < end; ++row) {
    const float* xr = x + row * D;
    if (branch) {
      for (int64_t j = 0; j < D; ++j) h[row * D + j] = xr[j] + static_cast<float>(branch[row * D + j]);
      xr = h + row * D;
    }
    float sum = 0.0f, sum_sq = 0.0f;
    for (int64_t j = 0; j < D; ++j) sum += xr[j];
    const float m = sum / static_cast<float>(D);
    for (int64_t j = 0; j < D; ++j) sum_sq += (xr[j] - m) * (xr[j] - m);
    const float r = 1.0f / std::sqrt(sum_sq / static_cast<float>(D) + eps);
    mean[row] = m, rstd[row] = r;
    for (int64_t j = 0; j < D; ++j) y[row * D + j] = static_cast<BF16>((xr[j] - m) * r * w[j] + (b ? b[j] : 0.0f));
  }
}

// Per row, with x_hat = (x - mean) rstd and h = g w: g_x = rstd (h - mean(h) - x_hat mean(h x_hat)), plus the
// gradient g_res that reaches x past the norm (a residual stream's) when given, also written rounded to bf16 when
// g_branch (a bf16 residual branch's gradient) is given; the weight and bias gradients add g x_hat and g.
template <typename G>
void backward_rows(const float* x, const float* w, const float* mean, const float* rstd, const G* g, const float* g_res,
                   int64_t D, int64_t begin, int64_t end, float* gx, BF16* g_branch, float* gw, float* gb) {
  for (int64_t row = begin; row < end; ++row) {
    const float *xr = x + row * D, m = mean[row], r = rstd[row];
    const G* gr = g + row * D;
    float sum_h = 0.0f, sum_hx = 0.0f;
    for (int64_t j = 0; j < D; ++j) {
      const float gj = static_cast<float>(gr[j]), x_hat = (xr[j] - m) * r, h = gj * w[j];
      sum_h += h, sum_hx += h * x_hat;
      if (gw) gw[j] += gj * x_hat;
      if (gb) gb[j] += gj;
    }
    const float a = sum_h / static_cast<float>(D), c = sum_hx / static_cast<float>(D);
    for (int64_t j = 0; j < D; ++j) {
      const float x_hat = (xr[j] - m) * r;
      float v = r * (static_cast<float>(gr[j]) * w[j] - a - x_hat * c);
      if (g_res) v += g_res[row * D + j];
      gx[row * D + j] = v;
      if (g_branch) g_branch[row * D + j] = static_cast<BF16>(v);
    }
  }
}

// ---- AVX-512 rows (D a multiple of 16): the same arithmetic, 16 features at a time ----

using row_simd::load16;
using row_simd::store16;

template <typename B>
UPLVSM_ROW_AVX512 void forward_rows_avx512(const float* x, const B* branch, float* h, const float* w, const float* b,
                                           float eps, int64_t D, int64_t begin, int64_t end, BF16* y, float* mean,
                                           float* rstd) {
  for (int64_t row = begin; row < end; ++row) {
    const float* xr = x + row * D;
    __m512 acc = _mm512_setzero_ps();
    if (branch) {
      for (int64_t j = 0; j < D; j += 16) {
        const __m512 v = _mm512_add_ps(_mm512_loadu_ps(xr + j), load16(branch + row * D + j));
        _mm512_storeu_ps(h + row * D + j, v);
        acc = _mm512_add_ps(acc, v);
      }
      xr = h + row * D;
    } else {
      for (int64_t j = 0; j < D; j += 16) acc = _mm512_add_ps(acc, _mm512_loadu_ps(xr + j));
    }
    const float m = _mm512_reduce_add_ps(acc) / static_cast<float>(D);
    const __m512 mv = _mm512_set1_ps(m);
    acc = _mm512_setzero_ps();
    for (int64_t j = 0; j < D; j += 16) {
      const __m512 c = _mm512_sub_ps(_mm512_loadu_ps(xr + j), mv);
      acc = _mm512_fmadd_ps(c, c, acc);
    }
    const float r = 1.0f / std::sqrt(_mm512_reduce_add_ps(acc) / static_cast<float>(D) + eps);
    mean[row] = m, rstd[row] = r;
    const __m512 rv = _mm512_set1_ps(r);
    for (int64_t j = 0; j < D; j += 16) {
      const __m512 x_hat = _mm512_mul_ps(_mm512_sub_ps(_mm512_loadu_ps(xr + j), mv), rv);
      const __m512 bias = b ? _mm512_loadu_ps(b + j) : _mm512_setzero_ps();
      store16(y + row * D + j, _mm512_fmadd_ps(x_hat, _mm512_loadu_ps(w + j), bias));
    }
  }
}

template <typename G>
UPLVSM_ROW_AVX512 void backward_rows_avx512(const float* x, const float* w, const float* mean, const float* rstd,
                                            const G* g, const float* g_res, int64_t D, int64_t begin, int64_t end,
                                            float* gx, BF16* g_branch, float* gw, float* gb) {
  for (int64_t row = begin; row < end; ++row) {
    const float* xr = x + row * D;
    const G* gr = g + row * D;
    const __m512 mv = _mm512_set1_ps(mean[row]), rv = _mm512_set1_ps(rstd[row]);
    __m512 sum_h = _mm512_setzero_ps(), sum_hx = _mm512_setzero_ps();
    for (int64_t j = 0; j < D; j += 16) {
      const __m512 gj = load16(gr + j), x_hat = _mm512_mul_ps(_mm512_sub_ps(_mm512_loadu_ps(xr + j), mv), rv);
      const __m512 h = _mm512_mul_ps(gj, _mm512_loadu_ps(w + j));
      sum_h = _mm512_add_ps(sum_h, h);
      sum_hx = _mm512_fmadd_ps(h, x_hat, sum_hx);
      if (gw) _mm512_storeu_ps(gw + j, _mm512_fmadd_ps(gj, x_hat, _mm512_loadu_ps(gw + j)));
      if (gb) _mm512_storeu_ps(gb + j, _mm512_add_ps(gj, _mm512_loadu_ps(gb + j)));
    }
    const __m512 a = _mm512_set1_ps(_mm512_reduce_add_ps(sum_h) / static_cast<float>(D));
    const __m512 c = _mm512_set1_ps(_mm512_reduce_add_ps(sum_hx) / static_cast<float>(D));
    for (int64_t j = 0; j < D; j += 16) {
      const __m512 x_hat = _mm512_mul_ps(_mm512_sub_ps(_mm512_loadu_ps(xr + j), mv), rv);
      const __m512 h = _mm512_mul_ps(load16(gr + j), _mm512_loadu_ps(w + j));
      __m512 v = _mm512_mul_ps(rv, _mm512_fnmadd_ps(x_hat, c, _mm512_sub_ps(h, a)));
      if (g_res) v = _mm512_add_ps(v, _mm512_loadu_ps(g_res + row * D + j));
      _mm512_storeu_ps(gx + row * D + j, v);
      if (g_branch) store16(g_branch + row * D + j, v);
    }
  }
}

bool vectorised(int64_t D) { return D % 16 == 0 && isa_at_least(Isa::Avx512); }

// An absent bias travels through the autograd function as an empty tensor (it takes no undefined inputs).
const float* data_or_null(const torch::Tensor& t) { return t.numel() > 0 ? t.data_ptr<float>() : nullptr; }

// The forward of both functions: y, with h = x + branch when a branch is given (else h is x), and each row's
// mean and rstd.
struct Normalised {
  torch::Tensor h, y, mean, rstd;
};

Normalised normalise(const torch::Tensor& x, const torch::Tensor& branch, const torch::Tensor& weight,
                     const torch::Tensor& bias, double eps) {
  const int64_t D = x.size(-1), rows = x.numel() / D;
  Normalised n{branch.defined() ? torch::empty(x.sizes(), x.options()) : x,
               torch::empty(x.sizes(), x.options().dtype(torch::kBFloat16)), torch::empty({rows}, x.options()),
               torch::empty({rows}, x.options())};
  auto run = [&](auto* branch_tag) {
    using B = std::remove_pointer_t<decltype(branch_tag)>;
    const auto rows_kernel = vectorised(D) ? forward_rows_avx512<B> : forward_rows<B>;
    at::parallel_for(0, rows, 64, [&](int64_t begin, int64_t end) {
      rows_kernel(x.data_ptr<float>(), branch.defined() ? branch.data_ptr<B>() : nullptr, n.h.data_ptr<float>(),
                  weight.data_ptr<float>(), data_or_null(bias), static_cast<float>(eps), D, begin, end,
                  n.y.data_ptr<BF16>(), n.mean.data_ptr<float>(), n.rstd.data_ptr<float>());
    });
  };
  if (branch.defined() && branch.scalar_type() == torch::kBFloat16)
    run(static_cast<BF16*>(nullptr));
  else
    run(static_cast<float*>(nullptr));
  return n;
}

// The backward of both: the gradient of the norm's input (plus g_res, the gradient reaching it past the norm, when
// defined), in fp32 and, for a bf16 residual branch, rounded to bf16; the weight and bias gradients when asked.
struct NormGradients {
  torch::Tensor x, branch, weight, bias;
};

NormGradients normalise_backward(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& mean,
                                 const torch::Tensor& rstd, torch::Tensor g, const torch::Tensor& g_res,
                                 bool bf16_branch, bool weight_grad, bool bias_grad) {
  g = g.contiguous();
  if (g.scalar_type() != torch::kBFloat16) g = g.to(torch::kFloat32);
  const auto res = g_res.defined() ? g_res.to(torch::kFloat32).contiguous() : torch::Tensor();
  const int64_t D = x.size(-1), rows = x.numel() / D, blocks = (rows + kRowsPerBlock - 1) / kRowsPerBlock;
  NormGradients out{torch::empty(x.sizes(), x.options()),
                    bf16_branch ? torch::empty(x.sizes(), x.options().dtype(torch::kBFloat16)) : torch::Tensor(),
                    {},
                    {}};
  auto gw_partial = torch::zeros({weight_grad ? blocks : 0, D}, weight.options());
  auto gb_partial = torch::zeros({bias_grad ? blocks : 0, D}, weight.options());
  auto run = [&](auto* g_tag) {
    using G = std::remove_pointer_t<decltype(g_tag)>;
    const auto rows_kernel = vectorised(D) ? backward_rows_avx512<G> : backward_rows<G>;
    at::parallel_for(0, blocks, 1, [&](int64_t block_begin, int64_t block_end) {
      for (int64_t b = block_begin; b < block_end; ++b)
        rows_kernel(x.data_ptr<float>(), weight.data_ptr<float>(), mean.data_ptr<float>(), rstd.data_ptr<float>(),
                    g.data_ptr<G>(), res.defined() ? res.data_ptr<float>() : nullptr, D, b * kRowsPerBlock,
                    std::min(rows, (b + 1) * kRowsPerBlock), out.x.data_ptr<float>(),
                    bf16_branch ? out.branch.data_ptr<BF16>() : nullptr,
                    weight_grad ? gw_partial.data_ptr<float>() + b * D : nullptr,
                    bias_grad ? gb_partial.data_ptr<float>() + b * D : nullptr);
    });
  };
  if (g.scalar_type() == torch::kBFloat16)
    run(static_cast<BF16*>(nullptr));
  else
    run(static_cast<float*>(nullptr));
  if (!bf16_branch) out.branch = out.x;  // LibTorch's add hands an fp32 branch the same gradient
  if (weight_grad) out.weight = sum_blocks_in_order(gw_partial);
  if (bias_grad) out.bias = sum_blocks_in_order(gb_partial);
  return out;
}

struct LayerNormToBf16Function : torch::autograd::Function<LayerNormToBf16Function> {
  static torch::Tensor forward(AutogradContext* ctx, torch::Tensor x, torch::Tensor weight, torch::Tensor bias,
                               double eps) {
    RECORD_FUNCTION("uplvsm::layer_norm_to_bf16", std::vector<c10::IValue>());
    x = x.contiguous();
    auto n = normalise(x, {}, weight, bias, eps);
    ctx->save_for_backward({x, weight, n.mean, n.rstd});
    ctx->saved_data["has_bias"] = bias.numel() > 0;
    return n.y;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grad_outputs) {
    RECORD_FUNCTION("uplvsm::layer_norm_to_bf16_backward", std::vector<c10::IValue>());
    auto saved = ctx->get_saved_variables();
    const bool bias_grad = ctx->saved_data["has_bias"].toBool() && ctx->needs_input_grad(2);
    auto g = normalise_backward(saved[0], saved[1], saved[2], saved[3], grad_outputs[0], {}, false,
                                ctx->needs_input_grad(1), bias_grad);
    return {g.x, g.weight, g.bias, torch::Tensor()};
  }
};

// h = x + branch and layer_norm(h) in bf16, as one node with two outputs.
struct AddLayerNormToBf16Function : torch::autograd::Function<AddLayerNormToBf16Function> {
  static variable_list forward(AutogradContext* ctx, torch::Tensor x, torch::Tensor branch, torch::Tensor weight,
                               torch::Tensor bias, double eps) {
    RECORD_FUNCTION("uplvsm::add_layer_norm_to_bf16", std::vector<c10::IValue>());
    auto n = normalise(x.contiguous(), branch.contiguous(), weight, bias, eps);
    ctx->save_for_backward({n.h, weight, n.mean, n.rstd});
    ctx->saved_data["has_bias"] = bias.numel() > 0;
    ctx->saved_data["bf16_branch"] = branch.scalar_type() == torch::kBFloat16;
    return {n.h, n.y};
  }

  static variable_list backward(AutogradContext* ctx, variable_list grad_outputs) {
    RECORD_FUNCTION("uplvsm::add_layer_norm_to_bf16_backward", std::vector<c10::IValue>());
    auto saved = ctx->get_saved_variables();
    const bool bf16_branch = ctx->saved_data["bf16_branch"].toBool();
    const auto &g_h = grad_outputs[0], &g_y = grad_outputs[1];
    if (!g_y.defined()) {  // only h was used: the residual add's own gradients
      auto g = g_h.to(torch::kFloat32);
      return {g, bf16_branch ? g.to(torch::kBFloat16) : g, torch::Tensor(), torch::Tensor(), torch::Tensor()};
    }
    const bool bias_grad = ctx->saved_data["has_bias"].toBool() && ctx->needs_input_grad(3);
    auto g = normalise_backward(saved[0], saved[1], saved[2], saved[3], g_y, g_h, bf16_branch, ctx->needs_input_grad(2),
                                bias_grad);
    return {g.x, g.branch, g.weight, g.bias, torch::Tensor()};
  }
};

bool fp32_vector_of(const torch::Tensor& t, int64_t D) {
  return t.scalar_type() == torch::kFloat32 && t.device().is_cpu() && t.dim() == 1 && t.size(0) == D &&
         t.is_contiguous();
}

}  // namespace

bool layer_norm_to_bf16_fuses(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias) {
  if (forced_unfused() || !x.device().is_cpu() || x.scalar_type() != torch::kFloat32 || x.dim() < 1) return false;
  const int64_t D = x.size(-1);
  return D > 0 && weight.defined() && fp32_vector_of(weight, D) && (!bias.defined() || fp32_vector_of(bias, D));
}

torch::Tensor layer_norm_to_bf16_unfused(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias,
                                         double eps) {
  return torch::layer_norm(x, {x.size(-1)}, weight, bias, eps).to(torch::kBFloat16);
}

torch::Tensor layer_norm_to_bf16(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias,
                                 double eps) {
  if (!layer_norm_to_bf16_fuses(x, weight, bias)) return layer_norm_to_bf16_unfused(x, weight, bias, eps);
  return LayerNormToBf16Function::apply(x, weight, bias.defined() ? bias : torch::empty({0}, weight.options()), eps);
}

bool add_layer_norm_to_bf16_fuses(const torch::Tensor& x, const torch::Tensor& branch, const torch::Tensor& weight,
                                  const torch::Tensor& bias) {
  return layer_norm_to_bf16_fuses(x, weight, bias) && branch.device().is_cpu() && branch.sizes() == x.sizes() &&
         (branch.scalar_type() == torch::kBFloat16 || branch.scalar_type() == torch::kFloat32);
}

std::pair<torch::Tensor, torch::Tensor> add_layer_norm_to_bf16_unfused(const torch::Tensor& x,
                                                                       const torch::Tensor& branch,
                                                                       const torch::Tensor& weight,
                                                                       const torch::Tensor& bias, double eps) {
  auto h = x + branch;
  return {h, layer_norm_to_bf16_unfused(h, weight, bias, eps)};
}

std::pair<torch::Tensor, torch::Tensor> add_layer_norm_to_bf16(const torch::Tensor& x, const torch::Tensor& branch,
                                                               const torch::Tensor& weight, const torch::Tensor& bias,
                                                               double eps) {
  if (!add_layer_norm_to_bf16_fuses(x, branch, weight, bias))
    return add_layer_norm_to_bf16_unfused(x, branch, weight, bias, eps);
  auto out = AddLayerNormToBf16Function::apply(x, branch, weight,
                                               bias.defined() ? bias : torch::empty({0}, weight.options()), eps);
  return {out[0], out[1]};
}

}  // namespace uplvsm::kernels
