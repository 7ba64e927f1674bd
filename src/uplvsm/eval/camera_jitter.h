// Jitter of camera-controlled rendering (Less3Depend #6: the linear mapper "jitters"): what a viewer sees as
// flicker when a model renders a smooth real camera path. Along a scene's own camera sequence, jitter is the RMS of
// the frame-to-frame change of the renders beyond the ground truth's own change,
//   J = mean_t RMS((r[t+1] - r[t]) - (g[t+1] - g[t])),
// in 8-bit grey levels. An error that stays put from frame to frame (a blur, a colour cast, a constant offset)
// costs nothing; a latent camera that wobbles around the true path, or a render that changes where the scene does
// not, does. PSNR scores each frame alone and cannot see it.
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>
#include <string>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/model/novel_view_model.h"

namespace uplvsm::eval {

// rendered, truth: [T, 3, H, W] in [0, 1], T >= 2 -> J in grey levels (x 255).
double temporal_jitter(const torch::Tensor& rendered, const torch::Tensor& truth);

struct JitterOptions {
  std::string index_path;  // empty: <dataset root>/evaluation_index.json
  int64_t max_scenes = 0;  // 0: every scene of the index
  int64_t max_frames = 48;  // the path: the scene's frames from its first context view on, at most this many
  torch::Device device = torch::kCPU;
  bool bf16 = false;
};

struct JitterSummary {
  int64_t scenes = 0, frames = 0;
  double jitter = 0;      // mean over scenes, grey levels
  double truth_change = 0;  // the ground truth's own frame-to-frame change (RMS), for scale
  nlohmann::json to_json() const;
};

// Renders each indexed scene's ordered frames at their real cameras through the model's camera control (UP-LVSM's
// pose mapper, or the posed models' cameras) from the scene's context views, and measures the jitter.
JitterSummary measure_jitter(model::NovelViewModel& net, const data::ChunkDataset& dataset,
                             const data::PreprocessOptions& prep, const JitterOptions& options);

}  // namespace uplvsm::eval
