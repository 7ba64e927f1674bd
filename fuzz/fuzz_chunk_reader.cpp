// libFuzzer target: a pixelSplat chunk (torch.save zip + pickle) through read_chunk, then every frame's image
// header and EXIF focal length and the first frame's decode, as the loader and `dataset import` would. Any exception is
// a clean rejection; a crash, a sanitizer report or a hang is a bug.
#include <cstdint>
#include <exception>

#include "fuzz_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/scene_import.h"
#include "uplvsm/io/image.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = uplvsm::fuzz::write_scratch("chunk.torch", data, size);
  try {
    for (const auto& scene : uplvsm::data::read_chunk(path)) {
      for (const auto& bytes : scene.images) {
        try {
          const auto [h, w] = uplvsm::io::image_size(bytes.data_ptr<uint8_t>(), bytes.numel(), "fuzz");
          uplvsm::data::exif_intrinsics(bytes.data_ptr<uint8_t>(), bytes.numel(), w, h);  // as `dataset import`
        } catch (const std::exception&) {
        }
      }
      if (!scene.images.empty() && scene.images[0].numel() < (1 << 20)) {
        try {
          uplvsm::io::decode_image(scene.images[0].data_ptr<uint8_t>(), scene.images[0].numel(), "fuzz");
        } catch (const std::exception&) {
        }
      }
    }
  } catch (const std::exception&) {
  }
  return 0;
}
