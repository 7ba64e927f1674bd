#include "uplvsm/data/loader.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <random>
#include <utility>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/data/view_sampler.h"
#include "uplvsm/geometry/camera.h"

namespace uplvsm::data {

namespace {

uint64_t mix(uint64_t a, uint64_t b) {
  // splitmix64 of a combined value: independent streams per (seed, step, sample).
  uint64_t z = a * 0x9E3779B97F4A7C15ULL + b + 0x632BE59BD9B4E5ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

template <class T>
void shuffle(std::vector<T>& v, size_t begin, std::mt19937_64& rng) {
  for (size_t i = v.size(); i > begin + 1; --i)
    std::swap(v[i - 1],
              v[static_cast<size_t>(uniform_int(rng, static_cast<int64_t>(begin), static_cast<int64_t>(i - 1)))]);
}

// Scene order of one epoch, chunk by chunk as pixelSplat's iterable dataset reads them: chunks in a seeded order,
// taken `per_shuffle` at a time (0: all), the scenes of each such group shuffled together. With 2, consecutive
// samples come from at most two groups, which the dataset's chunk cache holds; a plain permutation re-reads a
// random chunk (~100 MB for RealEstate10K) for almost every scene. Identical on every rank.
std::vector<int64_t> epoch_order(const ChunkDataset& dataset, int64_t n, uint64_t seed, int64_t epoch,
                                 int64_t per_shuffle) {
  // Each chunk is a contiguous range [begin, end) of scene indices; training may use only the first n scenes.
  std::vector<std::pair<int64_t, int64_t>> chunks;
  const auto& starts = dataset.chunk_starts();
  for (size_t c = 0; c < starts.size() && starts[c] < n; ++c)
    chunks.emplace_back(starts[c], c + 1 < starts.size() ? std::min(starts[c + 1], n) : n);
  std::mt19937_64 rng(mix(seed, static_cast<uint64_t>(epoch) + 1));
  shuffle(chunks, 0, rng);
  std::vector<int64_t> order;
  order.reserve(static_cast<size_t>(n));
  const size_t group = per_shuffle > 0 ? static_cast<size_t>(per_shuffle) : std::max<size_t>(chunks.size(), 1);
  for (size_t g = 0; g < chunks.size(); g += group) {
    const size_t begin = order.size();
    for (size_t k = g; k < std::min(g + group, chunks.size()); ++k)
      for (int64_t i = chunks[k].first; i < chunks[k].second; ++i) order.push_back(i);
    shuffle(order, begin, rng);
  }
  return order;
}

// The official dataset's preprocess_poses over a sample's sampled (distinct) views: centred on their mean camera,
// axes from their mean viewing and up directions, translations scaled into [-1/1.35, 1/1.35]. Cameras that are not
// finite (photos imported without poses, which no camera-reading model trains on) stay as read.
torch::Tensor in_scene_frame(const torch::Tensor& c2w) {
  if (!torch::isfinite(c2w).all().item<bool>()) return c2w;
  return geometry::official_scene_normalize(c2w);
}

// The inputs' and the targets' cameras as the model is told them (official ProcessData.forward: split, then noise).
void tell_cameras(TrainingBatch& batch, const LoaderOptions& opt) {
  const auto& ti = batch.target_index;
  batch.input_cameras = batch.c2w.narrow(1, 0, opt.num_input_views);
  batch.target_cameras = batch.c2w.gather(1, ti.view({ti.size(0), ti.size(1), 1, 1}).expand({-1, -1, 4, 4}));
  if (opt.pose_noise_std <= 0) return;
  std::mt19937_64 rng(mix(opt.seed ^ 0x6e6f697365ULL, static_cast<uint64_t>(batch.step * opt.world_size + opt.rank)));
  batch.input_cameras = with_pose_noise(batch.input_cameras, opt.pose_noise_std, rng);
  batch.target_cameras = with_pose_noise(batch.target_cameras, opt.pose_noise_std, rng);
}

// The training views of a scene of `frames` frames at training step `step`; throws when it has too few.
std::vector<int64_t> sample_views(int64_t frames, const LoaderOptions& opt, int64_t step, std::mt19937_64& rng) {
  if (!opt.ordered_views) {
    if (frames < opt.num_views)
      throw std::runtime_error(fmt::format("{} frames: too few for {} views", frames, opt.num_views));
    return sample_unordered_views(frames, opt.num_views, rng);
  }
  if (!can_sample(frames, opt.num_views, opt.min_frame_dist))
    throw std::runtime_error(
        fmt::format("{} frames: too few for {} views with the inputs more than {} frames apart (the official selector "
                    "needs at least min_frame_dist + 2 frames)",
                    frames, opt.num_views, opt.min_frame_dist));
  const int64_t update = step / std::max<int64_t>(opt.micro_batches_per_step, 1);
  const int max_gap = max_gap_at_step(opt.min_frame_dist, opt.max_frame_dist, opt.frame_dist_curriculum_steps, update);
  return sample_training_views(frames, opt.num_views, opt.min_frame_dist, max_gap, rng);
}

}  // namespace

torch::Tensor with_pose_noise(const torch::Tensor& c2w, double std, std::mt19937_64& rng) {
  auto enc = geometry::c2w_to_pose_encoding(c2w.to(torch::kFloat32));
  std::normal_distribution<float> normal(0.0F, 1.0F);
  std::vector<float> noise(static_cast<size_t>(enc.numel()));
  for (auto& x : noise) x = normal(rng);
  enc = enc + torch::tensor(noise, torch::kFloat32).view(enc.sizes()) * static_cast<float>(std);
  return geometry::pose_encoding_to_c2w(enc).to(c2w.dtype());
}

TrainingBatch make_training_batch(const ChunkDataset& dataset, const LoaderOptions& opt, int64_t step) {
  const int64_t n = opt.max_scenes > 0 ? std::min(opt.max_scenes, dataset.size()) : dataset.size();
  if (n == 0)
    throw std::runtime_error("training data: split '" + dataset.split() + "' of " + dataset.root() + " has no scenes");
  TrainingBatch batch;
  batch.step = step;
  std::vector<torch::Tensor> images, intrinsics, c2ws, targets;
  int64_t epoch_cached = -1;
  std::vector<int64_t> perm;
  for (int64_t i = 0; i < opt.batch_size; ++i) {
    // Global sample number: disjoint across ranks within a step, contiguous across steps.
    const int64_t g = (step * opt.world_size + opt.rank) * opt.batch_size + i;
    std::mt19937_64 rng(mix(opt.seed, static_cast<uint64_t>(g)));
    bool done = false;
    // 64 tries even for a split of a few scenes: each try may land in another epoch's order and repeat scenes.
    for (int64_t attempt = 0; attempt < 64 && !done; ++attempt) {
      const int64_t slot = g + attempt * 7919;  // a bad scene is replaced by another one of the order
      const int64_t epoch = slot / n;
      if (epoch != epoch_cached) {
        perm = epoch_order(dataset, n, opt.seed, epoch, opt.chunks_per_shuffle);
        epoch_cached = epoch;
      }
      const int64_t scene = perm[slot % n];
      try {
        const int64_t frames = dataset.num_frames(scene);
        auto chosen = sample_views(frames, opt, step, rng);
        // Frames of another size are resized from their own size, as the official dataset does.
        auto views = dataset.load_views(scene, chosen, opt.preprocess, data::FrameSizePolicy::Resize);
        if (views.resized_frames > 0)
          spdlog::info("training data: scene {}: {} frame(s) of another size than frame 0, resized", dataset.key(scene),
                       views.resized_frames);
        batch.resized_frames += views.resized_frames;
        images.push_back(views.images);
        intrinsics.push_back(views.fxfycxcy);
        c2ws.push_back(in_scene_frame(views.c2w));
        batch.keys.push_back(dataset.key(scene));
        batch.frames.push_back(chosen);
        // Official target_has_input=True: random.sample(range(V), num_target_views).
        std::vector<int64_t> all(opt.num_views);
        std::iota(all.begin(), all.end(), 0);
        for (int k = 0; k < opt.num_target_views; ++k) std::swap(all[k], all[uniform_int(rng, k, opt.num_views - 1)]);
        targets.push_back(torch::tensor(std::vector<int64_t>(all.begin(), all.begin() + opt.num_target_views)));
        done = true;
      } catch (const std::exception& e) {
        ++batch.replaced_scenes;
        spdlog::warn("training data: skipping scene {} ({}): {}", dataset.key(scene), dataset.chunk_path(scene),
                     e.what());
      }
    }
    if (!done)
      throw std::runtime_error("training data: could not build a sample from 64 scenes in a row of " + dataset.root());
  }
  batch.images = torch::stack(images);
  batch.fxfycxcy = torch::stack(intrinsics);
  batch.c2w = torch::stack(c2ws);
  batch.target_index = torch::stack(targets);
  tell_cameras(batch, opt);
  return batch;
}

torch::Tensor TrainingBatch::input_images(int64_t n) const { return images.narrow(1, 0, n); }
torch::Tensor TrainingBatch::input_fxfycxcy(int64_t n) const { return fxfycxcy.narrow(1, 0, n); }

torch::Tensor TrainingBatch::target_images() const {
  auto idx = target_index.view({target_index.size(0), target_index.size(1), 1, 1, 1})
                 .expand({-1, -1, images.size(2), images.size(3), images.size(4)});
  return images.gather(1, idx);
}

torch::Tensor TrainingBatch::target_fxfycxcy() const {
  return fxfycxcy.gather(1, target_index.unsqueeze(-1).expand({-1, -1, 4}));
}

torch::Tensor TrainingBatch::input_c2w(int64_t n) const {
  TORCH_CHECK(n <= input_cameras.size(1), "training batch: ", n, " input views asked, the loader told ",
              input_cameras.size(1));
  return input_cameras.narrow(1, 0, n);
}

torch::Tensor TrainingBatch::target_c2w() const { return target_cameras; }

TrainingLoader::TrainingLoader(const ChunkDataset& dataset, LoaderOptions opt, int64_t first_step)
    : dataset_(dataset), opt_(std::move(opt)), next_to_hand_out_(first_step), next_to_build_(first_step) {
  for (int i = 0; i < std::max(1, opt_.threads); ++i) workers_.emplace_back([this] { work(); });
}

TrainingLoader::~TrainingLoader() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  for (auto& w : workers_) w.join();
}

void TrainingLoader::work() {
  while (true) {
    int64_t step;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [&] { return stop_ || next_to_build_ < next_to_hand_out_ + opt_.prefetch; });
      if (stop_) return;
      step = next_to_build_++;
    }
    try {
      auto batch = make_training_batch(dataset_, opt_, step);
      std::lock_guard<std::mutex> lock(mutex_);
      ready_.emplace(step, std::move(batch));
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lock(mutex_);
      errors_.emplace(step, e.what());
    }
    cv_.notify_all();
  }
}

TrainingBatch TrainingLoader::next() {
  auto t0 = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock(mutex_);
  const int64_t step = next_to_hand_out_;
  cv_.wait(lock, [&] { return ready_.count(step) || errors_.count(step); });
  wait_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (errors_.count(step)) throw std::runtime_error(errors_.at(step));
  auto batch = std::move(ready_.at(step));
  ready_.erase(step);
  ++next_to_hand_out_;
  resized_frames_ += batch.resized_frames;
  lock.unlock();
  cv_.notify_all();
  return batch;
}

}  // namespace uplvsm::data
