// Where a training run's image tokenizer starts: the authors always load Meta's pretrained DINOv2 ViT-B/14 into it;
// ours asks for those weights (--init) at that size, or for an explicit opt-out, and says which it is.
#pragma once
#include <string>

#include "uplvsm/core/config.h"

namespace uplvsm::train {

// Whether the tokenizer is Meta's DINOv2 ViT-B/14 at the size of its released weights
// (dinov2_vitb14_reg4_pretrain.pth: embed_dim 768, depth 12, 12 heads, patch 14), which the official UP-LVSM and
// PT-LVSM always load into it (ptlvsm.py:31-41 at d490397).
bool tokenizer_has_released_weights(const ModelConfig& model);

// Where a run's tokenizer starts, for the dry-run and the log: the --init file, the checkpoint it resumes, random by
// choice (training.random_tokenizer), random because no weights of its size exist, or missing (the run refuses).
std::string describe_tokenizer_start(const Config& config, const std::string& init_weights, bool resuming);

// Refuses, before anything is read, a new run whose tokenizer has released weights but starts without --init and
// without the explicit opt-out; the message names the authors' file, where it comes from and both ways on.
void require_tokenizer_start(const Config& config, const std::string& init_weights, bool resuming);

}  // namespace uplvsm::train
