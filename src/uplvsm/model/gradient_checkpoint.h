// Gradient checkpointing (the official `torch.utils.checkpoint` per group of transformer blocks): a group runs
// without keeping its activations; backward recomputes it, under the autocast state of the forward, and
// differentiates the recomputation. Peak memory drops from O(layers) activations to O(groups); compute rises by
// one extra forward of the checkpointed layers.
#pragma once
#include <torch/torch.h>

#include <functional>
#include <vector>

namespace uplvsm::model {

using LayerGroupFn = std::function<torch::Tensor(const torch::Tensor&)>;

// y = fn(x), with gradients for x and for every tensor in `params` (the weights fn reads) produced by recomputation.
// Outside grad mode, or when nothing requires grad, it is a plain call.
torch::Tensor checkpointed(LayerGroupFn fn, const torch::Tensor& x, const std::vector<torch::Tensor>& params);

}  // namespace uplvsm::model
