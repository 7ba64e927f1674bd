// libFuzzer target: the JSON (and COLMAP text) readers of the data layer. The first byte picks the reader, the rest
// is the file. Any exception is a clean rejection; a crash, a sanitizer report or a hang is a bug.
#include <cstdint>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "fuzz_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/data/lvsm_layout.h"
#include "uplvsm/data/scene_import.h"
#include "uplvsm/data/subset.h"

namespace {

using namespace uplvsm;

void run_reader(uint8_t which, const uint8_t* data, size_t size) {
  namespace fs = std::filesystem;
  const auto split = fuzz::scratch_dir() / "split";
  std::vector<std::string> warnings;
  switch (which % 9) {
    case 0: data::read_eval_index(fuzz::write_scratch("evaluation_index.json", data, size)); break;
    case 1:
      fs::create_directories(split / "metadata");
      data::read_lvsm_metadata(fuzz::write_scratch("split/metadata/scene.json", data, size));
      break;
    case 2: data::read_subset_manifest(fuzz::write_scratch("subset.json", data, size)); break;
    case 3:
      fs::create_directories(split);
      fuzz::write_scratch("split/index.json", data, size);
      data::read_chunk_index(split.string());
      break;
    case 4:
      fs::create_directories(split);
      fuzz::write_scratch("split/unposed.json", data, size);
      data::read_unposed_keys(split.string());
      fs::remove(split / "unposed.json");
      break;
    case 5: data::read_colmap_cameras(fuzz::write_scratch("cameras.txt", data, size), &warnings); break;
    case 6: data::read_transforms(fuzz::write_scratch("transforms.json", data, size), &warnings); break;
    case 7: data::read_colmap_images(fuzz::write_scratch("images.txt", data, size)); break;
    default: data::read_full_list(fuzz::write_scratch("full_list.txt", data, size));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  try {
    run_reader(data[0], data + 1, size - 1);
  } catch (const std::exception&) {
  }
  return 0;
}
