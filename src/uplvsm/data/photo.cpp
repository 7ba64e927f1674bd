#include "uplvsm/data/photo.h"

#include <cmath>
#include <stdexcept>

#include "uplvsm/io/image.h"

namespace uplvsm::data {

namespace {

// The camera row of a W x H photo: square pixels, principal point at the centre, identity world-to-camera.
torch::Tensor photo_camera(double fov_degrees, double width, double height) {
  const double fx_norm = 0.5 / std::tan(fov_degrees * M_PI / 360.0);
  auto cam = torch::zeros({1, 18});
  cam[0][0] = fx_norm;
  cam[0][1] = fx_norm * width / height;
  cam[0][2] = 0.5;
  cam[0][3] = 0.5;
  for (int i = 0; i < 3; ++i) cam[0][6 + 5 * i] = 1.0;
  return cam;
}

}  // namespace

Views load_photos(const std::vector<std::string>& paths, double fov_degrees, const PreprocessOptions& opt) {
  if (paths.empty()) throw std::invalid_argument("load_photos: no photo given");
  if (!(fov_degrees > 0 && fov_degrees < 180))
    throw std::invalid_argument("load_photos: field of view must be in (0, 180) degrees, got " +
                                std::to_string(fov_degrees));
  std::vector<torch::Tensor> images, fxfycxcy, c2w;
  for (const auto& path : paths) {
    auto img = io::read_image(path);
    auto view = preprocess({img}, photo_camera(fov_degrees, double(img.size(1)), double(img.size(0))), opt, path);
    if (!images.empty() && view.images.sizes() != images[0].sizes())
      throw std::runtime_error(path + ": preprocessed to " + c10::str(view.images.sizes()) + ", but " + paths[0] +
                               " to " + c10::str(images[0].sizes()) + " (photos of one scene need the same aspect)");
    images.push_back(view.images);
    fxfycxcy.push_back(view.fxfycxcy);
    c2w.push_back(view.c2w);
  }
  Views out{torch::cat(images), torch::cat(fxfycxcy), torch::cat(c2w), {}};
  for (size_t i = 0; i < paths.size(); ++i) out.frames.push_back(static_cast<int64_t>(i));
  return out;
}

}  // namespace uplvsm::data
