#include "uplvsm/model/transformer.h"

#include "uplvsm/core/autocast.h"
#include "uplvsm/kernels/flash_attention.h"
#include "uplvsm/kernels/gelu.h"
#include "uplvsm/kernels/layer_norm_to_bf16.h"
#include "uplvsm/kernels/qk_norm.h"
#include "uplvsm/model/gradient_checkpoint.h"

#include <algorithm>
#include <cmath>

namespace uplvsm::model {

LayerNormImpl::LayerNormImpl(int64_t dim_, double eps_, bool with_bias) : dim(dim_), eps(eps_) {
  weight = register_parameter("weight", torch::ones({dim}));
  if (with_bias) bias = register_parameter("bias", torch::zeros({dim}));
}

torch::Tensor LayerNormImpl::forward(const torch::Tensor& x) { return torch::layer_norm(x, {dim}, weight, bias, eps); }

torch::Tensor LayerNormImpl::forward_into_linear(const torch::Tensor& x) {
  if (autocast_active(x.device()) && layer_norm_to_bf16_fuses(x, weight, bias))
    return layer_norm_to_bf16(x, weight, bias, eps);
  return forward(x);
}

std::pair<torch::Tensor, torch::Tensor> LayerNormImpl::add_then_forward_into_linear(const torch::Tensor& x,
                                                                                    const torch::Tensor& branch) {
  if (autocast_active(x.device()) && add_layer_norm_to_bf16_fuses(x, branch, weight, bias))
    return add_layer_norm_to_bf16(x, branch, weight, bias, eps);
  auto h = x + branch;
  return {h, forward_into_linear(h)};
}

RMSNormImpl::RMSNormImpl(int64_t dim, double eps_) : eps(eps_) {
  weight = register_parameter("weight", torch::ones({dim}));
}

torch::Tensor RMSNormImpl::forward(const torch::Tensor& x) {
  return qk_norm(x, weight, eps, torch::promote_types(x.scalar_type(), weight.scalar_type()));
}

torch::ScalarType qk_norm_output_dtype(const torch::Tensor& projected, int64_t d_head) {
  // The dtype `attention` casts to under autocast (bf16 for the fused kernel) saves that pass; otherwise RMSNorm's
  // own result dtype (that of x times an fp32 weight).
  const auto device = projected.device();
  if (autocast_active(device) && fused_attention_applies(device, torch::kBFloat16, d_head)) return torch::kBFloat16;
  return torch::promote_types(projected.scalar_type(), torch::kFloat32);
}

torch::Tensor attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  // Under autocast the fused kernel takes bf16 operands (as autocast's matmuls would) and accumulates in fp32.
  const auto dtype = autocast_active(q.device()) ? torch::kBFloat16 : q.scalar_type();
  if (q.dim() == 4 && fused_attention_applies(q.device(), dtype, q.size(3)))
    return fused_attention(q.to(dtype), k.to(dtype), v.to(dtype));
#if TORCH_VERSION_MAJOR >= 2
  return at::scaled_dot_product_attention(q, k, v);
#else
  const double scale = 1.0 / std::sqrt(static_cast<double>(q.size(-1)));
  auto scores = torch::matmul(q, k.transpose(-2, -1)).mul_(scale);
  return torch::matmul(torch::softmax(scores, -1), v);
#endif
}

QKNormAttentionImpl::QKNormAttentionImpl(int64_t d, int64_t d_head_, double eps) : heads(d / d_head_), d_head(d_head_) {
  to_qkv = register_module("to_qkv", CastOnceLinear(torch::nn::LinearOptions(d, 3 * d).bias(false)));
  fc = register_module("fc", CastOnceLinear(torch::nn::LinearOptions(d, d).bias(false)));
  q_norm = register_module("q_norm", RMSNorm(d_head, eps));
  k_norm = register_module("k_norm", RMSNorm(d_head, eps));
}

