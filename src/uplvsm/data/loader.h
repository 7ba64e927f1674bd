// The training batch loader: for every micro-batch a batch that is a pure function of (seed, micro-batch, rank), so
// a resumed run sees exactly the data the uninterrupted run would have seen, and ranks read disjoint shards. Each
// sample's cameras are put in the frame of its sampled views (the official dataset's preprocess_poses). Scenes are
// visited in a seeded order per epoch: shuffled over the whole split (the official order), or through the chunks a
// few at a time (shuffled within them) so the chunk cache serves consecutive samples; views follow the official
// selector; a frame of another size is resized from its own size (as officially) and counted; a bad scene (too few
// frames, a broken file) is replaced by the next scene of the permutation and counted. Worker threads decode ahead
// into a bounded queue.
#pragma once
#include <torch/torch.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/preprocess.h"

namespace uplvsm::data {

struct LoaderOptions {
  int64_t batch_size = 1;  // per rank
  int num_views = 8;
  int num_input_views = 2;
  int num_target_views = 6;
  int min_frame_dist = 25, max_frame_dist = 192;
  int64_t frame_dist_curriculum_steps =
      0;                      // max_frame_dist reached after this many steps (max_gap_at_step); 0: at once
  bool ordered_views = true;  // false: any distinct frames (unordered views); min/max_frame_dist unused
  PreprocessOptions preprocess;
  uint64_t seed = 777;
  int rank = 0, world_size = 1;
  int threads = 2;
  int prefetch = 4;        // batches decoded ahead
  int64_t max_scenes = 0;  // train on the split's first N scenes only (nested subsets); 0: all
  // Chunks whose scenes are shuffled together in an epoch's order; 0: one shuffle over the whole split (the
  // official order, which reads a random chunk for almost every sample).
  int64_t chunks_per_shuffle = 2;
  // The pose-noise study, as the official unposed.noise_scale: N(0, pose_noise_std^2) (a standard deviation) on the
  // fp32 7-D (t, q) encoding of the input cameras and, drawn apart, the target cameras, after the split and the
  // scene normalisation; from its own stream, so the views chosen do not change with it. 0: clean cameras.
  double pose_noise_std = 0;
  // Micro-batches per optimiser step (the run's gradient accumulation): the stream is keyed to micro-batches, and
  // the frame-distance curriculum counts optimiser steps.
  int64_t micro_batches_per_step = 1;
};

struct TrainingBatch {
  int64_t step = 0;
  torch::Tensor images;    // [b, V, 3, H, W]
  torch::Tensor fxfycxcy;  // [b, V, 4]
  torch::Tensor c2w;       // [b, V, 4, 4] clean, each sample in the frame of its V views (official preprocess_poses)
  torch::Tensor target_index;  // int64 [b, num_target_views]: views used as targets (official: may include inputs)
  // The cameras the model is told: c2w's first num_input_views, and its targets gathered by target_index, each with
  // its own pose noise (a target that repeats an input gets its own draw, as officially).
  torch::Tensor input_cameras;   // [b, num_input_views, 4, 4]
  torch::Tensor target_cameras;  // [b, num_target_views, 4, 4]
  std::vector<std::string> keys;
  std::vector<std::vector<int64_t>> frames;
  int64_t replaced_scenes = 0;  // bad scenes swapped for others while building this batch
  // Frames of another size than their scene's frame 0, resized from their own size as the official dataset does.
  int64_t resized_frames = 0;

  // Inputs are the first num_input_views views; targets are gathered by target_index. The c2w are the told ones
  // (input_cameras, target_cameras).
  torch::Tensor input_images(int64_t n) const;
  torch::Tensor input_fxfycxcy(int64_t n) const;
  torch::Tensor target_images() const;
  torch::Tensor target_fxfycxcy() const;
  torch::Tensor input_c2w(int64_t n) const;
  torch::Tensor target_c2w() const;
};

// Official noise_scale (data_utils.py ProcessData.forward): the fp32 (t, q_xyzw) encoding of every camera of c2w
// [..., 4, 4] plus N(0, std^2) drawn from rng, decoded back (the quaternion renormalised), in c2w's dtype. The
// training loader and the evaluation (eval/eval_pose_noise.h) share it so both perturb cameras the same way.
torch::Tensor with_pose_noise(const torch::Tensor& c2w, double std, std::mt19937_64& rng);

// The batch of micro-batch `step` for this rank (no threads; the loader below calls it).
TrainingBatch make_training_batch(const ChunkDataset& dataset, const LoaderOptions& opt, int64_t step);

class TrainingLoader {
 public:
  TrainingLoader(const ChunkDataset& dataset, LoaderOptions opt, int64_t first_step);
  ~TrainingLoader();
  TrainingLoader(const TrainingLoader&) = delete;
  TrainingLoader& operator=(const TrainingLoader&) = delete;
  // Batches come in step order: first_step, first_step + 1, ...
  TrainingBatch next();
  double wait_seconds() const { return wait_seconds_; }       // time next() spent blocked on workers
  int64_t resized_frames() const { return resized_frames_; }  // in the batches handed out so far

 private:
  void work();
  const ChunkDataset& dataset_;
  LoaderOptions opt_;
  int64_t next_to_hand_out_, next_to_build_;
  std::map<int64_t, TrainingBatch> ready_;
  std::map<int64_t, std::string> errors_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::vector<std::thread> workers_;
  double wait_seconds_ = 0;
  int64_t resized_frames_ = 0;
};

}  // namespace uplvsm::data
