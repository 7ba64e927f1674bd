// The LVSM / official UP-LVSM transformer block: pre-LayerNorm without bias, QK RMSNorm per head (one [d_head]
// weight shared by all heads, eps a parameter: 1e-5 in LVSM, 1e-3 in UP-LVSM), bias-free linears, GELU MLP 4x.
// Module and parameter names equal the official state_dict names (norm1, attn.to_qkv, attn.fc, attn.q_norm,
// attn.k_norm, norm2, mlp.mlp.0, mlp.mlp.2) so official checkpoints load without renaming.
#pragma once
#include <torch/torch.h>

#include <vector>

#include "uplvsm/model/layer_loop.h"
#include "uplvsm/model/linear.h"
#include "uplvsm/model/norm.h"

namespace uplvsm::model {

// softmax(rms(q) rms(k)^T / sqrt(d_head)) v per head, q | k | v = to_qkv(x), heads merged and projected by fc.
struct QKNormAttentionImpl : torch::nn::Module {
  QKNormAttentionImpl(int64_t d, int64_t d_head, double qk_norm_eps);
  // Attention over every row of x; the result only for `rows`.
  torch::Tensor forward(const torch::Tensor& x, OutputRows rows = {});
  // The attention probabilities (head-mean, [B, L, L]) for analysis tools; not used by forward.
  torch::Tensor attention_map(const torch::Tensor& x);
  Linear to_qkv{nullptr}, fc{nullptr};
  RMSNorm q_norm{nullptr}, k_norm{nullptr};
  int64_t heads, d_head;
};
TORCH_MODULE(QKNormAttention);

struct MLPImpl : torch::nn::Module {
  MLPImpl(int64_t d, int64_t hidden);
  torch::Tensor forward(const torch::Tensor& x) { return mlp->forward(x); }
  torch::nn::Sequential mlp{nullptr};  // 0: Linear, 1: GELU, 2: Linear (official names mlp.mlp.0 / mlp.mlp.2)
};
TORCH_MODULE(MLP);

// The pre-norm block: x = x + attn(norm1(x)); x = x + mlp(norm2(x)). `rows`: only those rows' queries, attention
// outputs and MLP (every row still serves as a key and value). forward is the reference; stacks run through the
// layer loop (layer_loop.h), which reads the block as layers().
struct TransformerBlockImpl : torch::nn::Module {
  TransformerBlockImpl(int64_t d, int64_t d_head, double qk_norm_eps);
  torch::Tensor forward(const torch::Tensor& x, OutputRows rows = {});
  BlockLayers layers();
  LayerNorm norm1{nullptr}, norm2{nullptr};
  QKNormAttention attn{nullptr};
  MLP mlp{nullptr};
};
TORCH_MODULE(TransformerBlock);

// The std of each block's linear weights when a stack is built (official transformer.py `init_weights`: N(0, std),
// biases zero).
using BlockInitStds = std::vector<double>;

// The official rule for a stack of n_layer blocks, the same for PT-LVSM's stack and UP-LVSM's encoder and decoder
// (ptlvsm.py; uplvsm.py `_init_transformer`, lines 126-148 at d490397): special_init with depth_init: block i gets
// 0.02 / sqrt(2 (i + 1)); special_init alone: 0.02 / sqrt(2 n_layer); without special_init: 0.02 (depth_init then does
// nothing). (The first release, 00411f7, set only the decoder's last block: a for-else typo fixed in f3e23d0.)
BlockInitStds official_block_init_stds(int64_t n_layer, bool special_init, bool depth_init);

// A stack of init_stds.size() blocks in a ModuleList (keys "<name>.<i>.*"), block i's linears drawn by init_stds[i].
torch::nn::ModuleList make_transformer_stack(int64_t d, int64_t d_head, double qk_norm_eps,
                                             const BlockInitStds& init_stds);
// The same with the official rule for special_init = depth_init = `depth_init` (true: 0.02 / sqrt(2 (i + 1));
// false: 0.02 for every block).
torch::nn::ModuleList make_transformer_stack(int64_t n_layer, int64_t d, int64_t d_head, double qk_norm_eps,
                                             bool depth_init);
// Runs the blocks in order through the layer loop (layer_loop.h: the blocks' forwards, each closing residual add
// fused into the next block's first norm). checkpoint_every > 0: each group of that many blocks is
// gradient-checkpointed (the official `grad_checkpoint_every`); 0 keeps every activation. `span` names the stack in
// profiler traces (UPLVSM_PROFILE), so the forwards that call it need no profiling code of their own. Returns `rows` of
// the output.
torch::Tensor run_stack(const torch::nn::ModuleList& stack, torch::Tensor x, int64_t checkpoint_every = 0,
                        const char* span = "uplvsm::transformer_stack", OutputRows rows = {});

// N(0, std) for every Linear weight under `module` (biases zero); norms keep their ones/zeros.
void init_linear_weights(torch::nn::Module& module, double std);

// PyTorch's nn.init.trunc_normal_ (inverse-CDF sampling, then a clamp): N(mean, std) truncated to [a, b], where a
// and b are absolute values, not multiples of std (the official latents' std 0.02 with a = -2, b = 2 cut nothing).
// Fills `t` in place and returns it.
torch::Tensor trunc_normal_(torch::Tensor t, double mean, double stddev, double a, double b);

}  // namespace uplvsm::model
