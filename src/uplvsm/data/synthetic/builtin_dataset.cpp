// The shared half of the built-in generators: frame rendering, view overlap and the dataset writer.
#include "uplvsm/data/synthetic/builtin_dataset.h"

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/dataset_info.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/io/image.h"

namespace uplvsm::data {

using synthetic::Camera;
using synthetic::Vec3;

namespace {

// c2w [4,4] in float64 from a camera.
torch::Tensor camera_c2w(const Camera& c) {
  auto m = torch::eye(4, torch::kFloat64);
  auto a = m.accessor<double, 2>();
  for (int k = 0; k < 3; ++k) {
    a[0][k] = c.axes[k].x;
    a[1][k] = c.axes[k].y;
    a[2][k] = c.axes[k].z;
  }
  a[0][3] = c.position.x, a[1][3] = c.position.y, a[2][3] = c.position.z;
  return m;
}

void render_frame(const Camera& cam, int height, int width, const PixelTracer& trace, uint8_t* rgb, float* depth) {
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      size_t i = static_cast<size_t>(v) * width + u;
      Vec3 c = trace(cam, u, v, &depth[i]);
      rgb[i * 3 + 0] = static_cast<uint8_t>(std::lround(std::clamp(c.x, 0.0, 1.0) * 255));
      rgb[i * 3 + 1] = static_cast<uint8_t>(std::lround(std::clamp(c.y, 0.0, 1.0) * 255));
      rgb[i * 3 + 2] = static_cast<uint8_t>(std::lround(std::clamp(c.z, 0.0, 1.0) * 255));
    }
  }
}

// One direction of context_overlap: share of a's pixels (those that see a surface) landing inside b.
double overlap_one_way(const torch::Tensor& depth_a, const torch::Tensor& k_a, const torch::Tensor& c2w_a,
                       const torch::Tensor& k_b, const torch::Tensor& c2w_b) {
  int64_t h = depth_a.size(0), w = depth_a.size(1);
  auto ka = k_a.to(torch::kFloat64), kb = k_b.to(torch::kFloat64);
  auto vs = torch::arange(h, torch::kFloat64).add(0.5).view({h, 1}).expand({h, w});
  auto us = torch::arange(w, torch::kFloat64).add(0.5).view({1, w}).expand({h, w});
  auto z = depth_a.to(torch::kFloat64);
  auto pts = torch::stack({(us - ka[2]) / ka[0] * z, (vs - ka[3]) / ka[1] * z, z, torch::ones_like(z)}, -1);
  auto a2b = torch::linalg_inv(c2w_b.to(torch::kFloat64)).matmul(c2w_a.to(torch::kFloat64));
  auto q = pts.view({-1, 4}).matmul(a2b.t());
  auto qz = q.select(1, 2);
  auto pu = q.select(1, 0) / qz * kb[0] + kb[2], pv = q.select(1, 1) / qz * kb[1] + kb[3];
  auto inside = (qz > 1e-6) & (pu >= 0) & (pu < w) & (pv >= 0) & (pv < h);
  auto surface = torch::isfinite(z).view({-1});
  if (surface.all().item<bool>()) return inside.to(torch::kFloat64).mean().item<double>();
  const auto seen = surface.sum().item<int64_t>();  // background pixels (objects on a backdrop) do not count
  return seen == 0 ? 0.0 : (inside & surface).sum().item<int64_t>() / static_cast<double>(seen);
}

// Nested calls (a scene rendering its frames inside a parallel loop over scenes) run serially.
thread_local bool t_in_parallel = false;

}  // namespace

SceneRender render_scene(const std::vector<Camera>& cameras, double fx, int height, int width, int jpeg_quality,
                         const PixelTracer& trace, std::string key, std::string url) {
  const int64_t n = static_cast<int64_t>(cameras.size());
  SceneRender r;
  r.images = torch::empty({n, height, width, 3}, torch::kUInt8);
  r.depth = torch::empty({n, height, width}, torch::kFloat32);
  r.scene.images.resize(n);
  parallel_for_each(n, [&](int64_t i) {
    render_frame(cameras[i], height, width, trace, r.images[i].data_ptr<uint8_t>(), r.depth[i].data_ptr<float>());
    auto bytes = io::encode_jpeg(r.images[i], jpeg_quality);
    r.scene.images[i] = torch::from_blob(bytes.data(), {static_cast<int64_t>(bytes.size())}, torch::kUInt8).clone();
  });
  std::vector<torch::Tensor> c2w(n);
  for (int64_t i = 0; i < n; ++i) c2w[i] = camera_c2w(cameras[i]);
  auto c2w64 = torch::stack(c2w);
  r.c2w = c2w64.to(torch::kFloat32);
  r.fxfycxcy = torch::tensor({fx, fx, width / 2.0, height / 2.0}, torch::kFloat64).repeat({n, 1});
  r.scene.key = std::move(key);
  r.scene.url = std::move(url);
  r.scene.timestamps = torch::arange(n, torch::kInt64) * 100000;
  r.scene.cameras = make_cameras18(r.fxfycxcy, torch::linalg_inv(c2w64), width, height);
  r.fxfycxcy = r.fxfycxcy.to(torch::kFloat32);
  return r;
}

