// The built-in dataset: deterministic, seedable RealEstate10K-like indoor walkthroughs, ray-cast on the CPU (a
// textured room box with a plank floor, 3-6 textured spheres and boxes, Lambertian shading from one directional
// light plus ambient), written as pixelSplat chunks with an evaluation index, so the whole pipeline can run
// without downloading anything.
#pragma once
#include <torch/torch.h>

#include <cstdint>
#include <optional>
#include <string>

#include "uplvsm/core/config.h"
#include "uplvsm/data/synthetic/builtin_dataset.h"

namespace uplvsm::data {

struct RoomSceneOptions {
  int height = 72;
  int width = 128;
  int frames = 32;
  double frame_spacing = 1.0;  // scales the camera motion (translation and rotation) per frame
  double texture_scale = 1.0;  // scales every surface pattern's size (periods, planks); colours are unchanged
  int jpeg_quality = 90;
  int eval_gap = 0;  // frames between the two evaluation context views; 0: frames / 2
};

// The rooms a dataset config makes (make-dataset --config): size, frames, motion, texture and evaluation gap.
RoomSceneOptions room_scene_options(const DatasetConfig& c);

using RoomRender = SceneRender;

// Key of a scene: 16 lowercase hex characters, a hash of the seed.
std::string room_scene_key(uint64_t seed);

// Renders one scene (frames in parallel). key = room_scene_key(seed), url "builtin://room/<seed>",
// timestamps 100000 * i, cameras with the world-to-camera matrices of the rendering cameras.
RoomRender render_room(uint64_t seed, const RoomSceneOptions& opt);
RawScene render_room_scene(uint64_t seed, const RoomSceneOptions& opt);

// The same room (the seed and options it was rendered with: its objects and path depend on both) seen from any
// cameras c2w [N, 4, 4] (world, OpenCV axes), with the room's own intrinsics: the ground truth of a camera path that
// leaves the scene's frames, which only a procedural scene has.
RoomRender render_room_at(uint64_t seed, const RoomSceneOptions& opt, const torch::Tensor& c2w);
// The seed of a built-in room from its scene's url ("builtin://room/<seed>"); nullopt for any other scene.
std::optional<uint64_t> room_seed_from_url(const std::string& url);

// The room walkthroughs as a generator for write_generated_dataset (ordered views).
SceneGenerator room_generator(const RoomSceneOptions& opt);

// write_generated_dataset with room_generator: evaluation views are context [f, f+gap] (gap = eval_gap or
// frames/2), three sorted targets strictly between them, and the context overlap.
void write_builtin_dataset(const std::string& root, int num_train, int num_test, uint64_t seed,
                           const RoomSceneOptions& opt, int scenes_per_chunk = 64);

}  // namespace uplvsm::data
