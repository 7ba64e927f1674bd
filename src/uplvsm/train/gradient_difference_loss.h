// training.gradient_difference_weight's term (not in the paper): the gradient difference loss of Mathieu, Couprie and
// LeCun, "Deep multi-scale video prediction beyond mean square error" (ICLR 2016), with alpha = 1. An MSE-trained
// predictor that is unsure where an edge lies paints the average, a blur; this term compares the images' local
// differences in magnitude, so a flat render where the truth has an edge costs as much as the edge itself.
#pragma once
#include <torch/torch.h>

namespace uplvsm::train {

// Mean over every channel and pixel pair of | |pred(i+1) - pred(i)| - |target(i+1) - target(i)| |, the forward
// differences along x and along y together (C H (W-1) + C (H-1) W values per image, as eval's gradient energy counts
// them), averaged over images. pred, target: [..., C, H, W] of one shape, H, W >= 2; fp32; gradients flow into `pred`.
torch::Tensor gradient_difference_loss(const torch::Tensor& pred, const torch::Tensor& target);

}  // namespace uplvsm::train
