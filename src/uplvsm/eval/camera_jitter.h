// Jitter of camera-controlled rendering (Less3Depend #6: the linear mapper "jitters"): what a viewer sees as
// wobble when a model renders a smooth real camera path. The path: a held-out scene's own camera sequence from its
// first input view, each step between two frames cut into `subdivisions` (translation linear, rotation slerp), so
// that consecutive renders are close. Jitter is the wobble of eval/picture_motion.h: how much the rendered
// picture's motion (its optical flow) changes from one render to the next, in pixels per frame², which a steady
// motion does not at any speed or texture. The dataset has no frames between its own, so along these paths it reads
// the renders alone and also counts the path's own turns (the same path for every mapper); the ground-truth paths
// of the built-in rooms subtract the truth's motion.
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>
#include <string>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/eval/picture_motion.h"
#include "uplvsm/model/novel_view_model.h"

namespace uplvsm::eval {

// Real poses [1, n, 7] (camera-control units) with each step cut into `subdivisions` -> [1, (n - 1) s + 1, 7].
torch::Tensor subdivide_path(const torch::Tensor& poses, int64_t subdivisions);

struct JitterOptions {
  std::string index_path;    // empty: <dataset root>/evaluation_index.json
  int64_t max_scenes = 0;    // 0: every scene of the index
  int64_t max_frames = 16;   // the scene's frames from its first context view on, at most this many
  int64_t subdivisions = 4;  // renders per step between two frames
  torch::Device device = torch::kCPU;
  bool bf16 = false;
};

struct JitterSummary {
  int64_t scenes = 0, renders = 0;
  double jitter = 0;  // wobble, pixels per frame² (mean over scenes)
  double speed = 0;   // the rendered picture's RMS motion, pixels per frame (mean over scenes)
  nlohmann::json to_json() const;
};

// Renders each indexed scene's path at its real cameras through the model's camera control (UP-LVSM's pose mapper,
// or the posed models' cameras) from the scene's context views, and measures the jitter.
JitterSummary measure_jitter(model::NovelViewModel& net, const data::ChunkDataset& dataset,
                             const data::PreprocessOptions& prep, const JitterOptions& options);

}  // namespace uplvsm::eval
