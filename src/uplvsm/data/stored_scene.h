// One scene as its dataset layout stores it, behind the four things ChunkDataset reads from either layout: the frame
// count, a frame's encoded image bytes, its camera row (pixelSplat's: normalised intrinsics, 3x4 w2c) and the whole
// scene. A pixelSplat chunk holds its scenes' image bytes in memory; an LVSM scene is its metadata JSON, each frame
// read from its image file when asked for.
#pragma once
#include <torch/torch.h>

#include <cstdint>
#include <memory>
#include <string>

#include "uplvsm/data/scene.h"

namespace uplvsm::data {

class StoredScene {
 public:
  virtual ~StoredScene() = default;
  virtual const std::string& key() const = 0;
  virtual int64_t num_frames() const = 0;
  // Frame f's encoded image (JPEG or PNG), uint8 [n]; f must be in [0, num_frames()).
  virtual torch::Tensor frame_bytes(int64_t f) const = 0;
  // Frame f's pixelSplat camera row [18], given its decoded image's size (an LVSM camera is in that image's pixels).
  virtual torch::Tensor camera_row(int64_t f, int height, int width) const = 0;
  // Every frame's bytes and camera, as a chunk holds them.
  virtual RawScene raw() const = 0;
  // Bytes kept in memory while the scene is cached.
  virtual int64_t bytes() const = 0;
};

// A scene of a pixelSplat chunk (read_chunk): its frames' bytes are in memory.
std::unique_ptr<const StoredScene> chunk_scene(RawScene scene);

// The LVSM scene of a metadata JSON (lvsm_layout.h); throws when its scene_name differs from the file's stem, the
// key the dataset lists it under.
std::unique_ptr<const StoredScene> lvsm_scene(const std::string& metadata_path);

}  // namespace uplvsm::data
