// The EXIF focal length of a user's JPEG (read by io/exif.h) and the default field of view when there is none
// (scene_import.h): the last two sources of intrinsics import_scene (scene_import.cpp) falls back on.
#include <cmath>
#include <optional>

#include "uplvsm/data/scene_import.h"
#include "uplvsm/io/exif.h"

namespace uplvsm::data {

std::optional<PinholeIntrinsics> exif_intrinsics(const uint8_t* data, size_t size, int width, int height) {
  const auto focal = io::exif_focal_pixels(io::read_exif(data, size), width, height);
  if (!focal) return std::nullopt;
  return PinholeIntrinsics{focal->pixels, focal->pixels, 0.5 * width, 0.5 * height, width, height};
}

PinholeIntrinsics default_fov_intrinsics(int width, int height, double fov_deg) {
  const double f = 0.5 * width / std::tan(fov_deg * M_PI / 360.0);
  return {f, f, 0.5 * width, 0.5 * height, width, height};
}

}  // namespace uplvsm::data