double context_overlap(const SceneRender& r, int64_t a, int64_t b) {
  double ab = overlap_one_way(r.depth[a], r.fxfycxcy[a], r.c2w[a], r.fxfycxcy[b], r.c2w[b]);
  double ba = overlap_one_way(r.depth[b], r.fxfycxcy[b], r.c2w[b], r.fxfycxcy[a], r.c2w[a]);
  return 0.5 * (ab + ba);
}

// Dynamic assignment on std::threads. Not at::parallel_for: that is inline and only parallel when the caller is
// compiled with -fopenmp, which this project is not.
void parallel_for_each(int64_t n, const std::function<void(int64_t)>& fn) {
  int workers = static_cast<int>(std::min<int64_t>(n, std::max(1, at::get_num_threads())));
  if (t_in_parallel || workers <= 1) {
    for (int64_t i = 0; i < n; ++i) fn(i);
    return;
  }
  std::atomic<int64_t> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto work = [&] {
    t_in_parallel = true;
    for (int64_t i; (i = next++) < n;) {
      try {
        fn(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        next = n;  // stop handing out work
      }
    }
    t_in_parallel = false;
  };
  std::vector<std::thread> threads;
  for (int w = 1; w < workers; ++w) threads.emplace_back(work);
  work();
  for (auto& t : threads) t.join();
  if (error) std::rethrow_exception(error);
}

std::string builtin_scene_key(uint64_t seed) {
  return fmt::format("{:016x}", synthetic::splitmix64(seed ^ 0x5EED5EED5EEDull));
}

uint64_t builtin_scene_seed(uint64_t dataset_seed, int split, int64_t index) {
  // Two rounds of mixing over (seed, split, index): distinct triples give distinct seeds except with ~2^-64 odds
  // (write_generated_dataset still checks keys are unique).
  return synthetic::splitmix64(synthetic::splitmix64(dataset_seed) ^ (static_cast<uint64_t>(split) << 62) ^
                               static_cast<uint64_t>(index));
}

void write_generated_dataset(const std::string& root, int num_train, int num_test, uint64_t seed,
                             const SceneGenerator& generator, int scenes_per_chunk) {
  if (num_train < 0 || num_test < 0 || scenes_per_chunk < 1)
    throw std::runtime_error(fmt::format("make-dataset ({}): bad counts (train {}, test {}, per chunk {})",
                                         generator.name, num_train, num_test, scenes_per_chunk));
  const uint64_t dataset_seed = seed ^ generator.seed_salt;
  std::set<std::string> all_keys;
  std::vector<EvalEntry> evaluation;
  const std::pair<const char*, int> splits[2] = {{"train", num_train}, {"test", num_test}};
  for (int split = 0; split < 2; ++split) {
    const std::string dir = (std::filesystem::path(root) / splits[split].first).string();
    std::filesystem::create_directories(dir);
    std::map<std::string, std::string> index;
    const int count = splits[split].second;
    for (int first = 0, chunk = 0; first < count; first += scenes_per_chunk, ++chunk) {
      const int in_chunk = std::min(scenes_per_chunk, count - first);
      std::vector<SceneRender> renders(in_chunk);
      // Scenes in parallel (each renders its frames serially inside).
      parallel_for_each(in_chunk, [&](int64_t j) {
        renders[j] = generator.render(builtin_scene_seed(dataset_seed, split, first + j));
      });
      std::vector<RawScene> scenes;
      const std::string file = fmt::format("{:06d}.torch", chunk);
      for (int j = 0; j < in_chunk; ++j) {
        const auto& r = renders[j];
        if (!all_keys.insert(r.scene.key).second)
          throw std::runtime_error(
              fmt::format("make-dataset ({}): duplicate scene key {}", generator.name, r.scene.key));
        index[r.scene.key] = file;
        if (split == 1)
          if (auto e = generator.eval_entry(r, builtin_scene_seed(dataset_seed, split, first + j)))
            evaluation.push_back(*e);
        scenes.push_back(r.scene);
      }
      write_chunk((std::filesystem::path(dir) / file).string(), scenes);
    }
    write_chunk_index(dir, index);
  }
  if (num_test > 0 && evaluation.empty())
    spdlog::warn("make-dataset ({}): the scenes' frames leave no room for evaluation views", generator.name);
  write_eval_index((std::filesystem::path(root) / "evaluation_index.json").string(), evaluation);
  write_dataset_info(root, {generator.name, generator.ordered_views});
}

}  // namespace uplvsm::data
