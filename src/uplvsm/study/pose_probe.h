// Pose probing (paper: "Probing Pose Accuracy", Table 7, and the t-SNE appendix): pairs of (latent pose from the
// Latent Plücker Learner, real pose) for the frames of dataset scenes, and probes that map latent poses to real
// SE(3) poses - a 2-layer MLP (the paper's probe) and a linear least-squares map for comparison.
// Real poses are camera-control poses (model/pose_mapper.h): relative to the first context view, translations in
// units of the context baseline. Latent poses are put in the same convention (relative to the first context view's
// latent pose, translations in the latent context baseline), so a probe maps like to like. Per scene the context is
// frames {0, gap}; every frame in between is a target.
// Errors: translation |t_pred - t_real| (baseline units); rotation the geodesic angle 2 acos |<q_pred, q_real>|
// (degrees). Accuracy@x = share of views with error below x. The first context view (always the identity) is
// left out of fitting and scoring.
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::study {

struct PosePairs {
  torch::Tensor latent, real;  // [N, 7] float64 (t, q_xyzw), both relative to the first context view
  std::vector<std::string> scenes;
  std::vector<int64_t> frames;
  int64_t skipped_scenes = 0;  // too few frames or a bad frame (logged)
};

struct PosePairOptions {
  int64_t max_scenes = 0;  // 0: every scene of the split
  int64_t gap = 12;        // context frames {0, gap} (clamped to the scene length)
  int64_t chunk = 8;       // target views per estimator pass
  torch::Device device = torch::kCPU;
};

// Runs the estimator (eval mode, no gradients) on every frame in [0, gap] of each scene. UP-LVSM variant only.
PosePairs collect_pose_pairs(model::UPLVSM& net, const data::ChunkDataset& dataset, const data::PreprocessOptions& prep,
                             const PosePairOptions& options);

// scene,frame,latent_tx..latent_qw,real_tx..real_qw (one row per view).
void write_pose_pairs_csv(const std::string& path, const PosePairs& pairs);

struct PoseAccuracy {
  std::vector<double> translation_thresholds{0.1, 0.2, 0.3}, rotation_thresholds_deg{10, 20, 30};
  std::vector<double> translation_accuracy, rotation_accuracy;  // per threshold, in [0, 1]
  double median_translation_error = 0, median_rotation_error_deg = 0;
  int64_t views = 0;
};
// Scores predicted real poses [N, 7] against the truth [N, 7].
PoseAccuracy pose_accuracy(const torch::Tensor& predicted, const torch::Tensor& real);
nlohmann::json to_json(const PoseAccuracy& accuracy);

struct ProbeOptions {
  int64_t hidden = 256;
  int64_t iterations = 3000;  // full-batch Adam steps
  double lr = 1e-3;
  uint64_t seed = 0;
};
// The probes fitted on `train` and applied to latent poses [N, 7]: predicted real poses [N, 7].
// The floor a probe must beat: every view predicted as the training views' mean real pose (no latent pose used).
torch::Tensor mean_pose_baseline(const PosePairs& train, int64_t views);
torch::Tensor fit_and_apply_linear_probe(const PosePairs& train, const torch::Tensor& latent);
torch::Tensor fit_and_apply_mlp_probe(const PosePairs& train, const torch::Tensor& latent, const ProbeOptions& options);

// Pairs without the first context view (its real pose is the identity by construction).
PosePairs without_canonical_views(const PosePairs& pairs);

}  // namespace uplvsm::study
