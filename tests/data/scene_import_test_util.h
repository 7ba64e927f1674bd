// Helpers shared by the scene import tests (scene_import_test, scene_import_exif_test).
#pragma once
#include <cstdint>
#include <filesystem>
#include <vector>

#include "uplvsm/data/scene_import.h"
#include "uplvsm/io/atomic_file.h"

namespace uplvsm::test {

inline void write_bytes(const std::filesystem::path& path, const std::vector<uint8_t>& bytes) {
  std::filesystem::create_directories(path.parent_path());
  io::write_file_atomic(path.string(), bytes.data(), bytes.size());
}

// Field `field` (0..17, the chunk's camera row) of an imported scene's frame.
inline float cam(const data::ImportedScene& s, int64_t frame, int field) {
  return s.scene.cameras[frame][field].item<float>();
}

}  // namespace uplvsm::test
