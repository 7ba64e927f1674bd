#include "uplvsm/model/layer_loop.h"

#include <algorithm>
#include <tuple>
#include <utility>

#include "uplvsm/kernels/ops.h"
#include "uplvsm/model/gradient_checkpoint.h"

namespace uplvsm::model {
namespace {

// The ops of the loop, on a block's modules. LayerNorms feed linear layers only, so they may come out in bf16 under
// autocast (kernels/ops.h: into_linear).
torch::Tensor norm(const LayerNormImpl& n, const torch::Tensor& x) {
  return kernels::layer_norm(x, n.weight, n.bias, n.eps, /*into_linear=*/true);
}

// {h = x + branch, norm(h)} as one op.
std::pair<torch::Tensor, torch::Tensor> add_norm(const LayerNormImpl& n, const torch::Tensor& x,
                                                 const torch::Tensor& branch) {
  return kernels::add_layer_norm(x, branch, n.weight, n.bias, n.eps, /*into_linear=*/true);
}

// softmax(rms(q) rms(k)^T / sqrt(d_head)) v per head for the query rows kept, heads merged (no QK-Norm without
// q_norm).
torch::Tensor attention(const BlockLayers& b, const torch::Tensor& qkv, bool all_rows, OutputRows rows) {
  if (!b.q_norm)
    return kernels::qk_norm_attention(qkv, b.heads, {}, 0.0, {}, 0.0, all_rows ? 0 : rows.start,
                                      all_rows ? -1 : rows.count);
  return kernels::qk_norm_attention(qkv, b.heads, b.q_norm->weight, b.q_norm->eps, b.k_norm->weight, b.k_norm->eps,
                                    all_rows ? 0 : rows.start, all_rows ? -1 : rows.count);
}

// DINOv2's LayerScale (x * gamma); LVSM's blocks have none.
torch::Tensor layer_scale(const torch::Tensor& x, const torch::Tensor& gamma) {
  return gamma.defined() ? x * gamma : x;
}

// Blocks [begin, end); the last keeps only `rows`. The residual stream is carried as residual + mlp_out, so that
// each block's closing add can join the next block's first norm.
torch::Tensor run_range(const std::vector<BlockLayers>& blocks, size_t begin, size_t end, torch::Tensor residual,
                        OutputRows rows) {
  torch::Tensor mlp_out, normed;
  for (size_t i = begin; i < end; ++i) {
    const auto& b = blocks[i];
    const bool all_rows = i + 1 < end || rows.all(residual.size(1));
    // Fused across blocks, as llm.c: block i-1's closing add (residual + mlp_out) runs in block i's norm1.
    if (mlp_out.defined())
      std::tie(residual, normed) = add_norm(*b.norm1, residual, mlp_out);
    else
      normed = norm(*b.norm1, residual);
    const auto attn = layer_scale(b.proj->forward(attention(b, b.qkv->forward(normed), all_rows, rows)), b.ls1);
    const auto kept = all_rows ? residual : residual.narrow(1, rows.start, rows.count);
    std::tie(residual, normed) = add_norm(*b.norm2, kept, attn);  // x + attn, and norm2 of it
    mlp_out = layer_scale(b.fc2->forward(kernels::gelu(b.fc1->forward(normed))), b.ls2);
  }
  return residual + mlp_out;  // the last block's closing add
}

}  // namespace

torch::Tensor run_layers(const std::vector<BlockLayers>& blocks, torch::Tensor x, int64_t checkpoint_every,
                         OutputRows rows) {
  const int64_t length = x.size(1);
  TORCH_CHECK(rows.all(length) || (rows.start >= 0 && rows.count > 0 && rows.start + rows.count <= length),
              "layer loop: output rows [", rows.start, ", ", rows.start + rows.count, ") outside a sequence of ",
              length);
  const size_t n = blocks.size();
  if (n == 0) return rows.all(length) ? x : x.narrow(1, rows.start, rows.count);
  if (checkpoint_every <= 0 || !torch::GradMode::is_enabled()) return run_range(blocks, 0, n, std::move(x), rows);
  // Each group runs as one range (fused inside); backward recomputes it from the group's input.
  auto shared = std::make_shared<const std::vector<BlockLayers>>(blocks);
  const auto group = static_cast<size_t>(checkpoint_every);
  for (size_t begin = 0; begin < n; begin += group) {
    const size_t end = std::min(n, begin + group);
    const OutputRows kept = end == n ? rows : OutputRows{};
    std::vector<torch::Tensor> params;
    for (size_t i = begin; i < end; ++i) {
      const auto p = blocks[i].block->parameters();
      params.insert(params.end(), p.begin(), p.end());
    }
    x = checkpointed(
        [shared, begin, end, kept](const torch::Tensor& t) { return run_range(*shared, begin, end, t, kept); }, x,
        params);
  }
  return x;
}

}  // namespace uplvsm::model
