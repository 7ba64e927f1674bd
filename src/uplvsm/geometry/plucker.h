// Plücker rays [o x d, d] (moment first, 6 channels), LVSM's pixel-centre convention: pixel (row y, col x) looks
// through (x + 0.5, y + 0.5); d = normalize(R [ (x+0.5-cx)/fx, (y+0.5-cy)/fy, 1 ]), o = camera centre.
#pragma once
#include <torch/torch.h>

#include <utility>

namespace uplvsm::geometry {

// c2w [..., 4, 4], fxfycxcy [..., 4] in pixels of the height x width ray map -> (origins, directions), each
// [..., 3, height, width]. Direction normalisation runs in fp32 with the norm clamped at 1e-3 (official).
std::pair<torch::Tensor, torch::Tensor> compute_rays(const torch::Tensor& c2w, const torch::Tensor& fxfycxcy,
                                                     int64_t height, int64_t width);

// [..., 6, height, width] Plücker embedding of the same rays.
torch::Tensor plucker_rays(const torch::Tensor& c2w, const torch::Tensor& fxfycxcy, int64_t height, int64_t width);

}  // namespace uplvsm::geometry
