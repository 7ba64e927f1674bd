#include "uplvsm/data/dataset_stats.h"

#include <algorithm>
#include <set>

#include <fmt/format.h>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/io/image.h"

namespace uplvsm::data {

DatasetStats dataset_stats(const std::string& root, const std::string& split, int64_t min_frames_needed,
                           const std::function<void(int64_t, int64_t)>& progress) {
  ChunkDataset dataset(root, split, 1);
  DatasetStats st;
  st.layout = dataset.layout() == ChunkDataset::Layout::Lvsm ? "lvsm" : "chunks";
  st.scenes = dataset.size();
  st.min_frames_needed = min_frames_needed;
  std::set<std::string> chunks;
  for (int64_t i = 0; i < dataset.size(); ++i) {
    chunks.insert(dataset.chunk_path(i));
    const auto scene = dataset.scene(i);
    const int64_t n = static_cast<int64_t>(scene.images.size());
    st.frames += n;
    st.min_frames = i == 0 ? n : std::min(st.min_frames, n);
    st.max_frames = std::max(st.max_frames, n);
    if (n < min_frames_needed) ++st.scenes_shorter_than;
    if (!dataset.poses_known(i)) ++st.unposed_scenes;
    std::pair<int, int> first{-1, -1};
    for (int64_t f = 0; f < n; ++f) {
      const auto& bytes = scene.images[f];
      const auto size = io::image_size(bytes.data_ptr<uint8_t>(), bytes.numel(),
                                       fmt::format("{}: scene {} frame {}", dataset.chunk_path(i), scene.key, f));
      if (f == 0) first = size;
      if (size != first) ++st.off_size_frames;
      ++st.image_sizes[fmt::format("{}x{}", size.first, size.second)];
    }
    st.nonfinite_cameras += (~torch::isfinite(scene.cameras).all(1)).sum().item<int64_t>();
    if (progress) progress(i + 1, dataset.size());
  }
  st.chunks = static_cast<int64_t>(chunks.size());
  st.mean_frames = st.scenes ? static_cast<double>(st.frames) / static_cast<double>(st.scenes) : 0.0;
  return st;
}

nlohmann::json to_json(const DatasetStats& s) {
  return {{"layout", s.layout},
          {"scenes", s.scenes},
          {"chunks", s.chunks},
          {"frames", s.frames},
          {"frames_per_scene", {{"min", s.min_frames}, {"mean", s.mean_frames}, {"max", s.max_frames}}},
          {"image_sizes", s.image_sizes},
          {"off_size_frames", s.off_size_frames},
          {"nonfinite_camera_frames", s.nonfinite_cameras},
          {"scenes_shorter_than_needed", s.scenes_shorter_than},
          {"min_frames_needed", s.min_frames_needed},
          {"unposed_scenes", s.unposed_scenes}};
}

}  // namespace uplvsm::data
