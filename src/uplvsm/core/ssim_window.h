// SSIM's definition (scikit-image's structural_similarity), used by the evaluation metric (eval/metrics.h).
#pragma once
#include <cmath>
#include <cstdint>
#include <vector>

namespace uplvsm::ssim {

constexpr int64_t kRadius = 5;  // int(3.5 * 1.5 + 0.5): scipy's truncate rule, an 11-tap window
constexpr double kSigma = 1.5;
constexpr double kCovNorm = 121.0 / 120.0;              // NP / (NP - 1), NP = 11 * 11 (sample covariance)
constexpr double kC1 = 0.01 * 0.01, kC2 = 0.03 * 0.03;  // (K * data_range)^2, data_range 1

// The normalised 11-tap Gaussian (float64), as scipy's _gaussian_kernel1d builds it.
inline std::vector<double> window_values() {
  std::vector<double> w;
  double sum = 0;
  for (int64_t x = -kRadius; x <= kRadius; ++x) {
    w.push_back(std::exp(-0.5 / (kSigma * kSigma) * static_cast<double>(x * x)));
    sum += w.back();
  }
  for (auto& v : w) v /= sum;
  return w;
}

}  // namespace uplvsm::ssim