std::tuple<torch::Tensor, torch::Tensor, torch::Tensor> QKNormAttentionImpl::project(const torch::Tensor& projected,
                                                                                     OutputRows rows) {
  const int64_t B = projected.size(0), L = projected.size(1);
  auto qkv = projected.chunk(3, -1);  // q | k | v, each head-major (heads, d_head)
  auto split = [&](const torch::Tensor& t) { return t.view({B, L, heads, d_head}); };
  const auto dtype = qk_norm_output_dtype(qkv[0], d_head);
  auto queries = rows.all(L) ? split(qkv[0]) : split(qkv[0]).narrow(1, rows.start, rows.count);
  auto q = qk_norm(queries, q_norm->weight, q_norm->eps, dtype).transpose(1, 2);
  auto k = qk_norm(split(qkv[1]), k_norm->weight, k_norm->eps, dtype).transpose(1, 2);
  auto v = split(qkv[2]).transpose(1, 2);
  return {q, k, v};
}

torch::Tensor QKNormAttentionImpl::forward(const torch::Tensor& x, OutputRows rows) {
  auto projected = to_qkv(x);
  torch::Tensor o;  // [B, heads, rows, d_head]
  const int64_t L = x.size(1), first = rows.all(L) ? 0 : rows.start, count = rows.all(L) ? L : rows.count;
  const bool fused_norm_dtype = autocast_active(x.device()) || projected.scalar_type() == torch::kFloat32;
  if (count > 0 && fused_norm_dtype && fused_qk_norm_attention_applies(projected, q_norm->weight, d_head)) {
    // The same bits as the path below (under autocast, or fp32 without gradients), in one node that stores neither
    // q and k normalised nor three separate gradients.
    o = fused_qk_norm_attention(projected, heads, q_norm->weight, k_norm->weight, q_norm->eps, first, count);
  } else {
    auto [q, k, v] = project(projected, rows);
    o = attention(q, k, v);
  }
  return fc(o.transpose(1, 2).reshape({x.size(0), o.size(2), heads * d_head}));
}

torch::Tensor QKNormAttentionImpl::attention_map(const torch::Tensor& x) {
  auto [q, k, v] = project(to_qkv(x), {});
  auto scores = torch::matmul(q, k.transpose(-2, -1)) / std::sqrt(static_cast<double>(d_head));
  return torch::softmax(scores.to(torch::kFloat32), -1).mean(1);
}

MLPImpl::MLPImpl(int64_t d, int64_t hidden) {
  mlp = register_module(
      "mlp", torch::nn::Sequential(CastOnceLinear(torch::nn::LinearOptions(d, hidden).bias(false)),
                                   torch::nn::Functional([](const torch::Tensor& t) { return model::gelu(t); }),
                                   CastOnceLinear(torch::nn::LinearOptions(hidden, d).bias(false))));
}

TransformerBlockImpl::TransformerBlockImpl(int64_t d, int64_t d_head, double eps) {
  norm1 = register_module("norm1", LayerNorm(d, 1e-5, false));
  attn = register_module("attn", QKNormAttention(d, d_head, eps));
  norm2 = register_module("norm2", LayerNorm(d, 1e-5, false));
  mlp = register_module("mlp", MLP(d, 4 * d));
}

torch::Tensor TransformerBlockImpl::forward(const torch::Tensor& x, OutputRows rows) {
  auto [h, mlp_out] = forward_deferred(x, {}, rows);
  return h + mlp_out;
}

std::pair<torch::Tensor, torch::Tensor> TransformerBlockImpl::forward_deferred(const torch::Tensor& stream,
                                                                               const torch::Tensor& pending,
                                                                               OutputRows rows) {
  auto [x, normed1] = pending.defined() ? norm1->add_then_forward_into_linear(stream, pending)
                                        : std::pair{stream, norm1->forward_into_linear(stream)};
  const auto kept = rows.all(x.size(1)) ? x : x.narrow(1, rows.start, rows.count);
  auto [h, normed2] = norm2->add_then_forward_into_linear(kept, attn->forward(normed1, rows));
  return {h, mlp(normed2)};
}

