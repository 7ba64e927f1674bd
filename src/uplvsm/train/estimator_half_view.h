// model.estimator_half_view (not in the paper): a partial peek against latent poses that carry the target's content
// (RUST, Sajjadi et al., CVPR 2023, learns latent poses from a pose encoder that "peeks at the target image"; here
// the peek is cut in half). During training the estimator sees one half of each target — the left or the right,
// drawn per target — and the rendering loss counts only the other half. The latent pose can then help the
// render only as far as it carries what the two halves share, which is the camera, not the content it was shown; a
// latent camera used as a code for "this view looks like this" (docs/demo.md: the translation shortcut) no longer
// pays. Outside training the estimator sees the left half (model/uplvsm: estimate_poses), so it always reads what it
// learned on: half a view, the rest black.
#pragma once
#include <torch/torch.h>

#include "uplvsm/core/config.h"

namespace uplvsm::train {

// The half of each of `count` targets the estimator sees: [count, 1, H, W] (CPU fp32), 1 on the seen half (columns
// [0, W/2) or [W/2, W), drawn from the seed and the step so a resumed run draws the same), 0 elsewhere.
torch::Tensor draw_seen_halves(int64_t count, int64_t H, int64_t W, const TrainingConfig& tc, int64_t step);

// The mean squared error of `render` against `target` ([..., C, H, W]) over the pixels `scored` ([..., 1, H, W],
// 0 or 1) marks, every channel: the plain MSE where every pixel is scored.
torch::Tensor masked_mse(const torch::Tensor& render, const torch::Tensor& target, const torch::Tensor& scored);

}  // namespace uplvsm::train
