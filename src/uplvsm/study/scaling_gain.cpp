#include "uplvsm/study/scaling_gain.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace uplvsm::study {

namespace {

template <typename T>
void add_unique(std::vector<T>& list, const T& v) {
  if (std::find(list.begin(), list.end(), v) == list.end()) list.push_back(v);
}

// Linear interpolation between the order statistics (R's type 7) of the sorted values.
double quantile(const std::vector<double>& sorted, double p) {
  const double h = p * static_cast<double>(sorted.size() - 1);
  const auto below = static_cast<size_t>(std::floor(h));
  const size_t above = std::min(below + 1, sorted.size() - 1);
  return sorted[below] + (h - static_cast<double>(below)) * (sorted[above] - sorted[below]);
}

// The run indices of each model's each seed: groups[model][seed].
struct SeedGroups {
  std::vector<std::vector<std::vector<size_t>>> groups;
  int64_t fewest_seeds = 0;
};

SeedGroups seed_groups(const std::vector<ScoredRun>& runs) {
  std::vector<std::string> models;
  for (const auto& r : runs) add_unique(models, r.series);
  SeedGroups g;
  for (const auto& model : models) {
    std::vector<int64_t> seeds;
    for (const auto& r : runs)
      if (r.series == model) add_unique(seeds, r.seed);
    auto& by_seed = g.groups.emplace_back(seeds.size());
    for (size_t i = 0; i < runs.size(); ++i)
      if (runs[i].series == model)
        by_seed[std::find(seeds.begin(), seeds.end(), runs[i].seed) - seeds.begin()].push_back(i);
    const auto n = static_cast<int64_t>(seeds.size());
    g.fewest_seeds = g.fewest_seeds == 0 ? n : std::min(g.fewest_seeds, n);
  }
  return g;
}

// The number of per-scene scores every run holds, 0 when some run holds none or another number.
size_t shared_scene_count(const std::vector<ScoredRun>& runs) {
  if (runs.empty()) return 0;
  const size_t n = runs.front().scenes.size();
  for (const auto& r : runs)
    if (r.scenes.size() != n) return 0;
  return n;
}

// One replicate's runs: each model's seeds redrawn (renumbered 0..k-1, so a seed drawn twice is two seeds), each
// run's value the mean over the drawn scenes (its own value when `scene_draw` is empty).
std::vector<ScoredRun> redraw(const std::vector<ScoredRun>& runs, const SeedGroups& g,
                              const std::vector<size_t>& scene_draw, std::mt19937_64& rng) {
  std::vector<ScoredRun> out;
  for (const auto& by_seed : g.groups) {
    std::uniform_int_distribution<size_t> pick(0, by_seed.size() - 1);
    for (size_t j = 0; j < by_seed.size(); ++j)
      for (size_t i : by_seed[pick(rng)]) {
        const auto& r = runs[i];
        double value = r.value;
        if (!scene_draw.empty()) {
          double sum = 0;
          for (size_t s : scene_draw) sum += r.scenes[s];
          value = sum / static_cast<double>(scene_draw.size());
        }
        out.push_back({r.series, r.x, static_cast<int64_t>(j), value, {}});
      }
  }
  return out;
}

}  // namespace

double gain_per_4x(const std::vector<ScoredRun>& runs, bool higher_is_better) {
  std::vector<int64_t> seeds;
  for (const auto& r : runs) add_unique(seeds, r.seed);
  double sxx = 0, sxy = 0;
  for (int64_t seed : seeds) {
    double n = 0, mx = 0, my = 0;
    for (const auto& r : runs)
      if (r.seed == seed) n += 1, mx += std::log(r.x) / std::log(4.0), my += r.value;
    mx /= n, my /= n;
    for (const auto& r : runs) {
      if (r.seed != seed) continue;
      const double dx = std::log(r.x) / std::log(4.0) - mx;
      sxx += dx * dx, sxy += dx * (r.value - my);
    }
  }
  if (!(sxx > 1e-12) || !std::isfinite(sxy)) return std::numeric_limits<double>::quiet_NaN();
  return (higher_is_better ? 1 : -1) * sxy / sxx;
}

std::vector<ScoredRun> runs_with_a_slope(const std::vector<ScoredRun>& runs) {
  std::vector<ScoredRun> out;
  for (const auto& r : runs) {
    bool other_size = false;
    for (const auto& o : runs) other_size |= o.series == r.series && o.seed == r.seed && o.x != r.x;
    if (other_size) out.push_back(r);
  }
  return out;
}

std::vector<ScoredRun> runs_of(const std::vector<ScoredRun>& runs, const std::string& series) {
  std::vector<ScoredRun> out;
  for (const auto& r : runs)
    if (r.series == series) out.push_back(r);
  return out;
}

std::vector<ScoredRun> runs_at(const std::vector<ScoredRun>& runs, const std::string& series, double x) {
  std::vector<ScoredRun> out;
  for (const auto& r : runs)
    if (r.series == series && r.x == x) out.push_back(r);
  return out;
}

double mean_value(const std::vector<ScoredRun>& runs) {
  if (runs.empty()) return std::numeric_limits<double>::quiet_NaN();
  double sum = 0;
  for (const auto& r : runs) sum += r.value;
  return sum / static_cast<double>(runs.size());
}

std::string Interval::resampled() const {
  if (std::isnan(lo)) return "-";
  if (seeds_redrawn && scenes > 0) return "seeds+scenes";
  return seeds_redrawn ? "seeds" : "scenes";
}

Interval bootstrap_interval(const std::vector<ScoredRun>& runs, const Statistic& statistic,
                            const BootstrapOptions& options) {
  Interval out;
  out.estimate = statistic(runs);
  const auto groups = seed_groups(runs);
  out.seeds = groups.fewest_seeds;
  const size_t n_scenes = shared_scene_count(runs);
  out.scenes = static_cast<int64_t>(n_scenes);
  for (const auto& by_seed : groups.groups) out.seeds_redrawn |= by_seed.size() > 1;
  if (!out.seeds_redrawn && n_scenes == 0) return out;
  std::mt19937_64 rng(options.seed);
  std::uniform_int_distribution<size_t> scene(0, n_scenes == 0 ? 0 : n_scenes - 1);
  std::vector<size_t> scene_draw(n_scenes);
  std::vector<double> values;
  for (int b = 0; b < options.replicates; ++b) {
    for (auto& s : scene_draw) s = scene(rng);
    const double v = statistic(redraw(runs, groups, scene_draw, rng));
    if (std::isfinite(v)) values.push_back(v);
  }
  if (values.size() * 2 < static_cast<size_t>(options.replicates)) return out;
  std::sort(values.begin(), values.end());
  out.lo = quantile(values, (1 - options.level) / 2);
  out.hi = quantile(values, (1 + options.level) / 2);
  return out;
}

}  // namespace uplvsm::study
