// Training view selection; see view_sampler.h for the rule and why it is written this way.
#include "uplvsm/data/view_sampler.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>

namespace uplvsm::data {

int64_t uniform_int(std::mt19937_64& rng, int64_t lo, int64_t hi) {
  if (hi < lo) throw std::invalid_argument(fmt::format("uniform_int: empty range [{}, {}]", lo, hi));
  const uint64_t range = static_cast<uint64_t>(hi) - static_cast<uint64_t>(lo) + 1;  // 0 means all 2^64 values
  if (range == 0) return static_cast<int64_t>(rng());
  // Largest multiple of `range` representable: draws at or above it are rejected to avoid modulo bias.
  const uint64_t limit = std::numeric_limits<uint64_t>::max() - std::numeric_limits<uint64_t>::max() % range;
  uint64_t draw;
  do {
    draw = rng();
  } while (draw >= limit);
  return lo + static_cast<int64_t>(draw % range);
}

bool can_sample(int64_t num_frames, int num_views, int min_gap) {
  // Strictly greater, as the official `if max_frame_dist <= min_frame_dist: return None`.
  return num_views >= 1 && num_frames >= num_views && num_frames - 1 > min_gap;
}

std::vector<int64_t> sample_training_views(int64_t num_frames, int num_views, int min_gap, int max_gap,
                                           std::mt19937_64& rng) {
  if (num_views < 1) throw std::invalid_argument(fmt::format("sample_training_views: num_views {} < 1", num_views));
  if (num_frames < num_views || (num_views > 1 && num_frames < 2))
    throw std::invalid_argument(
        fmt::format("sample_training_views: scene has {} frames, fewer than the {} views "
                    "needed",
                    num_frames, num_views));
  if (num_views == 1) return {uniform_int(rng, 0, num_frames - 1)};
  const int64_t hi = std::min<int64_t>(num_frames - 1, max_gap);
  const int64_t lo = std::max<int64_t>(1, std::min<int64_t>(min_gap, hi));
  const int64_t gap = uniform_int(rng, lo, std::max(lo, hi));
  const int64_t start = uniform_int(rng, 0, num_frames - gap - 1);
  std::vector<int64_t> views = {start, start + gap};
  const int64_t need = num_views - 2;
  const int64_t interior = gap - 1;  // frames start+1 .. start+gap-1
  if (interior >= need) {
    // Partial Fisher-Yates over the interior frames: `need` distinct frames in random order.
    std::vector<int64_t> pool(interior);
    for (int64_t j = 0; j < interior; ++j) pool[j] = start + 1 + j;
    for (int64_t j = 0; j < need; ++j) {
      int64_t pick = uniform_int(rng, j, interior - 1);
      std::swap(pool[j], pool[pick]);
      views.push_back(pool[j]);
    }
  } else {
    // Too few interior frames: draw with repeats (from the whole span when there is no interior frame at all).
    int64_t a = interior > 0 ? start + 1 : start, b = interior > 0 ? start + gap - 1 : start + gap;
    for (int64_t j = 0; j < need; ++j) views.push_back(uniform_int(rng, a, b));
  }
  return views;
}

int max_gap_at_step(int min_gap, int max_gap, int64_t steps, int64_t step) {
  if (steps <= 0 || step >= steps || max_gap <= min_gap) return max_gap;
  const double grown = static_cast<double>(max_gap - min_gap) * static_cast<double>(std::max<int64_t>(step, 0)) /
                       static_cast<double>(steps);
  return min_gap + static_cast<int>(std::floor(grown));
}

std::vector<int64_t> sample_unordered_views(int64_t num_frames, int num_views, std::mt19937_64& rng) {
  if (num_views < 1 || num_frames < num_views)
    throw std::invalid_argument(
        fmt::format("sample_unordered_views: scene has {} frames, fewer than the {} views "
                    "needed",
                    num_frames, num_views));
  // Partial Fisher-Yates: the first num_views entries of a random permutation of the frames.
  std::vector<int64_t> pool(num_frames);
  for (int64_t j = 0; j < num_frames; ++j) pool[j] = j;
  for (int64_t j = 0; j < num_views; ++j) std::swap(pool[j], pool[uniform_int(rng, j, num_frames - 1)]);
  pool.resize(num_views);
  return pool;
}

bool uses_ordered_views(const std::string& view_sampler, const DatasetInfo& dataset) {
  if (view_sampler == "ordered") return true;
  if (view_sampler == "unordered") return false;
  if (view_sampler == "auto") return dataset.ordered_views;
  throw std::invalid_argument("training.view_sampler must be 'auto', 'ordered' or 'unordered', got '" + view_sampler +
                              "'");
}

}  // namespace uplvsm::data
