// Model FLOPs of one forward pass, the numerator of model FLOP utilisation (MFU). Only matmuls count (linears,
// attention scores and weighted values, patch embeddings), 2 FLOPs per multiply-add. Training costs 3x the forward
// (the backward is two forwards' worth); recomputation by gradient checkpointing is not model work and not counted.
#pragma once
#include <cstdint>

#include "uplvsm/core/config.h"

namespace uplvsm::train {

struct FlopCount {
  double dinov2 = 0, encoder = 0, estimator = 0, decoder = 0, other = 0;  // tokenizers, heads
  double total() const { return dinov2 + encoder + estimator + decoder + other; }
};

// One pre-norm transformer block over one sequence: QKV + output projections, the MLP, and attention.
double transformer_block_flops(int64_t seq, int64_t d, int64_t mlp_hidden);
// A stack of n_layer blocks whose caller reads `kept` of the last block's `seq` rows (transformer.h: OutputRows):
// that block projects q, k, v for every row but the rest (out projection, MLP, attention queries) for `kept` only.
double transformer_stack_flops(int64_t n_layer, int64_t seq, int64_t kept, int64_t d, int64_t mlp_hidden);

// One forward of each model for `batch` scenes with the given view counts at config.image_size
// (model_factory.h: forward_flops picks the one of a config).
FlopCount uplvsm_forward_flops(const ModelConfig& config, int64_t batch, int64_t input_views, int64_t target_views);
// posed_input_views: the input views whose tokens get their rays (PT-LVSM 1, LVSM all).
FlopCount posed_lvsm_forward_flops(const ModelConfig& config, int64_t batch, int64_t input_views, int64_t target_views,
                                   int64_t posed_input_views);

// One forward of config's model (the one of the two above that it is), without building it.
FlopCount forward_flops(const ModelConfig& config, int64_t batch, int64_t input_views, int64_t target_views);

}  // namespace uplvsm::train
