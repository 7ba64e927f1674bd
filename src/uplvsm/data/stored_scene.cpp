#include "uplvsm/data/stored_scene.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <stdexcept>
#include <utility>

#include "uplvsm/data/lvsm_layout.h"
#include "uplvsm/io/atomic_file.h"

namespace uplvsm::data {
namespace {

class ChunkScene : public StoredScene {
 public:
  explicit ChunkScene(RawScene scene) : scene_(std::move(scene)) {}
  const std::string& key() const override { return scene_.key; }
  int64_t num_frames() const override { return static_cast<int64_t>(scene_.images.size()); }
  torch::Tensor frame_bytes(int64_t f) const override { return scene_.images.at(f); }
  torch::Tensor camera_row(int64_t f, int, int) const override { return scene_.cameras[f]; }
  RawScene raw() const override { return scene_; }  // a copy sharing the tensors' storage (read-only use expected)
  int64_t bytes() const override {
    int64_t n = 0;
    for (const auto& image : scene_.images) n += image.numel();
    return n;
  }

 private:
  RawScene scene_;
};

class LvsmScene : public StoredScene {
 public:
  explicit LvsmScene(std::string path) : path_(std::move(path)), meta_(read_lvsm_metadata(path_)) {
    if (meta_.key != std::filesystem::path(path_).stem().string())
      throw std::runtime_error(
          fmt::format("LVSM metadata {}: scene_name '{}' differs from the file name", path_, meta_.key));
  }
  const std::string& key() const override { return meta_.key; }
  int64_t num_frames() const override { return meta_.size(); }
  torch::Tensor frame_bytes(int64_t f) const override {
    const auto bytes = io::read_file(meta_.image_paths.at(f));
    auto t = torch::empty({static_cast<int64_t>(bytes.size())}, torch::kUInt8);
    std::copy(bytes.begin(), bytes.end(), t.data_ptr<uint8_t>());
    return t;
  }
  torch::Tensor camera_row(int64_t f, int height, int width) const override {
    return lvsm_camera_row(meta_, f, height, width);
  }
  RawScene raw() const override { return read_lvsm_scene(path_); }
  int64_t bytes() const override { return 256 * meta_.size(); }  // paths and cameras: small beside images

 private:
  std::string path_;
  LvsmSceneMetadata meta_;
};

}  // namespace

std::unique_ptr<const StoredScene> chunk_scene(RawScene scene) {
  return std::make_unique<ChunkScene>(std::move(scene));
}

std::unique_ptr<const StoredScene> lvsm_scene(const std::string& metadata_path) {
  return std::make_unique<LvsmScene>(metadata_path);
}

}  // namespace uplvsm::data
