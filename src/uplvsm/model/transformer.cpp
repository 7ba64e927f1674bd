#include "uplvsm/model/transformer.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "uplvsm/kernels/ops.h"

namespace uplvsm::model {

QKNormAttentionImpl::QKNormAttentionImpl(int64_t d, int64_t d_head_, double eps) : heads(d / d_head_), d_head(d_head_) {
  to_qkv = register_module("to_qkv", Linear(torch::nn::LinearOptions(d, 3 * d).bias(false)));
  fc = register_module("fc", Linear(torch::nn::LinearOptions(d, d).bias(false)));
  q_norm = register_module("q_norm", RMSNorm(d_head, eps));
  k_norm = register_module("k_norm", RMSNorm(d_head, eps));
}

torch::Tensor QKNormAttentionImpl::forward(const torch::Tensor& x, OutputRows rows) {
  const bool all = rows.all(x.size(1));
  return fc(kernels::qk_norm_attention(to_qkv(x), heads, q_norm->weight, q_norm->eps, k_norm->weight, k_norm->eps,
                                       all ? 0 : rows.start, all ? -1 : rows.count));
}

torch::Tensor QKNormAttentionImpl::attention_map(const torch::Tensor& x) {
  const auto projected = to_qkv(x);
  const int64_t B = x.size(0), L = x.size(1);
  auto qkv = projected.view({B, L, 3, heads, d_head}).permute({2, 0, 3, 1, 4}).unbind(0);  // [B, heads, L, d_head]
  const auto dtype = kernels::qk_norm_output_dtype(projected, d_head);
  auto q = kernels::rms_norm(qkv[0], q_norm->weight, q_norm->eps, dtype);
  auto k = kernels::rms_norm(qkv[1], k_norm->weight, k_norm->eps, dtype);
  auto scores = torch::matmul(q, k.transpose(-2, -1)) / std::sqrt(static_cast<double>(d_head));
  return torch::softmax(scores.to(torch::kFloat32), -1).mean(1);
}

MLPImpl::MLPImpl(int64_t d, int64_t hidden) {
  mlp = register_module(
      "mlp", torch::nn::Sequential(Linear(torch::nn::LinearOptions(d, hidden).bias(false)),
                                   torch::nn::Functional([](const torch::Tensor& t) { return kernels::gelu(t); }),
                                   Linear(torch::nn::LinearOptions(hidden, d).bias(false))));
}

TransformerBlockImpl::TransformerBlockImpl(int64_t d, int64_t d_head, double eps) {
  norm1 = register_module("norm1", LayerNorm(d, 1e-5, false));
  attn = register_module("attn", QKNormAttention(d, d_head, eps));
  norm2 = register_module("norm2", LayerNorm(d, 1e-5, false));
  mlp = register_module("mlp", MLP(d, 4 * d));
}

torch::Tensor TransformerBlockImpl::forward(const torch::Tensor& x, OutputRows rows) {
  const auto kept = rows.all(x.size(1)) ? x : x.narrow(1, rows.start, rows.count);
  const auto h = kept + attn(norm1->forward_into_linear(x), rows);
  return h + mlp(norm2->forward_into_linear(h));
}

BlockLayers TransformerBlockImpl::layers() {
  BlockLayers l;
  l.block = shared_from_this();
  l.norm1 = norm1.ptr(), l.norm2 = norm2.ptr();
  l.qkv = attn->to_qkv.ptr(), l.proj = attn->fc.ptr(), l.heads = attn->heads;
  l.q_norm = attn->q_norm.ptr(), l.k_norm = attn->k_norm.ptr();
  l.fc1 = mlp->mlp->ptr<LinearImpl>(0), l.fc2 = mlp->mlp->ptr<LinearImpl>(2);  // 1 is the GELU
  return l;
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

torch::nn::ModuleList make_transformer_stack(int64_t d, int64_t d_head, double eps, const BlockInitStds& init_stds) {
  torch::nn::ModuleList stack;
  for (const double block_std : init_stds) {
    auto block = TransformerBlock(d, d_head, eps);
    init_linear_weights(*block, block_std);
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
  std::vector<BlockLayers> blocks;
  for (size_t i = 0; i < stack->size(); ++i) blocks.push_back(stack->ptr<TransformerBlockImpl>(i)->layers());
  return run_layers(blocks, std::move(x), checkpoint_every, rows);
}

}  // namespace uplvsm::model
