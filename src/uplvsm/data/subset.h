// Training subsets (the paper's little / medium / large / full): a deterministic selection of a split's chunks or
// scenes, written as a manifest file that `uplvsm train --subset` reads. Chunk splits take the first N chunk files
// in name order (the official README's 76 / 304 / 1,216 / 4,866 chunks, which hold 1,202 / 4,121 / 16,449 / 66,033
// RealEstate10K scenes); LVSM-layout splits, which have no chunks, take the first N scenes in list order.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "uplvsm/data/chunk_dataset.h"

namespace uplvsm::data {

struct OfficialSubset {
  std::string name;
  int64_t chunks = 0;  // RealEstate10K train chunks
  int64_t scenes = 0;  // the scenes those chunks hold
};
const std::vector<OfficialSubset>& official_subsets();
std::optional<OfficialSubset> find_official_subset(const std::string& name);

struct SubsetManifest {
  std::string name;  // little / medium / large / full, or custom
  std::string split;
  std::string rule;                 // how it was selected, in words
  std::vector<std::string> chunks;  // chunk files (empty for LVSM-layout splits)
  std::vector<std::string> scenes;  // scene keys, in dataset order
  int64_t official_scenes = 0;      // the official subset's scene count, 0 for custom ones
};

// What to select: an official name, or a custom count of chunks or of scenes (exactly one of the three).
struct SubsetRequest {
  std::string name;
  int64_t chunks = 0, scenes = 0;
};

// Throws when the request is ambiguous or asks for more chunks/scenes than the split has (naming both counts);
// "full" takes everything there is.
SubsetManifest select_subset(const ChunkDataset& dataset, const SubsetRequest& request);

void write_subset_manifest(const std::string& path, const SubsetManifest& manifest);  // JSON, atomic
SubsetManifest read_subset_manifest(const std::string& path);                         // errors name the file and field

}  // namespace uplvsm::data
