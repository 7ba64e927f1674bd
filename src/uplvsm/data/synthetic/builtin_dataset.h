// What every built-in generator (room walkthroughs, object turntables) does the same way: render a scene's frames
// from a per-pixel tracer into JPEG bytes + cameras, measure how much two views overlap, and write a seeded
// dataset of train/test chunks with an evaluation index and a dataset.json that says whether frames are ordered.
#pragma once
#include <torch/torch.h>

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "uplvsm/data/eval_index.h"
#include "uplvsm/data/scene.h"
#include "uplvsm/data/synthetic/shading.h"

namespace uplvsm::data {

// A rendered scene with what the JPEG bytes lose: the exact pixels and the ray-cast depth.
struct SceneRender {
  RawScene scene;          // what goes into the chunk (JPEG bytes, 18-float cameras)
  torch::Tensor images;    // uint8 [N,H,W,3], before JPEG compression
  torch::Tensor depth;     // float32 [N,H,W], camera z of the surface seen through each pixel centre (inf: none)
  torch::Tensor fxfycxcy;  // float32 [N,4], pixels
  torch::Tensor c2w;       // float32 [N,4,4], the rendering cameras (float64 ones cast)
};

// Colour (0..1) of pixel (u, v) of a camera; writes the camera z-depth of the surface hit (inf for none).
using PixelTracer = std::function<synthetic::Vec3(const synthetic::Camera& camera, int u, int v, float* depth)>;

// Renders every camera (frames in parallel), JPEG-encodes the frames and fills the chunk record: cameras from
// focal length fx (square pixels, principal point at the centre), timestamps 100000 * i.
SceneRender render_scene(const std::vector<synthetic::Camera>& cameras, double fx, int height, int width,
                         int jpeg_quality, const PixelTracer& trace, std::string key, std::string url);

// Fraction of frame a's pixels (with a surface) whose ray-cast 3D point projects in front of camera b and inside
// its image (no occlusion test), averaged over both directions (a->b and b->a). Same definition as the re10k
// fixture.
double context_overlap(const SceneRender& r, int64_t a, int64_t b);

// Runs fn(i) for i in [0, n) on at::get_num_threads() threads; nested calls run serially. Results must not depend
// on which thread runs which i.
void parallel_for_each(int64_t n, const std::function<void(int64_t)>& fn);

// Key of a scene: 16 lowercase hex characters, a hash of the seed.
std::string builtin_scene_key(uint64_t seed);

// Seed of scene `index` of a split (0 train, 1 test) of a dataset seeded `dataset_seed`; different splits never
// share a seed.
uint64_t builtin_scene_seed(uint64_t dataset_seed, int split, int64_t index);

// A built-in scene generator as the dataset writer sees it.
struct SceneGenerator {
  std::string name;           // dataset.json "generator"
  bool ordered_views = true;  // frames form a path (rooms) or are independent views (objects)
  uint64_t seed_salt = 0;     // mixed into the dataset seed, so generators never share scene keys
  std::function<SceneRender(uint64_t scene_seed)> render;
  // Evaluation views of a test scene (nullopt: the scene has none).
  std::function<std::optional<EvalEntry>(const SceneRender&, uint64_t scene_seed)> eval_entry;
};

// Writes root/train and root/test (chunks of `scenes_per_chunk` scenes, NNNNNN.torch, and index.json),
// root/evaluation_index.json for the test scenes and root/dataset.json {generator, view_order}. Scenes render in
// parallel; the same arguments give the same bytes.
void write_generated_dataset(const std::string& root, int num_train, int num_test, uint64_t seed,
                             const SceneGenerator& generator, int scenes_per_chunk = 64);

}  // namespace uplvsm::data
