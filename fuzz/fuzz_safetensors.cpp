// libFuzzer target: a safetensors file through the header reader, the full reader and our checkpoint reader
// (metadata config and training state), as `uplvsm eval --checkpoint` and `train --resume` would read it. Any
// exception is a clean rejection; a crash, a sanitizer report, a hang or an allocation beyond the limit is a bug.
#include <cstdint>
#include <exception>

#include "fuzz_util.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/io/safetensors.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = uplvsm::fuzz::write_scratch("weights.safetensors", data, size);
  try {
    uplvsm::io::read_safetensors_header(path);
    uplvsm::io::read_safetensors(path);
    uplvsm::io::read_checkpoint(path);
  } catch (const std::exception&) {
  }
  return 0;
}
