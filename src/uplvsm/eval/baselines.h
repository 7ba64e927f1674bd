// Trivial reference predictors reported next to the model, so a number in the results table can be read against
// "how good is doing nothing clever": copy the nearest input view, or paint a constant colour.
#pragma once
#include <torch/torch.h>

#include <cstdint>
#include <vector>

namespace uplvsm::eval {

// Predicts each target by the input view nearest to it in frame index (ties -> the earlier input view).
// input_images [b, vi, 3, H, W]; input_frames[b] has vi entries and target_frames[b] vt entries (same vt for every
// batch element). Returns [b, vt, 3, H, W] on the device of input_images. Throws on inconsistent sizes.
torch::Tensor copy_nearest_input(const torch::Tensor& input_images,
                                 const std::vector<std::vector<int64_t>>& input_frames,
                                 const std::vector<std::vector<int64_t>>& target_frames);

// Index of the input frame nearest to `target` (first one on ties); exposed for tests and visualisations.
int64_t nearest_input(const std::vector<int64_t>& input_frames, int64_t target);

// For unordered views (frame indices say nothing about camera distance): predicts each target by the input view
// whose viewing direction (camera z axis) is nearest in angle (ties -> the earlier input view). input_c2w
// [b, vi, 4, 4], target_c2w [b, vt, 4, 4]; returns [b, vt, 3, H, W] on the device of input_images.
torch::Tensor copy_nearest_direction(const torch::Tensor& input_images, const torch::Tensor& input_c2w,
                                     const torch::Tensor& target_c2w);

// Predicts each target by a constant image of its own per-channel mean colour. This is an ORACLE constant: it
// looks at the ground truth, and the per-channel mean is the constant image with the lowest MSE, so its PSNR is an
// upper bound for every constant prediction (its SSIM is near 0 on textured images). target_images
// [..., 3, H, W] -> the same shape.
torch::Tensor mean_colour(const torch::Tensor& target_images);

}  // namespace uplvsm::eval
