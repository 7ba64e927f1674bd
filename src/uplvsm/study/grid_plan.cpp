// The runs of the grid studies (study/grid_runner.h): their series, settings, directories and descriptions.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/study/grid_runner.h"

namespace uplvsm::study {

namespace {

// Series name: the model variant, or the config's name when two configs share a variant.
std::vector<std::pair<std::string, Config>> load_series(const GridOptions& a) {
  std::vector<std::pair<std::string, Config>> out;
  for (const auto& path : a.configs) {
    auto c = apply_config_overrides(load_config(path), a.overrides, path);
    if (a.steps > 0) c.training.train_steps = a.steps;
    out.emplace_back(to_string(c.model.variant), c);
  }
  for (auto& [name, c] : out) {
    int same = 0;
    for (const auto& other : out) same += other.first == name;
    if (same > 1) name = c.name;
  }
  for (size_t i = 0; i < out.size(); ++i)
    for (size_t j = i + 1; j < out.size(); ++j)
      if (out[i].first == out[j].first)
        throw std::runtime_error("study: configs " + a.configs[i] + " and " + a.configs[j] +
                                 " have the same variant and name '" + out[i].first + "'; give them distinct names");
  return out;
}

// Each series on each subset; subset i trains steps x growth^i steps, every run with the given pose noise.
std::vector<GridRun> scaling_runs(const GridOptions& a, const std::vector<int64_t>& sizes, int64_t available,
                                  double growth, double noise_std) {
  std::vector<GridRun> runs;
  for (const auto& [series, config] : load_series(a))
    for (size_t i = 0; i < sizes.size(); ++i) {
      const int64_t n = sizes[i];
      GridRun r{series,
                n == 0 ? fmt::format("full ({})", available) : fmt::format("{} scenes", n),
                fmt::format("{}__{}", series, n == 0 ? std::string("full") : std::to_string(n)),
                static_cast<double>(n == 0 ? available : n),
                config,
                {}};
      r.config.training.max_train_scenes = n;
      r.config.training.pose_noise_std = noise_std;
      r.config.training.train_steps =
          std::llround(static_cast<double>(config.training.train_steps) * std::pow(growth, static_cast<double>(i)));
      runs.push_back(r);
    }
  return runs;
}

// Whether training a config reads the training cameras (what pose noise acts on): the posed variants, and UP-LVSM
// told its targets' cameras (the dataset-pose ablation or the mapper).
bool reads_training_cameras(const Config& c) {
  return c.model.variant != Variant::UPLVSM ||
         (c.training.target_poses != TargetPoses::Auto && c.training.target_poses != TargetPoses::Estimator);
}

std::vector<GridRun> pose_noise_runs(const GridOptions& a, const std::vector<std::pair<double, std::string>>& levels) {
  std::vector<GridRun> runs;
  for (const auto& [series, config] : load_series(a)) {
    const auto first_dir = fmt::format("{}__noise_sd{:g}", series, levels.front().first);
    for (size_t i = 0; i < levels.size(); ++i) {
      const auto& [sd, label] = levels[i];
      GridRun r{series, "noise " + label, fmt::format("{}__noise_sd{:g}", series, sd), sd, config, {}};
      r.config.training.pose_noise_std = sd;
      if (i > 0 && !reads_training_cameras(config)) r.same_as = first_dir;
      runs.push_back(r);
    }
  }
  return runs;
}

}  // namespace

std::vector<int64_t> parse_subsets(const std::vector<std::string>& tokens, int64_t available) {
  std::vector<int64_t> out;
  for (const auto& t : tokens) {
    int64_t n = 0;
    if (t != "full") {
      try {
        size_t used = 0;
        n = std::stoll(t, &used);
        if (used != t.size() || n <= 0) throw std::invalid_argument(t);
      } catch (const std::exception&) {
        throw std::runtime_error("--subsets: expected scene counts or 'full', got '" + t + "'");
      }
      if (n > available)
        throw std::runtime_error(fmt::format("--subsets {}: the train split has only {} scenes", n, available));
    }
    out.push_back(n);
  }
  return out;
}

std::vector<std::pair<double, std::string>> noise_levels(const std::vector<double>& stds,
                                                         const std::vector<double>& variances) {
  std::vector<std::pair<double, std::string>> levels;
  for (double v : stds) levels.emplace_back(v, fmt::format("sd {:g}", v));
  for (double v : variances) levels.emplace_back(std::sqrt(v), fmt::format("var {:g}", v));
  std::stable_sort(levels.begin(), levels.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<std::pair<double, std::string>> out;
  for (const auto& l : levels) {
    if (!(l.first >= 0) || !std::isfinite(l.first))
      throw std::runtime_error("--noise-std/--noise-variance: levels must be finite numbers >= 0, got " + l.second);
    if (!out.empty() && std::abs(out.back().first - l.first) <= 1e-12 * std::max(1.0, l.first))
      out.back().second += " = " + l.second;
    else
      out.push_back(l);
  }
  return out;
}

GridPlan scaling_plan(const GridOptions& a, const std::vector<std::string>& subsets, double growth, double noise_std) {
  const int64_t available = data::ChunkDataset(a.data, "train").size();
  GridPlan plan;
  plan.runs = scaling_runs(a, parse_subsets(subsets, available), available, growth, noise_std);
  const auto steps = plan.runs.front().config.training.train_steps;
  const auto budget =
      growth == 1 ? fmt::format("the same {} training steps", steps)
                  : fmt::format("{} training steps on the smallest subset, {:g}x more on each next", steps, growth);
  const auto noise_note = noise_std > 0 ? fmt::format(", training cameras with pose noise sd {:g}", noise_std) : "";
  plan.description = fmt::format(
      "Each run: {} on the first N training scenes of {}{}; scored on its test split. Avg. gain: the paper's, the "
      "least-squares slope per 4x data over every subset (improvement positive; LPIPS lower is better).",
      budget, a.data, noise_note);
  auto& fig = plan.figure;
  fig.title = "Scalability", fig.xlabel = "training scenes", fig.log_x = true, fig.with_gain = true;
  return plan;
}

GridPlan pose_noise_plan(const GridOptions& a, std::vector<std::pair<double, std::string>> levels) {
  if (levels.empty()) levels = noise_levels({0, 0.001, 0.01, 0.1}, {});
  GridPlan plan;
  plan.runs = pose_noise_runs(a, levels);
  plan.description = fmt::format(
      "Each run: {} training steps on {} with N(0, sd^2) added to the 7-D (t, q) encoding of the input and, drawn "
      "apart, the target cameras after the scene normalisation (the official noise_scale; 'var v' is sd = sqrt(v));"
      " scored with clean test cameras. A model that never reads training cameras is trained once per seed and "
      "stands at every level.",
      plan.runs.front().config.training.train_steps, a.data);
  auto& fig = plan.figure;
  fig.title = "Pose noise", fig.xlabel = "pose noise sd (the official noise_scale; log axis, no noise at the left)";
  fig.log_x = true;
  return plan;
}

}  // namespace uplvsm::study
