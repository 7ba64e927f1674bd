// Not in the paper (model.transformer.estimator_correspondence): where each patch of a target view finds its content
// in input view 0, as a displacement on the patch grid. The official estimator mean-pools its image tokens, which
// averages a global shift of the image (what a turn of the camera does) away; this readout hands the estimator the
// shift itself: one attention head whose values are the patch positions of view 0, minus the patch's own position.
#pragma once
#include <torch/torch.h>

#include "uplvsm/model/dinov2.h"

namespace uplvsm::model {

// [n, 2] (x, y) centres of a square grid of n patches in row-major order, in [-1, 1].
torch::Tensor patch_grid(int64_t n, const torch::TensorOptions& options);

// queries [N, n, c] (target patches), keys [N, n, c] (view-0 patches), grid [n, 2] (patch_grid) -> [N, n, 2]:
// softmax(q k^T / sqrt(c)) times the grid, minus the grid: the soft-matched position of each target patch relative
// to its own (fp32).
torch::Tensor correspondence_displacement(const torch::Tensor& queries, const torch::Tensor& keys,
                                          const torch::Tensor& grid);

struct CorrespondenceReadoutImpl : torch::nn::Module {
  CorrespondenceReadoutImpl(int64_t d, int64_t d_head);
  // target tokens [N, n, d], view-0 tokens [N, n, d] -> [N, d]: an MLP of (position, displacement) per patch,
  // mean-pooled. Its output layer starts at zero, so the estimator starts as the official one.
  torch::Tensor forward(const torch::Tensor& target_tokens, const torch::Tensor& view0_tokens);

  torch::nn::Linear query{nullptr}, key{nullptr};
  DinoMlp mlp{nullptr};
};
TORCH_MODULE(CorrespondenceReadout);

}  // namespace uplvsm::model
