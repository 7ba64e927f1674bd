#include "uplvsm/study/grid_stats.h"

#include <cmath>
#include <map>

#include <fmt/format.h>

namespace uplvsm::study {

namespace {

std::vector<GridCell> done_runs(const std::vector<GridCell>& runs) {
  std::vector<GridCell> done;
  for (const auto& r : runs)
    if (r.runs > 0) done.push_back(r);
  return done;
}

// Each run's scores of `metric` in the order of `keys`; empty when some run lacks a scene (or kept none).
std::vector<std::vector<double>> paired_scenes(const std::vector<GridCell>& runs, const std::string& metric) {
  if (runs.empty() || !runs.front().scenes || runs.front().scenes->keys.empty()) return {};
  const auto& keys = runs.front().scenes->keys;
  std::vector<std::vector<double>> out;
  for (const auto& r : runs) {
    if (!r.scenes) return {};
    std::map<std::string, size_t> index;
    for (size_t i = 0; i < r.scenes->keys.size(); ++i) index.emplace(r.scenes->keys[i], i);
    const auto& values = r.scenes->metric(metric);
    auto& row = out.emplace_back();
    for (const auto& key : keys) {
      const auto it = index.find(key);
      if (it == index.end() || std::isnan(values[it->second])) return {};
      row.push_back(values[it->second]);
    }
  }
  return out;
}

bool metric_available(const std::vector<GridCell>& runs, const std::string& metric) {
  for (const auto& r : runs)
    if (std::isnan(metric_value(r, metric))) return false;
  return !runs.empty();
}

std::string number(double v) { return std::isnan(v) ? std::string() : fmt::format("{:.6f}", v); }

// The cell means and the pairwise differences at each setting, for one metric.
void add_setting_stats(std::vector<GridStat>& out, const std::vector<GridCell>& runs, const std::string& metric,
                       const std::vector<ScoredRun>& scored, const BootstrapOptions& options) {
  const auto series = series_of(runs);
  for (const auto& setting : settings_of(runs)) {
    double x = std::nan("");
    for (const auto& r : runs)
      if (r.setting == setting) x = r.x;
    for (size_t a = 0; a < series.size(); ++a) {
      auto at_a = runs_at(scored, series[a], x);
      if (at_a.empty()) continue;
      out.push_back({"mean", series[a], "", setting, metric, x, bootstrap_interval(at_a, mean_value, options)});
      for (size_t b = a + 1; b < series.size(); ++b) {
        const auto at_b = runs_at(scored, series[b], x);
        if (at_b.empty() || metric != "psnr") continue;
        auto both = at_a;
        both.insert(both.end(), at_b.begin(), at_b.end());
        const auto difference = [&, sa = series[a], sb = series[b]](const std::vector<ScoredRun>& r) {
          return mean_value(runs_of(r, sa)) - mean_value(runs_of(r, sb));
        };
        out.push_back(
            {"difference", series[a], series[b], setting, metric, x, bootstrap_interval(both, difference, options)});
      }
    }
  }
}

// Each model's gain per 4x and, for PSNR, each ordered pair's difference of gains.
void add_gain_stats(std::vector<GridStat>& out, const std::vector<GridCell>& runs, const std::string& metric,
                    const std::vector<ScoredRun>& scored, const BootstrapOptions& options) {
  const bool higher = metric != "lpips";
  const auto series = series_of(runs);
  const auto gain = [higher](const std::vector<ScoredRun>& r) { return gain_per_4x(r, higher); };
  const auto sloped = runs_with_a_slope(scored);
  for (const auto& s : series)
    out.push_back({"gain", s, "", "", metric, std::nan(""), bootstrap_interval(runs_of(sloped, s), gain, options)});
  if (metric != "psnr") return;
  for (size_t a = 0; a < series.size(); ++a)
    for (size_t b = a + 1; b < series.size(); ++b) {
      auto both = runs_of(sloped, series[a]);
      const auto of_b = runs_of(sloped, series[b]);
      both.insert(both.end(), of_b.begin(), of_b.end());
      const auto difference = [sa = series[a], sb = series[b]](const std::vector<ScoredRun>& r) {
        return gain_per_4x(runs_of(r, sa)) - gain_per_4x(runs_of(r, sb));
      };
      out.push_back({"gain_difference", series[a], series[b], "", metric, std::nan(""),
                     bootstrap_interval(both, difference, options)});
    }
}

}  // namespace

std::vector<ScoredRun> scored_runs(const std::vector<GridCell>& runs, const std::string& metric) {
  const auto done = done_runs(runs);
  const auto scenes = paired_scenes(done, metric);
  std::vector<ScoredRun> out;
  for (size_t i = 0; i < done.size(); ++i)
    out.push_back({done[i].series, done[i].x, done[i].seed, metric_value(done[i], metric),
                   scenes.empty() ? std::vector<double>{} : scenes[i]});
  return out;
}

std::vector<GridStat> grid_stats(const std::vector<GridCell>& runs, bool with_gain, const BootstrapOptions& options) {
  const auto done = done_runs(runs);
  std::vector<GridStat> out;
  for (const std::string metric : {"psnr", "ssim", "lpips"}) {
    if (!metric_available(done, metric)) continue;
    const auto scored = scored_runs(done, metric);
    add_setting_stats(out, done, metric, scored, options);
    if (with_gain) add_gain_stats(out, done, metric, scored, options);
  }
  return out;
}

std::string grid_stats_csv(const std::vector<GridStat>& stats) {
  std::string out = "statistic,series,other,setting,x,metric,estimate,lo,hi,seeds,scenes,resampled\n";
  for (const auto& s : stats)
    out += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{}\n", s.statistic, s.series, s.other, s.setting,
                       std::isnan(s.x) ? std::string() : fmt::format("{:g}", s.x), s.metric,
                       number(s.interval.estimate), number(s.interval.lo), number(s.interval.hi), s.interval.seeds,
                       s.interval.scenes, s.interval.resampled());
  return out;
}

std::string grid_stats_markdown(const std::vector<GridStat>& stats) {
  std::string out =
      "| PSNR gain per 4x data | estimate | 95 % interval | seeds (fewest) | test scenes | interval redraws |\n"
      "|---|---|---|---|---|---|\n";
  bool any = false;
  for (const auto& s : stats) {
    if (s.metric != "psnr" || (s.statistic != "gain" && s.statistic != "gain_difference")) continue;
    const auto& i = s.interval;
    const auto name = s.statistic == "gain" ? paper_name(s.series) : paper_name(s.series) + " - " + paper_name(s.other);
    const auto range = std::isnan(i.lo) ? std::string("-") : fmt::format("[{:.2f}, {:.2f}]", i.lo, i.hi);
    out += fmt::format("| {} | {:.2f} | {} | {} | {} | {} |\n", name, i.estimate, range, i.seeds,
                       i.scenes == 0 ? std::string("not kept") : std::to_string(i.scenes), i.resampled());
    any = true;
  }
  if (!any) return "";
  return out +
         "\nThe gain: the least-squares slope of PSNR against log4(training scenes) over every subset, each seed its "
         "own intercept (the paper's Avg. Gain). The interval: a percentile bootstrap redrawing each model's seeds "
         "and, where every run kept its per-scene scores, the test scenes (one draw for all runs). Redrawing seeds "
         "alone, two seeds span no more than their own two gains.\n";
}

}  // namespace uplvsm::study
