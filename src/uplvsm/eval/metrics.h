// Image-quality metrics of novel-view-synthesis evaluation, with the community's exact definitions
// (community-formats.md §5, official-uplvsm.md §12): PSNR and scikit-image's SSIM as pixelSplat / MVSplat /
// NoPoSplat / LVSM / UP-LVSM call them. Batched tensor ops only: they run on CPU or CUDA, on any leading shape.
#pragma once
#include <torch/torch.h>

#include "uplvsm/core/psnr.h"

namespace uplvsm::eval {

// pred, gt: [..., 3, H, W] (any float dtype, same shape and device). Both are clamped to [0, 1], the MSE over
// (C, H, W) of each image is computed in float64, clamped below at kMinMse (core/psnr.h), and -10 log10(mse)
// returned: float64 [...].
torch::Tensor psnr(const torch::Tensor& pred, const torch::Tensor& gt);

// scikit-image 0.19 `structural_similarity(gt, pred, win_size=11, gaussian_weights=True, channel_axis=0,
// data_range=1.0)` per image: Gaussian window sigma 1.5 truncated at 3.5 sigma (11 taps), separable filtering
// with scipy.ndimage mode 'reflect' (edge sample repeated), sample covariance (x 121/120), K1 0.01, K2 0.03,
// map cropped by 5 px on every border, mean, then mean over the channels. Inputs are NOT clamped (skimage does not
// clamp). Float32 inputs are computed as skimage does on float32 arrays (each filter pass accumulates in float64
// and rounds to float32, the rest in float32); float64 inputs entirely in float64; half/bfloat16 are upcast to
// float32. pred, gt: [..., C, H, W] with H, W >= 11. Returns float64 [...].
torch::Tensor ssim(const torch::Tensor& pred, const torch::Tensor& gt);

// Edge content of a prediction against its truth, the structure measure available without LPIPS weights (defined in
// docs/model.md): mean |grad pred| / mean |grad gt|, where mean |grad x| is the mean absolute forward difference of
// the [0, 1]-clamped image along x and along y, over every channel (C (H (W-1)) + C (H-1) W values, float64). 1: as
// much edge as the truth; 0: flat (a blur of the truth scores in between). A flat truth (mean |grad gt| below
// kMinGradientEnergy) is floored there, so the ratio stays finite. pred, gt: [..., C, H, W], H, W >= 2; float64 [...].
constexpr double kMinGradientEnergy = 1e-6;
torch::Tensor gradient_energy(const torch::Tensor& x);
torch::Tensor gradient_energy_ratio(const torch::Tensor& pred, const torch::Tensor& gt);

// The normalised 11-tap Gaussian window (sigma 1.5, float64, CPU), as scipy's _gaussian_kernel1d builds it.
torch::Tensor gaussian_window();

// scipy.ndimage 'reflect' padding of the last two dims by `pad` samples on every side (d c b a | a b c d |
// d c b a), built by index_select so it works for pads larger than the image too.
torch::Tensor reflect_pad2d(const torch::Tensor& x, int64_t pad);

}  // namespace uplvsm::eval
