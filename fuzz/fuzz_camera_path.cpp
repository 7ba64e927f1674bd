// libFuzzer target: the camera-path JSON of `uplvsm render --trajectory FILE`. Any exception is a clean rejection;
// a crash, a sanitizer report or a hang is a bug.
#include <cstdint>
#include <exception>

#include "fuzz_util.h"
#include "uplvsm/render/trajectory.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    uplvsm::render::read_camera_path(uplvsm::fuzz::write_scratch("path.json", data, size));
  } catch (const std::exception&) {
  }
  return 0;
}
