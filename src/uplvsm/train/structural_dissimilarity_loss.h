// training.ssim_loss_weight's term (not in the official recipe, which adds a VGG perceptual loss we have no weights
// for): the structural dissimilarity 1 - SSIM, the structure half of 3D Gaussian Splatting's 0.8 L1 + 0.2 D-SSIM.
// An MSE-trained renderer that is unsure where an edge is paints the average (a blur); SSIM scores local contrast and
// correlation, so a blur costs more here than under the MSE.
#pragma once
#include <torch/torch.h>

namespace uplvsm::train {

// 1 - mean SSIM of [..., C, H, W] predictions against targets (H, W >= 11), with the evaluation's definition
// (eval/metrics.h: Gaussian window sigma 1.5 over 11 taps, sample covariance, K1 0.01, K2 0.03, data range 1) over the
// window positions that lie inside the image, which are the evaluation's map cropped by 5 pixels: the loss is
// 1 - eval::ssim averaged over images. Computed in fp32 with convolutions (differentiable; gradients flow into
// `pred`); call it outside an autocast region, where bf16 variances would cancel.
torch::Tensor structural_dissimilarity_loss(const torch::Tensor& pred, const torch::Tensor& target);

}  // namespace uplvsm::train
