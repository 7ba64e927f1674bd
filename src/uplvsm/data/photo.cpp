#include "uplvsm/data/photo.h"

#include <stdexcept>

#include "uplvsm/io/image.h"

namespace uplvsm::data {

SceneViews load_photos(const std::vector<std::string>& paths, double fov_degrees, const PreprocessOptions& opt) {
  if (paths.empty()) throw std::invalid_argument("load_photos: no photo given");
  // The field of view is the caller's argument, not a property of a file: refused before any photo is read.
  if (!(fov_degrees > 0 && fov_degrees < 180))
    throw std::invalid_argument("load_photos: field of view must be in (0, 180) degrees, got " + c10::str(fov_degrees));
  std::vector<torch::Tensor> images, fxfycxcy, c2w;
  for (const auto& path : paths) {
    auto view = preprocess_photo(io::read_image(path), fov_degrees, opt, path);
    if (!images.empty() && view.images.sizes() != images[0].sizes())
      throw std::runtime_error(path + ": preprocessed to " + c10::str(view.images.sizes()) + ", but " + paths[0] +
                               " to " + c10::str(images[0].sizes()) + " (photos of one scene need the same aspect)");
    images.push_back(view.images);
    fxfycxcy.push_back(view.fxfycxcy);
    c2w.push_back(view.c2w);
  }
  SceneViews out{torch::cat(images), torch::cat(fxfycxcy), torch::cat(c2w), {}};
  for (size_t i = 0; i < paths.size(); ++i) out.frames.push_back(static_cast<int64_t>(i));
  return out;
}

}  // namespace uplvsm::data
