// The single-model analyses of `uplvsm study` as library calls, each writing its files into an output directory:
// pose-pairs ((latent pose, real pose) pairs of a split), pose-probe (the paper's Table 7: MLP and linear probes
// latent -> SE(3) fitted on one split, scored on another), pose-sensitivity (does the decoder use the pose), tsne
// (latent and real poses embedded together) and attention (the cross-view attention figure).
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "uplvsm/core/config.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/study/pose_probe.h"

namespace uplvsm::study {

struct PoseStudyOptions {
  std::string data, split = "test", train_split = "train";  // dataset root with cameras; scored and fitted splits
  std::string out;                                          // output directory (pose-pairs: the CSV file)
  std::string checkpoint;                                   // recorded in the JSON written
  int64_t max_scenes = 0;                                   // scenes per split (0: all)
  int64_t gap = 12;                              // context frames {0, gap} per scene; every frame between them a target
  int64_t iterations = 3000;                     // the MLP probe's Adam steps; t-SNE's gradient steps
  double perplexity = 30;                        // t-SNE
  TargetPoses target_poses = TargetPoses::Auto;  // pose-sensitivity: where the views' poses come from
  torch::Device device = torch::kCPU;
};

// The pairs of one split of options.data.
PosePairs pose_pairs_of_split(model::UPLVSM& net, const Config& config, const PoseStudyOptions& options,
                              const std::string& split);

struct ProbeScores {
  PoseAccuracy mlp, linear, mean;  // mean: the training views' mean real pose, no latent used
  size_t train_views = 0, test_views = 0;
};
// Fits on train_split, scores on split; writes pairs_<split>.csv for both and probe.json.
ProbeScores run_pose_probe(model::UPLVSM& net, const Config& config, const PoseStudyOptions& options);

// Writes views.csv and sensitivity.json; returns the summary (targets, inputs, all_but_first_input, ...).
nlohmann::json run_pose_sensitivity(model::UPLVSM& net, const Config& config, const PoseStudyOptions& options);

struct TsneRun {
  int64_t pairs = 0;
  double kl_divergence = 0;
  std::string png;
};
// Writes pairs.csv, tsne.csv (the 2-D points) and tsne.png.
TsneRun run_tsne(model::UPLVSM& net, const Config& config, const PoseStudyOptions& options);

struct AttentionOptions {
  std::string data, split = "test", out;  // dataset scenes: the evaluation index's context views
  std::vector<std::string> images;        // or two photos
  double fov = 60;                        // their horizontal field of view, degrees
  std::vector<int64_t> patch;             // row col of view 1's query patch; empty: the centre
  int64_t scenes = 1;
  torch::Device device = torch::kCPU;
};
struct AttentionDrawn {
  std::string scene, png;
  int64_t row = 0, col = 0;
  double attention_sum = 0;  // over view 2 (1 up to rounding)
};
// attention_<scene>.png per scene and attention.json with the maps.
std::vector<AttentionDrawn> run_attention(model::UPLVSM& net, const Config& config, const AttentionOptions& options);

}  // namespace uplvsm::study
