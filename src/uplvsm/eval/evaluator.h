// Test-set evaluation of a model of the family with the community protocol: read an evaluation index (pixelSplat /
// NoPoSplat format), render every scene's target views from its two context views, score each target with PSNR
// and SSIM (eval/metrics.h), and LPIPS (eval/lpips.h) when its weights are given, next to two trivial baselines
// (eval/baselines.h), average per scene then over scenes (full set and NoPoSplat overlap buckets), and write
// labelled PNG grids of a few scenes and the result files (metrics.json, per_scene.csv, per_view.csv:
// eval/result_files.h).
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/eval/lpips.h"
#include "uplvsm/eval/target_pose_refinement.h"
#include "uplvsm/model/novel_view_model.h"

namespace uplvsm::eval {

constexpr double kUnavailable = std::numeric_limits<double>::quiet_NaN();  // LPIPS without its weights

struct EvalOptions {
  std::string index_path;              // empty: <dataset root>/evaluation_index.json
  int64_t max_scenes = 0;              // 0: all (counted after dropping null entries and keys absent from the dataset)
  int64_t batch_size = 4;              // scenes per forward
  torch::Device device = torch::kCPU;  // where inputs go; the caller puts the model there
  int64_t num_visualised = 8;          // PNG grids for the first scenes (index order)
  std::string out_dir;                 // empty: write nothing, only return the summary
  Lpips lpips{nullptr};                // null: LPIPS is unavailable (NaN, null in JSON), never a made-up number
  int64_t lpips_chunk = 10;            // images per LPIPS forward (the official evaluation uses 10)
  bool bf16 = false;                   // the model forward under bf16 autocast (metrics always in fp32/fp64)
  // Where target cameras come from: the estimator reading the target image (UP-LVSM's protocol), the dataset
  // cameras through the pose mapper (camera control), or the dataset cameras directly (posed models).
  model::TargetPoses target_poses = model::TargetPoses::Estimator;
  // UP-LVSM with the estimator's poses only: refine each target's latent pose against the target before the render
  // that is scored (eval/target_pose_refinement.h; steps 0, the paper's protocol, leaves them as they are).
  PoseRefinement pose_refinement;
  // The official evaluation's pose noise (`unposed.noise_scale`, eval/eval_pose_noise.h): N(0, std^2) on the (t, q)
  // encodings of the dataset cameras the model reads, each scene's stream seeded by (pose_noise_seed, its key).
  // 0: clean cameras. The baselines always use clean ones.
  double pose_noise_std = 0;
  uint64_t pose_noise_seed = 0;
  nlohmann::json extra = nlohmann::json::object();  // merged into metrics.json (checkpoint, data, ...)
  // Sharded evaluation, one process per rank: this rank scores the scenes whose position in the index is
  // shard_rank mod shard_count; `gather` (the caller's collective, e.g. c10d) returns every rank's string in rank
  // order, so every rank ends with the full summary. Only shard 0 writes the metrics files; each rank writes the
  // grids of its own scenes.
  int shard_rank = 0, shard_count = 1;
  std::function<std::vector<std::string>(const std::string&)> gather;
};

// One predictor's scores on a view, or their means over a scene's targets.
struct Scores {
  double psnr = 0, ssim = 0;
  double lpips = kUnavailable;
  double grad_ratio = 0;  // gradient_energy_ratio (eval/metrics.h)
};
// The scores' names as metrics.json's table and the CSV columns spell them, with their fields.
inline constexpr std::array<std::pair<const char*, double Scores::*>, 4> kScoreFields{
    {{"psnr", &Scores::psnr}, {"ssim", &Scores::ssim}, {"lpips", &Scores::lpips}, {"grad_ratio", &Scores::grad_ratio}}};

// The model and the two trivial baselines (eval/baselines.h), each scored alike.
struct PredictorScores {
  Scores model, copy_nearest, mean_colour;
};
// The predictors' names (metrics.json's table rows), their column suffixes in the CSV files and JSON views, and
// their fields.
struct PredictorField {
  const char* name;
  const char* suffix;
  Scores PredictorScores::*field;
};
inline constexpr std::array<PredictorField, 3> kPredictors{{{"model", "", &PredictorScores::model},
                                                            {"copy_nearest", "_copy", &PredictorScores::copy_nearest},
                                                            {"mean_colour", "_mean", &PredictorScores::mean_colour}}};

struct ViewMetrics : PredictorScores {
  int64_t frame = 0;
  bool extrapolated = false;  // the frame lies outside [min(context), max(context)] (else interpolation)
};

struct SceneResult : PredictorScores {  // the predictors' means over the targets
  std::string key;
  std::vector<int64_t> context, target;
  std::optional<double> overlap;
  std::string bucket = "none";  // data::overlap_bucket(overlap): small/medium/large/ignore; "none" without overlap
  std::vector<ViewMetrics> views;
};

namespace detail {
inline const PredictorScores& scores_of(const PredictorScores& x) { return x; }
inline const PredictorScores& scores_of(const PredictorScores* x) { return *x; }
}  // namespace detail

// The mean of each predictor's scores over `items` (views or scenes, or pointers to them); NaN without items.
template <class Items>
PredictorScores mean_scores(const Items& items) {
  PredictorScores mean;
  const double n = static_cast<double>(std::size(items));
  for (const auto& p : kPredictors)
    for (const auto& [name, field] : kScoreFields) {
      double sum = 0;
      for (const auto& item : items) sum += (detail::scores_of(item).*p.field).*field;
      mean.*p.field.*field = sum / n;
    }
  return mean;
}

struct EvalSummary {
  int64_t scenes = 0;
  // Each predictor's mean over scenes of per-scene means (NaN when no scene was evaluated, and LPIPS NaN when it
  // was unavailable); metrics.json's "table".
  PredictorScores scores;
  // bucket ("small", "medium", "large", "ignore"; scenes without overlap are in no bucket) -> the same means over
  // its scenes.
  std::map<std::string, PredictorScores> buckets;
  std::map<std::string, int64_t> bucket_scenes;  // scenes per bucket
  // "interpolation" / "extrapolation" -> per scene, the mean over its targets of that kind, then the mean over the
  // scenes that have such targets (the paper's appendix table; latentSplat's split).
  std::map<std::string, PredictorScores> spans;
  std::map<std::string, int64_t> span_scenes;
  std::vector<SceneResult> per_scene;  // index (key) order
  double seconds = 0;
  int64_t skipped_null = 0;        // null entries of the index
  int64_t skipped_missing = 0;     // keys of the index absent from the dataset
  int64_t skipped_bad_frames = 0;  // scenes with frames that preprocess to different sizes (no square crop)
  int64_t resized_frames = 0;      // frames of another size than their scene's frame 0, resized as the official does
  std::vector<std::string> scene_grids;           // paths of the PNG grids written
  nlohmann::json lpips = {{"available", false}};  // {"available", "net"}; set by evaluate()
  nlohmann::json pose_noise = {{"std", 0.0}};     // eval::pose_noise_record; set by evaluate()
};

// Runs the evaluation (see the top comment). The model runs in eval mode under NoGradGuard with the protocol of
// opt.target_poses (default: the paper's unposed one, the estimator sees the target images), in float32 unless
// opt.bf16; its training mode is restored
// afterwards. Scenes are batched by equal (context, target) counts and image size. Throws std::runtime_error for an
// unreadable index, frames out of range and undecodable images (naming the scene).
EvalSummary evaluate(model::NovelViewModel& net, const data::ChunkDataset& dataset, const data::PreprocessOptions& prep,
                     const EvalOptions& opt);

// One scene's results as JSON and back (NaN, e.g. unavailable LPIPS, travels as null); used to merge shards.
nlohmann::json scene_to_json(const SceneResult& scene);
SceneResult scene_from_json(const nlohmann::json& j);

// Per-scene means from the views, then the table and bucket means over scenes (community convention). Exposed so
// results can be re-aggregated (tests, merging runs).
void finalise_scene(SceneResult& scene);
EvalSummary summarise(std::vector<SceneResult> scenes);

// Visualisations. error_heatmap: mean |pred - gt| over channels, x`gain`, clamped, through a black-purple-orange-
// yellow colormap: float [3, H, W] in [0, 1] (same device). scene_grid: a labelled uint8 [H, W, 3] grid, one row per
// target: the inputs, prediction, ground truth, |error| heat map, copy-nearest baseline. Tensors: inputs
// [vi, 3, H, W], pred/gt/copy [vt, 3, H, W], any device.
torch::Tensor error_heatmap(const torch::Tensor& pred, const torch::Tensor& gt, double gain = 4.0);
torch::Tensor scene_grid(const SceneResult& scene, const torch::Tensor& inputs, const torch::Tensor& pred,
                         const torch::Tensor& gt, const torch::Tensor& copy);

}  // namespace uplvsm::eval
