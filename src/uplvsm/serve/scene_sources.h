// Where a viewer scene comes from: a dataset's scenes (the server's own numbered list; the client names a scene
// by that id, never by a path) with their two context views and thumbnails, or two photos a user uploaded,
// validated (size, format, pixel count from the header) before they are decoded.
#pragma once
#include <torch/torch.h>

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "uplvsm/data/photo.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/data/scene.h"

namespace uplvsm::data {
class ChunkDataset;
}

namespace uplvsm::serve {

struct CatalogScene {
  std::string id;                // "0", "1", ... in list order
  std::string name;              // the dataset's scene key
  int64_t index = -1;            // scene index in the dataset
  std::vector<int64_t> context;  // the evaluation index's context frames; empty: frames 0 and n/2
};

class SceneCatalog {
 public:
  SceneCatalog();  // no dataset: uploads only
  // Scenes of root/split, in the evaluation index's order when the index exists (context views from it), else in
  // dataset order; at most max_scenes.
  SceneCatalog(const std::string& root, const std::string& split, const std::string& index_path,
               const data::PreprocessOptions& prep, size_t max_scenes);
  ~SceneCatalog();

  const std::vector<CatalogScene>& scenes() const { return scenes_; }
  const CatalogScene* find(const std::string& id) const;  // nullptr when unknown
  // The two context views; posed = the dataset's cameras may be used (not a scene imported without poses).
  data::SceneViews load(const CatalogScene& scene, bool* posed) const;
  // JPEG of [view 0 | view 1], made on first use and kept.
  std::vector<uint8_t> thumbnail(const CatalogScene& scene);

 private:
  std::unique_ptr<data::ChunkDataset> dataset_;
  data::PreprocessOptions prep_;
  std::vector<CatalogScene> scenes_;
  std::map<std::string, size_t> by_id_;
  std::mutex mutex_;
  std::map<std::string, std::vector<uint8_t>> thumbnails_;
};

struct UploadLimits {
  size_t max_file_bytes = size_t{16} << 20;
  int64_t max_pixels = 40'000'000;  // width x height, read from the header before decoding
};

// One uploaded photo (PNG or JPEG bytes) -> upright uint8 [H, W, 3] and its field of view (data::decode_photo: the
// EXIF orientation applied; `fov_deg` when given, else the EXIF focal length's, else 60 degrees). Throws HttpError:
// 413 for a file or image over the limits (max_pixels, or io::max_image_pixels() when lower), 400 for anything that
// is not a decodable PNG/JPEG. `what` names the form field in messages.
data::Photo decode_upload(const std::string& bytes, const UploadLimits& limits, std::optional<double> fov_deg,
                          const std::string& what);

// Two views (inputs 0 and 1) side by side as one JPEG.
std::vector<uint8_t> views_jpeg(const torch::Tensor& images, int quality = 90);

}  // namespace uplvsm::serve
