// libFuzzer target: JPEG and PNG bytes through the header reader and the decoder, under a pixel limit (as every
// decode in uplvsm is), the EXIF focal length lookup of `dataset import`, and a user's photo as `render --images`
// and the viewer's uploads read it (decoded, turned upright by its EXIF orientation, its field of view from EXIF).
// Any exception is a clean rejection; a crash, a sanitizer report, a hang or an allocation beyond the limit is a bug.
#include <cstdint>
#include <exception>

#include "uplvsm/data/photo.h"
#include "uplvsm/data/scene_import.h"
#include "uplvsm/io/image.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // 4 MP: a decode stays fast, while declared sizes up to 65535^2 (JPEG) or 2^31^2 (PNG) exercise the limit.
  uplvsm::io::set_max_image_pixels(1 << 22);
  try {
    const auto [h, w] = uplvsm::io::image_size(data, size, "fuzz");
    uplvsm::data::exif_intrinsics(data, size, w, h);
  } catch (const std::exception&) {
  }
  try {
    uplvsm::data::decode_photo(data, size, std::nullopt, "fuzz");
  } catch (const std::exception&) {
  }
  return 0;
}
