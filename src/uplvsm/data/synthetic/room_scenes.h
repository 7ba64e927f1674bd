// The built-in dataset: deterministic, seedable RealEstate10K-like indoor walkthroughs, ray-cast on the CPU (a
// textured room box with a plank floor, 3-6 textured spheres and boxes, Lambertian shading from one directional
// light plus ambient), written as pixelSplat chunks with an evaluation index, so the whole pipeline can run
// without downloading anything.
#pragma once
#include <torch/torch.h>

#include <cstdint>
#include <string>

#include "uplvsm/data/scene.h"

namespace uplvsm::data {

struct RoomSceneOptions {
  int height = 72;
  int width = 128;
  int frames = 32;
  double frame_spacing = 1.0;  // scales the camera motion (translation and rotation) per frame
  double texture_scale = 1.0;  // scales every surface pattern's size (periods, planks); colours are unchanged
  int jpeg_quality = 90;
  int eval_gap = 0;            // frames between the two evaluation context views; 0: frames / 2
};

// A rendered scene with what the JPEG bytes lose: the exact pixels and the ray-cast depth.
struct RoomRender {
  RawScene scene;           // what goes into the chunk (JPEG bytes, 18-float cameras)
  torch::Tensor images;     // uint8 [N,H,W,3], before JPEG compression
  torch::Tensor depth;      // float32 [N,H,W], camera z of the surface seen through each pixel centre
  torch::Tensor fxfycxcy;   // float32 [N,4], pixels
  torch::Tensor c2w;        // float32 [N,4,4], the rendering cameras (float64 ones cast)
};

// Key of a scene: 16 lowercase hex characters, a hash of the seed.
std::string room_scene_key(uint64_t seed);

// Seed of scene `index` of a split (0 train, 1 test) of a dataset seeded `dataset_seed`; different splits never
// share a seed.
uint64_t builtin_scene_seed(uint64_t dataset_seed, int split, int64_t index);

// Renders one scene (frames in parallel). key = room_scene_key(seed), url "builtin://room/<seed>",
// timestamps 100000 * i, cameras with the world-to-camera matrices of the rendering cameras.
RoomRender render_room(uint64_t seed, const RoomSceneOptions& opt);
RawScene render_room_scene(uint64_t seed, const RoomSceneOptions& opt);

// Fraction of frame a's pixels whose ray-cast 3D point projects in front of camera b and inside its image
// (no occlusion test), averaged over both directions (a->b and b->a). Same definition as the re10k fixture.
double context_overlap(const RoomRender& r, int64_t a, int64_t b);

// Writes root/train and root/test (chunks of `scenes_per_chunk` scenes, NNNNNN.torch, and index.json) and
// root/evaluation_index.json for the test scenes: context [f, f+gap] (gap = eval_gap or frames/2), three sorted
// targets strictly between them, and the context overlap. Scenes render in parallel.
void write_builtin_dataset(const std::string& root, int num_train, int num_test, uint64_t seed,
                           const RoomSceneOptions& opt, int scenes_per_chunk = 64);

}  // namespace uplvsm::data
