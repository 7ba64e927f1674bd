// Function-preserving deepening (Net2DeeperNet: Chen, Goodfellow and Shlens, "Net2Net", ICLR 2016): a model built
// with more transformer blocks in a stack than a weight file holds starts from those weights with each added block
// the identity (its residual branches' output projections, attn.fc and mlp.mlp.2, zero), so it computes exactly what
// the file's model computed and training grows the new blocks from there (`training.init_new_blocks_identity`).
#pragma once
#include <torch/torch.h>

#include <string>
#include <vector>

#include "uplvsm/model/state_dict.h"

namespace uplvsm::model {

// The names ("estimator.transformer_estimator.1") of the transformer blocks of `net` of which `tensors` holds no
// key. Throws, naming `source`, when a block is only partly in the file or an absent block comes before one the
// file holds in the same stack: those are mismatched files, not a deeper model.
std::vector<std::string> blocks_absent_from(const torch::nn::Module& net, const NamedTensors& tensors,
                                            const std::string& source);

// Zeroes the residual output projections of the named blocks, so each adds nothing to its residual stream.
void make_blocks_identity(torch::nn::Module& net, const std::vector<std::string>& block_names);

}  // namespace uplvsm::model
