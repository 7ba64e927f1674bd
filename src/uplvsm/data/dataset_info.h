// <root>/dataset.json: what a dataset says about itself beyond its chunks. Today one fact matters to training and
// evaluation: whether a scene's frames are ordered along a camera path (video walkthroughs: RealEstate10K, the
// built-in rooms) or independent views of one scene (object renders: Objaverse-style, the built-in objects). The
// file is optional; without it frames are taken as ordered, the pixelSplat convention.
#pragma once
#include <string>

namespace uplvsm::data {

struct DatasetInfo {
  std::string generator;      // who wrote the dataset ("rooms", "objects", ...); empty when unknown
  bool ordered_views = true;  // "view_order": "ordered" | "unordered"
};

// Reads <root>/dataset.json; a missing file gives the defaults. Throws naming the file and field when present but
// malformed (not an object, unknown view_order).
DatasetInfo read_dataset_info(const std::string& root);
// Writes <root>/dataset.json atomically.
void write_dataset_info(const std::string& root, const DatasetInfo& info);

}  // namespace uplvsm::data
