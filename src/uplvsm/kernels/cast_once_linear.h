// The linear op of ops.h and its weight cache: the bf16 copy of the weights made once per layer for inference under
// bf16 autocast, instead of on every call (autocast's own cache lives only as long as one autocast region, i.e. one
// forward): for the paper's 260 M-parameter model that cast is ~0.3-0.9 s of every render call on two cores. The copy
// is remade when the weights change (their version counter, e.g. an optimizer step or a state-dict load) and is never
// used while gradients are recorded. Every path computes what ATen's linear (PyTorch's nn.Linear) computes: training
// and fp32 inference call it, bf16 inference calls it with the same round-to-nearest-even cast of the same weights.
// Training under CPU bf16 autocast goes through bf16_linear (the same forward, a faster weight gradient).
#pragma once
#include <torch/torch.h>

#include <mutex>
#include <utility>

namespace uplvsm::kernels {

class LinearWeightCache {
 public:
  // The bf16 weight (and bias) for the weights as they are now; made on first use and after every change.
  std::pair<torch::Tensor, torch::Tensor> bf16_weights(const torch::Tensor& weight, const torch::Tensor& bias);

 private:
  std::mutex mutex_;  // the viewer renders from several threads
  torch::Tensor weight_bf16_, bias_bf16_;
  // What the copy was made from: the storages themselves (held, so a new tensor cannot reuse their address) and
  // version counters (in-place changes).
  c10::Storage weight_storage_, bias_storage_;
  int64_t weight_version_ = -1, bias_version_ = -1;
};

}  // namespace uplvsm::kernels
