// `uplvsm dataset import` as a library call: one imported scene (data/scene_import.h) written into a dataset root
// as the pixelSplat chunk ROOT/SPLIT/<scene>.torch, merged into the split's index.json, optionally into
// ROOT/evaluation_index.json (the file `eval` and `render` read by default), and, for photos without poses, listed
// in ROOT/SPLIT/unposed.json so tools needing real poses can refuse it. Every file is checked before any is written.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "uplvsm/data/scene_import.h"

namespace uplvsm::data {

struct DatasetImportOptions {
  SceneImportOptions import;
  std::string out, split = "test";       // the dataset root and split written into
  std::vector<int64_t> context, target;  // an evaluation entry (both or neither)
  bool force = false;                    // replace this scene's chunk and entries
};

struct DatasetImport {
  ImportedScene result;
  std::string chunk_path;
  std::string stale_eval;  // a warning: an evaluation entry kept that names frames past the scene's end
};

DatasetImport import_into_dataset(const DatasetImportOptions& options);

}  // namespace uplvsm::data
