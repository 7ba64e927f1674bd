// Training view selection. Ordered frames (videos) use the official UP-LVSM selector (official-uplvsm.md §1,
// dataset_scene.py view_selector): two context frames `gap` apart plus random frames strictly between them.
// Unordered frames (object renders) have no "between": any distinct frames, as LVSM samples Objaverse views.
#pragma once
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "uplvsm/data/dataset_info.h"

namespace uplvsm::data {

// Uniform integer in [lo, hi] (inclusive) by rejection sampling on the raw 64-bit draws, so the sequence is the
// same for a given engine state on every platform (std::uniform_int_distribution is implementation-defined).
int64_t uniform_int(std::mt19937_64& rng, int64_t lo, int64_t hi);

// Frames for one training sample: needs num_frames >= num_views (else throws).
// gap = uniform in [min_gap, min(num_frames-1, max_gap)] (min_gap above that bound: the bound; at least 1);
// start = uniform in [0, num_frames-gap-1]; views = [start, start+gap] followed by num_views-2 distinct frames
// of (start, start+gap) in random order (repeats only when the interval has too few frames). num_views == 1
// gives one uniform frame.
std::vector<int64_t> sample_training_views(int64_t num_frames, int num_views, int min_gap, int max_gap,
                                           std::mt19937_64& rng);

// The baseline curriculum (small camera motion first; not in the official recipe): the largest context gap at
// `step` grows linearly from min_gap to max_gap over the first `steps` steps; steps <= 0 is max_gap throughout.
int max_gap_at_step(int min_gap, int max_gap, int64_t steps, int64_t step);

// Whether the official selector uses the scene: num_frames >= num_views and num_frames - 1 > min_gap. The official
// view_selector skips a scene (the dataset then takes another) when its largest gap, min(frames - 1,
// max_frame_dist), is <= min_frame_dist, so a scene of exactly min_gap + 1 frames is skipped.
bool can_sample(int64_t num_frames, int num_views, int min_gap);

// num_views distinct frames drawn uniformly, in random order (the first ones become the inputs). Needs
// num_frames >= num_views (else throws).
std::vector<int64_t> sample_unordered_views(int64_t num_frames, int num_views, std::mt19937_64& rng);

// Whether training.view_sampler ("auto", "ordered", "unordered") means the ordered selector for this dataset:
// "auto" follows the dataset's dataset.json (ordered without one). Throws on another value.
bool uses_ordered_views(const std::string& view_sampler, const DatasetInfo& dataset);

}  // namespace uplvsm::data
