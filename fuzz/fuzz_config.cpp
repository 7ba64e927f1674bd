// libFuzzer target: a run config (configs/*.json) through the parser and the consistency checks, as `uplvsm train
// --config` reads it. Any exception is a clean rejection; a crash, a sanitizer report or a hang is a bug.
#include <cstdint>
#include <exception>

#include "fuzz_util.h"
#include "uplvsm/core/config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const auto config = uplvsm::load_config(uplvsm::fuzz::write_scratch("config.json", data, size));
    uplvsm::config_from_json(uplvsm::config_to_json(config));  // what a checkpoint embeds reads back
  } catch (const std::exception&) {
  }
  return 0;
}
