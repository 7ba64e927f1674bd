// The model family's linear layer: torch::nn::Linear's parameters and state_dict names (`weight`, `bias`; official
// checkpoints load unchanged), computed by the kernels' linear op (kernels/ops.h), which keeps this layer's bf16 copy
// of the weights for bf16 inference.
#pragma once
#include <torch/torch.h>

#include <memory>

namespace uplvsm::kernels {
class LinearWeightCache;
}

namespace uplvsm::model {

struct LinearImpl : torch::nn::LinearImpl {
  explicit LinearImpl(const torch::nn::LinearOptions& options);
  LinearImpl(int64_t in_features, int64_t out_features)
      : LinearImpl(torch::nn::LinearOptions(in_features, out_features)) {}
  torch::Tensor forward(const torch::Tensor& input);

 private:
  std::shared_ptr<kernels::LinearWeightCache> cache_;
};
TORCH_MODULE(Linear);

}  // namespace uplvsm::model
