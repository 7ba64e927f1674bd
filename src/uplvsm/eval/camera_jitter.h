// Jitter of camera-controlled rendering (Less3Depend #6: the linear mapper "jitters"): what a viewer sees as
// flicker when a model renders a smooth real camera path. The path: a held-out scene's own camera sequence from its
// first input view, each step between two frames cut into `subdivisions` (translation linear, rotation slerp), so
// that consecutive renders are close. Jitter is how much the renders' frame-to-frame change swings, relative to the
// change itself:
//   J = RMS_t,px(r[t+1] - 2 r[t] + r[t-1]) / RMS_t,px(r[t+1] - r[t]),
// per scene, then the mean over scenes. A renderer that follows the path steadily changes by about the same amount
// from frame to frame (J small: only the path's own turns); a latent camera that wobbles around the path, or content
// that pops in and out, makes the change swing (independent noise: sqrt 3; a render alternating between two images:
// 2). Dividing by the change keeps a map that moves the camera less from scoring as steadier. PSNR scores each frame
// alone and cannot tell. The ground truth has no frames between the dataset's, and its frames are far apart, so J
// reads the renders alone.
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>
#include <string>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/model/novel_view_model.h"

namespace uplvsm::eval {

// frames: [T >= 3, C, H, W] in [0, 1] -> J (0 for frames that do not change).
double temporal_jitter(const torch::Tensor& frames);
// The RMS frame-to-frame change of frames [T >= 2, C, H, W], in grey levels (x 255).
double temporal_change(const torch::Tensor& frames);

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
  double jitter = 0;  // mean over scenes
  double change = 0;  // the renders' RMS frame-to-frame change, grey levels (mean over scenes)
  nlohmann::json to_json() const;
};

// Renders each indexed scene's path at its real cameras through the model's camera control (UP-LVSM's pose mapper,
// or the posed models' cameras) from the scene's context views, and measures the jitter.
JitterSummary measure_jitter(model::NovelViewModel& net, const data::ChunkDataset& dataset,
                             const data::PreprocessOptions& prep, const JitterOptions& options);

}  // namespace uplvsm::eval
