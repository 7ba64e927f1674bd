// Camera paths with ground truth (`uplvsm study camera-paths`, issue 82): a user drives orbits, dollies and spirals
// that leave the range between the two input views, where the dataset has no frames to score against. The built-in
// rooms are procedural: the ray tracer renders the truth at any camera (data::render_room_at). Per held-out scene,
// the path of a render preset is placed in camera-control units around the first input view, the truth rendered and
// preprocessed as the dataset's frames are, and each frame rendered by the model's camera control (UP-LVSM's pose
// mapper, or a posed model's cameras) and, for UP-LVSM, by the estimator reading the true frame (the best its
// latent camera can do: the upper bound for any mapper). Each frame is scored (PSNR, SSIM) against its position
// along the inputs' baseline: inside the inputs' span (0 <= s <= 1) or beyond it; the wobble of each sequence is
// measured relative to the truth's own motion (eval::temporal_wobble).
#pragma once
#include <torch/torch.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/data/synthetic/room_scenes.h"
#include "uplvsm/model/novel_view_model.h"
#include "uplvsm/render/trajectory.h"

namespace uplvsm::study {

struct CameraPathsOptions {
  std::string trajectory = "dolly";              // a render preset (orbit, spiral, dolly) or a camera-path file
  int64_t frames = 24;                           // poses of the (looping) path
  render::PresetOptions preset{2.0, 1.5, 30.0};  // dolly 1.5 baselines forward and back: past both inputs
  std::string index_path;                        // empty: <dataset root>/evaluation_index.json
  int64_t max_scenes = 0;                        // 0: every scene of the index
  data::RoomSceneOptions room;  // the options the dataset's rooms were made with (checked on its frames)
  torch::Device device = torch::kCPU;
  bool bf16 = false;
  // UP-LVSM: also the estimator reading each true frame. It does not depend on the mapper, so runs that compare
  // mappers of one model render it once and leave it out of the others (half the time of each).
  bool estimator = true;
};

struct PathMethodScores {
  std::string method;  // "camera control" or "estimator reading the truth"
  double psnr_inside = NAN, psnr_beyond = NAN, ssim_inside = NAN, ssim_beyond = NAN;
  double wobble = 0;  // pixels per frame², relative to the truth's motion (mean over scenes)
};

struct PathFrameScore {
  std::string scene, method;
  int64_t frame = 0;
  double position = 0;  // along the baseline: 0 at input 0, 1 at input 1
  bool inside = false;
  double psnr = 0, ssim = 0;
};

// One scene's figures for one method: what a paired comparison of two methods resamples (study/
// camera_paths_summary.h). NaN where the scene's path has no frame inside (or beyond) the inputs' span.
struct PathSceneScore {
  std::string scene, method;
  double psnr = 0, psnr_inside = NAN, psnr_beyond = NAN, ssim_inside = NAN, ssim_beyond = NAN;
  double wobble = 0;  // pixels per frame², relative to the truth's motion
};

struct CameraPathsReport {
  int64_t scenes = 0, frames_inside = 0, frames_beyond = 0;
  std::vector<PathMethodScores> methods;
  std::vector<PathFrameScore> frames;
  std::vector<PathSceneScore> scene_scores;  // scene by scene, the methods in a fixed order
  nlohmann::json to_json() const;
};

// The path's poses [F, 7] (float32, camera-control units): the preset named by options.trajectory at options.frames
// poses, or a camera-path file (render::read_camera_path) in baseline units, its own frame count (a path recorded in
// latent units is refused: it has no real camera to render the truth at). A file's intrinsics are not read: the
// truth is the room seen with its dataset's.
torch::Tensor camera_path_poses(const CameraPathsOptions& options);

// Positions [F] (float64) of path poses [F, 7] (camera-control units) along the baseline to input 1's pose [7]:
// the projection of each camera centre, 0 at input 0 and 1 at input 1.
torch::Tensor baseline_position(const torch::Tensor& poses, const torch::Tensor& input1_pose);

// One scene's path: its inputs, the path's poses, the truth at them and where each lies along the baseline.
struct ScenePath {
  std::string key;
  data::SceneViews inputs;
  torch::Tensor poses, truth, fxfycxcy, position;  // [F, 7] f32, [F, 3, H, W], [F, 4], [F] f64
};
// The room of scene `index` (its evaluation entry `entry`) seen along options' path; refused when its input frames
// are not what options.room gives (another generator, other options): the truth would be another room's.
ScenePath scene_path(const data::ChunkDataset& dataset, int64_t index, const data::EvalEntry& entry,
                     const data::PreprocessOptions& prep, const CameraPathsOptions& options);

// `dataset`'s scenes must be built-in rooms made with options.room (checked: their input frames are re-rendered).
CameraPathsReport run_camera_paths(model::NovelViewModel& net, const data::ChunkDataset& dataset,
                                   const data::PreprocessOptions& prep, const CameraPathsOptions& options);

// camera_paths.json (the report without its frames), camera_paths.csv (one row per frame and method) and
// camera_paths_scenes.csv (one row per scene and method: scene,method,psnr,psnr_inside,psnr_beyond,ssim_inside,
// ssim_beyond,wobble; empty where NaN).
void write_camera_paths(const CameraPathsReport& report, const std::string& out_dir);

}  // namespace uplvsm::study
