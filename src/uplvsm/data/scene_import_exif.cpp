// The EXIF focal length and orientation of a user's JPEG (read by io/exif.h) and the default field of view when
// there is none (scene_import.h): the last two sources of intrinsics import_scene (scene_import.cpp) falls back on.
#include <cmath>
#include <optional>
#include <string>
#include <utility>

#include "uplvsm/data/scene_import.h"
#include "uplvsm/io/exif.h"

namespace uplvsm::data {

std::optional<PinholeIntrinsics> exif_intrinsics(const uint8_t* data, size_t size, int width, int height,
                                                 std::string* rejected) {
  const auto focal = io::exif_focal_pixels(io::read_exif(data, size), width, height);
  if (!focal) return std::nullopt;
  if (!focal->usable()) {
    if (rejected) *rejected = focal->rejected;
    return std::nullopt;
  }
  return PinholeIntrinsics{focal->pixels, focal->pixels, 0.5 * width, 0.5 * height, width, height};
}

int exif_orientation(const uint8_t* data, size_t size) { return io::read_exif(data, size).orientation; }

PinholeIntrinsics upright_intrinsics(const PinholeIntrinsics& stored, int orientation) {
  if (orientation < 2 || orientation > 8) return stored;
  PinholeIntrinsics k = stored;
  const double w = stored.width, h = stored.height;
  // Where the stored principal point lands (io::apply_exif_orientation's turns and mirrors, in continuous pixels).
  if (orientation >= 5) {  // transposed first: x and y trade places
    std::swap(k.fx, k.fy);
    std::swap(k.width, k.height);
    k.cx = stored.cy, k.cy = stored.cx;
  }
  const bool flip_x = orientation == 2 || orientation == 3 || orientation == 6 || orientation == 7;
  const bool flip_y = orientation == 3 || orientation == 4 || orientation == 7 || orientation == 8;
  if (flip_x) k.cx = (orientation >= 5 ? h : w) - k.cx;
  if (flip_y) k.cy = (orientation >= 5 ? w : h) - k.cy;
  return k;
}

PinholeIntrinsics default_fov_intrinsics(int width, int height, double fov_deg) {
  const double f = 0.5 * width / std::tan(fov_deg * M_PI / 360.0);
  return {f, f, 0.5 * width, 0.5 * height, width, height};
}

}  // namespace uplvsm::data
