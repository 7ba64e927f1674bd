// The layer loop of every transformer stack in the model (the encoder, estimator and decoder stacks of
// transformer.h and DINOv2's blocks): per block x = x + attn(norm1(x)); x = x + mlp(norm2(x)), written out as the ops
// it runs (layer_loop.cpp). The blocks' own forwards (TransformerBlockImpl::forward, DinoBlockImpl::forward) are the
// unfused reference beside it; tests/model/layer_loop_test.cpp holds the loop equal to them.
#pragma once
#include <torch/torch.h>

#include <memory>
#include <vector>

#include "uplvsm/model/linear.h"
#include "uplvsm/model/norm.h"

namespace uplvsm::model {

// The rows [start, start + count) of a token sequence that a caller reads from a stack's output (count < 0: all).
// The last block then computes only those rows' queries, attention outputs and MLP: a stack whose caller keeps the
// scene latents or the target tokens skips the rest of the sequence in its last block (every row still serves as
// a key and value there).
struct OutputRows {
  int64_t start = 0, count = -1;
  bool all(int64_t length) const { return count < 0 || (start == 0 && count == length); }
};

// A pre-norm block as the loop reads it: its two norms; attention as one qkv projection, QK-Norm per head (when
// q_norm is set) and an output projection; a GELU MLP; DINOv2's LayerScale gammas (undefined in LVSM's blocks).
struct BlockLayers {
  std::shared_ptr<torch::nn::Module> block;  // the whole block, whose parameters gradient checkpointing recomputes
  std::shared_ptr<LayerNormImpl> norm1, norm2;
  std::shared_ptr<LinearImpl> qkv, proj, fc1, fc2;
  std::shared_ptr<RMSNormImpl> q_norm, k_norm;
  torch::Tensor ls1, ls2;
  int64_t heads = 1;
};

// Runs the blocks in order and returns `rows` of the output. checkpoint_every > 0 (under grad mode): each group of
// that many blocks is gradient-checkpointed (the official `grad_checkpoint_every`); 0 keeps every activation.
torch::Tensor run_layers(const std::vector<BlockLayers>& blocks, torch::Tensor x, int64_t checkpoint_every = 0,
                         OutputRows rows = {});

}  // namespace uplvsm::model
