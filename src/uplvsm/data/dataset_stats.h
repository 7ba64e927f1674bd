// `uplvsm dataset stats`: what a split holds (chunks or LVSM layout), read from the image headers without decoding
// pixels: scenes, chunks, frames per scene, image sizes, and the frames the loader will skip or refuse (another size
// than frame 0, as pixelSplat skips; non-finite cameras).
#pragma once
#include <cstdint>
#include <functional>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

namespace uplvsm::data {

struct DatasetStats {
  std::string layout;                          // "chunks" or "lvsm"
  int64_t scenes = 0, chunks = 0, frames = 0;  // chunks: chunk files (LVSM layout: metadata files)
  int64_t min_frames = 0, max_frames = 0;
  double mean_frames = 0;
  std::map<std::string, int64_t> image_sizes;  // "HxW" -> frames
  int64_t off_size_frames = 0;      // frames of another size than their scene's frame 0 (skipped by the loader)
  int64_t nonfinite_cameras = 0;    // frames with a NaN/Inf camera value (refused by the loader)
  int64_t scenes_shorter_than = 0;  // scenes with fewer frames than `min_frames_needed`
  int64_t min_frames_needed = 0;
  int64_t unposed_scenes = 0;  // imported without poses (unposed.json): unusable where ground truth is needed
};

// progress(done, total) after each scene.
DatasetStats dataset_stats(const std::string& root, const std::string& split, int64_t min_frames_needed,
                           const std::function<void(int64_t, int64_t)>& progress = {});
nlohmann::json to_json(const DatasetStats& stats);

}  // namespace uplvsm::data
