// t-SNE (van der Maaten & Hinton 2008, exact O(N^2) gradient) and the paper's latent-vs-real pose figure (Appendix
// "Investigation Details"): N latent poses and their N real poses are stacked into 2N x 7, embedded in 2-D
// together, and drawn with each pair in one colour (latent: filled square, real: ring). No Debian C++ library
// provides t-SNE, so this is the reference algorithm: perplexity-calibrated Gaussian affinities (per-row binary
// search), symmetrised; Student-t affinities in 2-D; gradient descent with momentum, adaptive gains and early
// exaggeration. Exact is fine for the few thousand poses a figure shows.
#pragma once
#include <torch/torch.h>

#include <string>

namespace uplvsm::study {

struct TsneOptions {
  double perplexity = 30;  // capped at (N - 1) / 3
  int64_t iterations = 1000;
  int64_t exaggeration_iterations = 250;
  double exaggeration = 12;
  double learning_rate = 0;  // 0: max(N / exaggeration / 4, 50) (the "auto" rate)
  uint64_t seed = 0;
};

struct TsneResult {
  torch::Tensor embedding;   // [N, 2] float64
  double kl_divergence = 0;  // KL(P || Q) at the end
};

// Row-conditional affinities P(j|i) [N, N] whose entropies equal log(perplexity) (binary search on the precision).
torch::Tensor conditional_affinities(const torch::Tensor& squared_distances, double perplexity);

// points [N, D] -> 2-D embedding. Throws for N < 4 or non-finite input.
TsneResult tsne(const torch::Tensor& points, const TsneOptions& options = {});

// The figure: embedding [2N, 2] of N latent poses (rows 0..N-1) then their real poses; uint8 [H, W, 3].
torch::Tensor pose_pair_figure(const torch::Tensor& embedding, const std::string& title, int size = 720);

}  // namespace uplvsm::study
