// pixelSplat chunk datasets (RealEstate10K / ACID layout): root/{train,test}/NNNNNN.torch, each a torch.save'd
// list of scene dicts, plus index.json {key: chunk file}. Reading, writing (readable by Python's torch.load) and a
// thread-safe indexed dataset with a small LRU cache of parsed chunks, which also reads a split in the LVSM layout
// (lvsm_layout.h) in place: the same scenes, views and errors without converting anything.
#pragma once
#include <torch/torch.h>

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include "uplvsm/data/chunk_cache.h"
#include "uplvsm/data/dataset_info.h"
#include "uplvsm/data/lvsm_layout.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/data/scene.h"
#include "uplvsm/data/stored_scene.h"

namespace uplvsm::data {

// A requested frame decodes to another size than frame 0 of its scene. pixelSplat skips such frames; callers
// catch this, count/log the skip and pick other views or another scene.
struct BadFrameError : std::runtime_error {
  std::string scene_key;
  int64_t frame = -1;
  int expected_height = 0, expected_width = 0;  // frame 0 of the scene
  int height = 0, width = 0;                    // the bad frame
  BadFrameError(const std::string& message, std::string key, int64_t frame_index, int exp_h, int exp_w, int h, int w)
      : std::runtime_error(message),
        scene_key(std::move(key)),
        frame(frame_index),
        expected_height(exp_h),
        expected_width(exp_w),
        height(h),
        width(w) {}
};

// Writes scenes as one chunk (torch.save format: list of dicts url/timestamps/cameras/images/key), atomically.
// Validates every scene first (same rules as read_chunk).
void write_chunk(const std::string& path, const std::vector<RawScene>& scenes);

// Reads a chunk; throws std::runtime_error naming the file, scene and field for: unreadable/truncated file,
// missing key, wrong type, wrong dtype or shape (cameras must be [N,18], timestamps [N]), image count != N.
// Floating-point cameras of another precision are converted to float32; JPEG bytes are not decoded here.
std::vector<RawScene> read_chunk(const std::string& path);

// Reads root/<split>/index.json, or, when absent, maps every *.torch file of the folder (reading them).
// Returns key -> chunk file name (relative to the split folder).
std::map<std::string, std::string> read_chunk_index(const std::string& split_dir);

// Writes root/<split>/index.json {key: chunk file name} atomically.
void write_chunk_index(const std::string& split_dir, const std::map<std::string, std::string>& index);

// Scene keys of a split whose cameras are placeholders (imported photos without poses): <split>/unposed.json, a
// JSON array of keys; empty when the file is absent.
std::vector<std::string> read_unposed_keys(const std::string& split_dir);

// What load_views does with a requested frame of another size than frame 0 of its scene.
enum class FrameSizePolicy {
  Skip,    // pixelSplat: BadFrameError (the caller counts the skip and picks other views or another scene)
  Resize,  // the official dataset: every frame resized from its own size (preprocess), counted in resized_frames
};

class ChunkDataset {
 public:
  enum class Layout { Chunks, Lvsm };

  // root/split holds chunks (index.json or *.torch) or the LVSM layout (full_list.txt or metadata/); chunks win
  // when both are there. Parsed chunks are kept while they fit in `cache_bytes`, and at least `cache_chunks` of
  // them (a RealEstate10K chunk is ~100 MB of JPEG bytes); the LVSM layout keeps at least 16x as many scenes'
  // metadata (a few kB each, images are read per request).
  ChunkDataset(std::string root, std::string split, int cache_chunks = 4, int64_t cache_bytes = kChunkCacheBytes);

  Layout layout() const { return layout_; }
  // <root>/dataset.json (whether frames are ordered; defaults when the file is absent).
  const DatasetInfo& info() const { return info_; }
  // Keep only these scenes (a subset manifest), in the dataset's order. Throws naming the first keys missing.
  void keep_only(const std::vector<std::string>& keys);
  // False for scenes listed in <split>/unposed.json: their cameras must not be used as ground truth.
  bool poses_known(int64_t i) const;
  // The chunk file name (chunks) or metadata JSON path (LVSM) scene i is read from.
  const std::string& chunk_name(int64_t i) const;
  // Scenes are ordered by chunk, so each chunk is a contiguous range of indices: the first index of every chunk,
  // ascending (the loader shuffles whole chunks without comparing names per batch).
  const std::vector<int64_t>& chunk_starts() const { return chunk_starts_; }
  // Chunk files (LVSM: metadata files) parsed so far, including re-reads of chunks the cache had evicted.
  int64_t chunk_reads() const { return chunk_reads_.load(); }

  int64_t size() const { return static_cast<int64_t>(entries_.size()); }
  const std::string& key(int64_t i) const;
  int64_t num_frames(int64_t i) const;         // may load the scene's chunk the first time
  int64_t find(const std::string& key) const;  // -1 if absent
  RawScene scene(int64_t i) const;
  std::string chunk_path(int64_t i) const;
  const std::string& root() const { return root_; }
  const std::string& split() const { return split_; }

  // Decodes the requested frames (any order, repeats allowed) and preprocesses them; SceneViews.frames = frames.
  // Throws std::runtime_error for a frame index out of range, an undecodable image or a NaN/Inf camera (naming the
  // scene key and frame), and BadFrameError for a frame of another size than frame 0 under FrameSizePolicy::Skip;
  // under Resize only for one whose output size differs from the first requested frame's (another aspect ratio
  // without a square crop: the frames could not be stacked), the others counted in SceneViews.resized_frames.
  SceneViews load_views(int64_t i, const std::vector<int64_t>& frames, const PreprocessOptions& opt,
                        FrameSizePolicy other_sizes = FrameSizePolicy::Skip) const;

 private:
  struct Entry {
    std::string key;
    std::string chunk;  // file name inside the split folder
  };
  // One cache entry: a chunk file's scenes, or one LVSM scene (its metadata file).
  struct LoadedChunk {
    std::vector<std::unique_ptr<const StoredScene>> scenes;
    std::unordered_map<std::string, size_t> by_key;
  };
  using ChunkPtr = std::shared_ptr<const LoadedChunk>;

  std::shared_ptr<const LoadedChunk> load_chunk(const std::string& chunk) const;
  std::pair<ChunkPtr, int64_t> read_loaded_chunk(const std::string& chunk) const;  // the chunk and its bytes
  const StoredScene& scene_ref(int64_t i, ChunkPtr& holder) const;
  void check_index(int64_t i) const;
  void rebuild_lookup();

  std::string root_, split_, dir_;
  Layout layout_ = Layout::Chunks;
  DatasetInfo info_;
  std::set<std::string> unposed_;
  std::vector<Entry> entries_;  // sorted by (chunk file, key): deterministic without reading the chunks
  std::unordered_map<std::string, int64_t> by_key_;
  std::unique_ptr<std::atomic<int64_t>[]> num_frames_;  // -1 until the scene's chunk was read
  std::vector<int64_t> chunk_starts_;

  std::unique_ptr<ChunkCache<LoadedChunk>> cache_;
  mutable std::atomic<int64_t> chunk_reads_{0};
};

}  // namespace uplvsm::data
