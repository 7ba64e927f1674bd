// What a config needs in memory before any of it is allocated: the exact parameter count of the model it builds
// (counted from the config, as the modules would register them) and a lower bound on training memory, so a config
// that cannot fit is refused with one clear line instead of a failed multi-gigabyte allocation deep in LibTorch.
#pragma once
#include <cstdint>

#include "uplvsm/core/config.h"

namespace uplvsm::train {

// Parameters of the model `config` builds (equals make_model(config)->parameter_count()).
int64_t parameter_count(const ModelConfig& config);

struct TrainingMemory {
  int64_t parameters = 0;
  // fp32 weights, gradients and AdamW's two moments: 16 bytes per parameter
  double state_bytes = 0;
  double activation_bytes = 0;  // tensors kept for the backward of one micro-batch (a lower bound)
  double total() const { return state_bytes + activation_bytes; }
};

// A lower bound on what one training process holds: the state above plus, per token of every transformer block
// (DINOv2, encoder, estimator, decoder), the block input, q/k/v, the attention output and the MLP hidden layer
// before and after its GELU (13 d values; bf16 under autocast); with gradient checkpointing in groups of k blocks
// only the group inputs are kept. Attention matrices, other buffers and the allocator's slack come on top.
TrainingMemory training_memory(const Config& config);

}  // namespace uplvsm::train
