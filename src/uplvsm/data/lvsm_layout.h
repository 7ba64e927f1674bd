// The LVSM dataset layout, which the official UP-LVSM trains on (Haian-Jin/LVSM process_data.py):
//   <split>/images/<scene>/<idx:05d>.png, <split>/metadata/<scene>.json = {scene_name, frames: [{image_path,
//   fxfycxcy (pixels of that image), w2c (4x4)}]}, <split>/full_list.txt (the JSON paths, absolute, sorted).
// ChunkDataset reads this layout directly (only the requested frames' files); conversions both ways with pixelSplat
// chunks. Chunks made from this layout carry the PNG bytes unchanged (no
// JPEG re-encoding; pixelSplat's PIL-based readers and ours open both), so the round trip is lossless.
#pragma once
#include <torch/torch.h>

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "uplvsm/data/scene.h"

namespace uplvsm::data {

// One scene's metadata without its images: what a loader needs to read only the frames it wants.
struct LvsmSceneMetadata {
  std::string key;                              // scene_name, else the JSON's file stem
  std::vector<std::string> image_paths;         // resolved (see read_lvsm_metadata)
  std::vector<std::array<double, 4>> fxfycxcy;  // pixels of each frame's own image
  std::vector<std::array<double, 12>> w2c;      // 3x4 world-to-camera, row-major
  int64_t size() const { return static_cast<int64_t>(image_paths.size()); }
};

// Parses and validates a metadata JSON (errors name the file and field: missing field, non-finite or wrong-shaped
// camera). Image paths: absolute (official), else relative to the split folder, else to the JSON's folder; an
// absolute path that no longer exists (a moved dataset) falls back to <split>/images/<scene>/<file name>.
LvsmSceneMetadata read_lvsm_metadata(const std::string& metadata_path);

// The pixelSplat camera row (normalised intrinsics, 3x4 w2c) of frame i, given its image's size.
torch::Tensor lvsm_camera_row(const LvsmSceneMetadata& m, int64_t i, int height, int width);

// The scenes of an LVSM split: full_list.txt (stale absolute paths fall back to <split>/metadata/<file name>), or
// every metadata/*.json sorted when there is no list. Throws when the folder is no LVSM split or lists nothing.
std::vector<std::string> list_lvsm_scenes(const std::string& split_dir);
bool is_lvsm_split(const std::string& split_dir);  // has full_list.txt or metadata/

// One scene's metadata JSON -> RawScene: frames as their PNG/JPEG file bytes, cameras as pixelSplat rows (intrinsics
// normalised by each image's size, 3x4 w2c). Relative image paths resolve against the split folder, then the JSON's
// folder. Errors name the file and field (missing field, non-finite or wrong-shaped camera, unreadable image).
RawScene read_lvsm_scene(const std::string& metadata_path);

// Writes one scene under split_dir (frames decoded and re-encoded as PNG, as process_data.py does); returns the
// metadata path. Image paths in the JSON are absolute, as the official converter writes them.
std::string write_lvsm_scene(const std::string& split_dir, const RawScene& scene);

std::vector<std::string> read_full_list(const std::string& path);  // non-empty lines; relative ones resolved
void write_full_list(const std::string& split_dir, std::vector<std::string> metadata_paths);  // sorted, atomic

struct ConversionResult {
  int64_t scenes = 0, frames = 0, files = 0;  // files: chunks written (to chunks) or metadata files (to LVSM)
};
using ConversionProgress = std::function<void(int64_t scenes_done, int64_t scenes_total)>;

// pixelSplat split folder (index.json + *.torch) -> LVSM split folder.
ConversionResult chunks_to_lvsm(const std::string& chunk_split_dir, const std::string& lvsm_split_dir,
                                const ConversionProgress& progress = {});
// LVSM split folder (full_list.txt, or every metadata/*.json when absent) -> pixelSplat split folder with
// index.json, `scenes_per_chunk` scenes per NNNNNN.torch file.
ConversionResult lvsm_to_chunks(const std::string& lvsm_split_dir, const std::string& chunk_split_dir,
                                int64_t scenes_per_chunk, const ConversionProgress& progress = {});

}  // namespace uplvsm::data
