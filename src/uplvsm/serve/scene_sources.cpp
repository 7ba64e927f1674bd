#include "uplvsm/serve/scene_sources.h"

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/io/image.h"
#include "uplvsm/serve/http_error.h"

namespace uplvsm::serve {

namespace fs = std::filesystem;

SceneCatalog::SceneCatalog(const std::string& root, const std::string& split, const std::string& index_path,
                           const data::PreprocessOptions& prep, size_t max_scenes)
    : dataset_(std::make_unique<data::ChunkDataset>(root, split)), prep_(prep) {
  auto add = [&](int64_t index, std::vector<int64_t> context) {
    CatalogScene s{std::to_string(scenes_.size()), dataset_->key(index), index, std::move(context)};
    by_id_[s.id] = scenes_.size();
    scenes_.push_back(std::move(s));
  };
  const std::string index = index_path.empty() ? (fs::path(root) / "evaluation_index.json").string() : index_path;
  if (fs::exists(index)) {
    for (const auto& e : data::read_eval_index(index)) {
      if (scenes_.size() >= max_scenes) break;
      const int64_t i = dataset_->find(e.key);
      if (i >= 0 && e.context.size() >= 2) add(i, {e.context[0], e.context[1]});
    }
  } else if (!index_path.empty()) {
    throw std::runtime_error("serve: evaluation index " + index_path + " does not exist");
  } else {
    for (int64_t i = 0; i < dataset_->size() && scenes_.size() < max_scenes; ++i) add(i, {});
  }
  if (scenes_.empty()) throw std::runtime_error("serve: no scene of " + index + " is in " + root + "/" + split);
}

SceneCatalog::SceneCatalog() = default;
SceneCatalog::~SceneCatalog() = default;

const CatalogScene* SceneCatalog::find(const std::string& id) const {
  auto it = by_id_.find(id);
  return it == by_id_.end() ? nullptr : &scenes_[it->second];
}

data::SceneViews SceneCatalog::load(const CatalogScene& scene, bool* posed) const {
  auto context = scene.context;
  if (context.empty()) context = {0, dataset_->num_frames(scene.index) / 2};
  if (posed) *posed = dataset_->poses_known(scene.index);
  return dataset_->load_views(scene.index, context, prep_);
}

std::vector<uint8_t> SceneCatalog::thumbnail(const CatalogScene& scene) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = thumbnails_.find(scene.id);
    if (it != thumbnails_.end()) return it->second;
  }
  auto jpeg = views_jpeg(load(scene, nullptr).images, 85);
  std::lock_guard<std::mutex> lock(mutex_);
  return thumbnails_.emplace(scene.id, std::move(jpeg)).first->second;
}

data::Photo decode_upload(const std::string& bytes, const UploadLimits& limits, std::optional<double> fov_deg,
                          const std::string& what) {
  if (bytes.size() > limits.max_file_bytes)
    throw HttpError(413, fmt::format("{}: {} bytes, more than the {} bytes allowed per photo", what, bytes.size(),
                                     limits.max_file_bytes));
  const auto* data = reinterpret_cast<const uint8_t*>(bytes.data());
  std::pair<int, int> hw;
  try {
    hw = io::image_size(data, bytes.size(), what);
  } catch (const std::exception& e) {
    throw HttpError(400, std::string(e.what()) + " (expected a PNG or JPEG photo)");
  }
  const int64_t h = hw.first, w = hw.second;
  if (h <= 0 || w <= 0) throw HttpError(400, fmt::format("{}: invalid image size {}x{}", what, w, h));
  // The server's limit, or the process-wide decompression-bomb limit (--max-image-pixels) when that is lower.
  const int64_t process_limit = io::max_image_pixels();
  const int64_t max_pixels = process_limit > 0 ? std::min(limits.max_pixels, process_limit) : limits.max_pixels;
  if (h * w > max_pixels)
    throw HttpError(413, fmt::format("{}: {}x{} pixels, more than the {} allowed", what, w, h, max_pixels));
  try {
    return data::decode_photo(data, bytes.size(), fov_deg, what);
  } catch (const std::exception& e) {
    throw HttpError(400, e.what());
  }
}

std::vector<uint8_t> views_jpeg(const torch::Tensor& images, int quality) {
  return io::encode_jpeg(io::to_u8_hwc(torch::cat({images[0], images[1]}, 2)), quality);
}

}  // namespace uplvsm::serve