void init_linear_weights(torch::nn::Module& module, double std) {
  torch::NoGradGuard no_grad;
  for (auto& m : module.modules()) {
    if (auto* lin = m->as<torch::nn::Linear>()) {
      lin->weight.normal_(0.0, std);
      if (lin->bias.defined()) lin->bias.zero_();
    }
  }
}

torch::Tensor trunc_normal_(torch::Tensor t, double mean, double stddev, double a, double b) {
  TORCH_CHECK(stddev > 0 && a < b, "trunc_normal_: needs std > 0 and a < b, got std ", stddev, " and [", a, ", ", b,
              "]");
  torch::NoGradGuard no_grad;
  auto cdf = [](double x) { return 0.5 * (1.0 + std::erf(x / std::sqrt(2.0))); };
  // Uniform between the bounds' CDF values mapped through the inverse normal CDF, as torch.nn.init does it.
  const double lo = cdf((a - mean) / stddev), hi = cdf((b - mean) / stddev);
  t.uniform_(2.0 * lo - 1.0, 2.0 * hi - 1.0).erfinv_().mul_(stddev * std::sqrt(2.0)).add_(mean).clamp_(a, b);
  return t;
}

BlockInitStds official_block_init_stds(int64_t n_layer, bool special_init, bool depth_init) {
  BlockInitStds stds(static_cast<size_t>(std::max<int64_t>(n_layer, 0)), 0.02);
  if (!special_init) return stds;
  for (size_t i = 0; i < stds.size(); ++i)
    stds[i] = 0.02 / std::sqrt(2.0 * static_cast<double>(depth_init ? static_cast<int64_t>(i) + 1 : n_layer));
  return stds;
}

BlockInitStds official_uplvsm_decoder_init_stds(int64_t n_layer, bool special_init) {
  if (!special_init || n_layer <= 0) return official_block_init_stds(n_layer, false, false);
  BlockInitStds stds(static_cast<size_t>(n_layer), std::nullopt);
  stds.back() = 0.02 / std::sqrt(2.0 * static_cast<double>(n_layer));
  return stds;
}

torch::nn::ModuleList make_transformer_stack(int64_t d, int64_t d_head, double eps, const BlockInitStds& init_stds) {
  torch::nn::ModuleList stack;
  for (const auto& block_std : init_stds) {
    auto block = TransformerBlock(d, d_head, eps);
    if (block_std) init_linear_weights(*block, *block_std);
    stack->push_back(block);
  }
  return stack;
}

torch::nn::ModuleList make_transformer_stack(int64_t n_layer, int64_t d, int64_t d_head, double eps, bool depth_init) {
  return make_transformer_stack(d, d_head, eps, official_block_init_stds(n_layer, depth_init, depth_init));
}

torch::Tensor run_stack(const torch::nn::ModuleList& stack, torch::Tensor x, int64_t checkpoint_every, const char* span,
                        OutputRows rows) {
  RECORD_FUNCTION(span, std::vector<c10::IValue>());
  TORCH_CHECK(rows.all(x.size(1)) || (rows.start >= 0 && rows.count > 0 && rows.start + rows.count <= x.size(1)),
              "run_stack: output rows [", rows.start, ", ", rows.start + rows.count, ") outside a sequence of ",
              x.size(1));
  if (stack->size() == 0) return rows.all(x.size(1)) ? x : x.narrow(1, rows.start, rows.count);
  const size_t last = stack->size() - 1;
  if (checkpoint_every <= 0 || !torch::GradMode::is_enabled()) {
    // Nothing checkpointed: each block's closing residual add is deferred into the next block's first norm.
    torch::Tensor stream = std::move(x), pending;
    for (size_t i = 0; i <= last; ++i)
      std::tie(stream, pending) =
          stack->ptr<TransformerBlockImpl>(i)->forward_deferred(stream, pending, i == last ? rows : OutputRows{});
    return stream + pending;
  }
  return run_checkpointed_stack(
      stack, std::move(x), checkpoint_every, [stack, last, rows](size_t i, const torch::Tensor& t) {
        return stack->ptr<TransformerBlockImpl>(i)->forward(t, i == last ? rows : OutputRows{});
      });
}

}  // namespace uplvsm::model
