// The PSNR floor, one definition for the two sibling layers that report PSNR: training's logged PSNR (train/) and
// the evaluation metric (eval/metrics.h). Here because train and eval may not include each other.
#pragma once
#include <algorithm>
#include <cmath>

namespace uplvsm {

// Smallest MSE a PSNR is computed from: a perfect prediction (mse 0) scores -10 log10(1e-10) = 100 dB instead of
// +inf, so means over scenes and logs stay finite.
constexpr double kMinMse = 1e-10;

// -10 log10(max(mse, kMinMse)) of one MSE, as the official LossComputer logs it (eval::psnr is the batched form).
inline double psnr_from_mse(double mse) { return -10.0 * std::log10(std::max(mse, kMinMse)); }

}  // namespace uplvsm
