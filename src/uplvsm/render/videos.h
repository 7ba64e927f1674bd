// `uplvsm render` as a library call: a novel-view video per scene, from dataset scenes (their evaluation context
// views) or from two photos, along the interpolation between the inputs, a preset (orbit, spiral, dolly) or a
// camera-path file; each video's frames, MP4, GIF and inputs in its folder, and a listing of them.
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "uplvsm/core/config.h"
#include "uplvsm/data/photo.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/model/novel_view_model.h"

namespace uplvsm::render {

struct VideoOptions {
  std::string out;                               // output directory (videos.json; a folder per dataset scene)
  std::string trajectory = "interpolate";        // interpolate, orbit, spiral, dolly, or a camera-path JSON file
  double focus = 2.0, radius = 0.5, arc = 30.0;  // the presets' (render/trajectory.h)
  int64_t frames = 24;
  double fps = 12;
  bool side_by_side = false;  // frames show [input 0 | input 1 | render]
  bool bf16 = false;          // the model under bf16 autocast
  // Dataset scenes: the first `scenes` of the evaluation index (default <data>/evaluation_index.json) in the split.
  std::string data, split = "test", index;
  int64_t scenes = 1;
};

// One video of `photos` (two, without cameras) into options.out, or else of the dataset scenes; writes
// <out>/videos.json and returns its listing (name, dir, mp4, gif, frames, size, trajectory; the photos' EXIF
// readings for photos). Frame counts that cannot fit in memory are refused before rendering.
nlohmann::json render_videos(model::NovelViewModel& net, const Config& config, const VideoOptions& options,
                             const std::vector<data::Photo>& photos = {});

}  // namespace uplvsm::render
