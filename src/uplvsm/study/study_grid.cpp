#include "uplvsm/study/study_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>

#include "uplvsm/study/grid_stats.h"

namespace uplvsm::study {

namespace {

std::vector<std::string> unique_in_order(const std::vector<GridCell>& cells, std::string GridCell::*field) {
  std::vector<std::string> out;
  for (const auto& c : cells)
    if (std::find(out.begin(), out.end(), c.*field) == out.end()) out.push_back(c.*field);
  return out;
}

const GridCell* find_cell(const std::vector<GridCell>& cells, const std::string& series, const std::string& setting) {
  for (const auto& c : cells)
    if (c.series == series && c.setting == setting) return &c;
  return nullptr;
}

double spread_of(const GridCell& c, const std::string& metric) {
  return metric == "psnr" ? c.psnr_spread : metric == "ssim" ? c.ssim_spread : c.lpips_spread;
}

// The gain column's cell: the PSNR gain per 4x with its interval, then SSIM's and LPIPS's (study/scaling_gain.h).
std::string gain_cell(const std::vector<GridCell>& runs, const std::string& series) {
  std::string out;
  for (const std::string metric : {"psnr", "ssim", "lpips"}) {
    const auto of_series = runs_with_a_slope(runs_of(scored_runs(runs, metric), series));
    const auto gain = [higher = metric != "lpips"](const std::vector<ScoredRun>& r) { return gain_per_4x(r, higher); };
    const auto i = metric == "psnr" ? bootstrap_interval(of_series, gain) : Interval{gain(of_series)};
    if (!out.empty()) out += " / ";
    if (std::isnan(i.estimate)) {
      out += "-";
    } else {
      out += fmt::format("{:.{}f}", i.estimate, metric == "psnr" ? 2 : 3);
      if (!std::isnan(i.lo)) out += fmt::format(" [{:.2f}, {:.2f}]", i.lo, i.hi);
    }
  }
  return out;
}

std::string format_lpips(double v) { return std::isnan(v) ? "-" : fmt::format("{:.3f}", v); }

}  // namespace

double metric_value(const GridCell& c, const std::string& metric) {
  if (metric == "psnr") return c.psnr;
  if (metric == "ssim") return c.ssim;
  if (metric == "lpips") return c.lpips;
  throw std::invalid_argument("study grid: unknown metric '" + metric + "' (expected psnr, ssim or lpips)");
}

std::vector<std::string> series_of(const std::vector<GridCell>& cells) {
  return unique_in_order(cells, &GridCell::series);
}
std::string paper_name(const std::string& series) {
  if (series == "uplvsm") return "UP-LVSM";
  if (series == "ptlvsm") return "PT-LVSM";
  if (series == "lvsm") return "LVSM";
  return series;
}

std::string metric_label(const std::string& metric) {
  if (metric == "psnr") return "PSNR (dB)";
  if (metric == "ssim") return "SSIM";
  if (metric == "lpips") return "LPIPS";
  return metric;
}

std::vector<std::string> settings_of(const std::vector<GridCell>& cells) {
  return unique_in_order(cells, &GridCell::setting);
}

std::vector<GridCell> mean_over_seeds(const std::vector<GridCell>& runs) {
  std::vector<GridCell> out;
  for (const auto& series : series_of(runs))
    for (const auto& setting : settings_of(runs)) {
      std::vector<const GridCell*> group;
      const GridCell* planned = nullptr;  // a run not done yet: the cell reads "(not run)" while no seed is done
      for (const auto& r : runs)
        if (r.series == series && r.setting == setting) (r.runs > 0 ? group.push_back(&r) : void(planned = &r));
      if (group.empty()) {
        if (planned) out.push_back(*planned);
        continue;
      }
      GridCell mean = *group.front();
      mean.runs = static_cast<int64_t>(group.size());
      // NaN stays NaN (LPIPS without its weights): no made-up number.
      for (auto [value, spread] :
           {std::pair{&GridCell::psnr, &GridCell::psnr_spread}, std::pair{&GridCell::ssim, &GridCell::ssim_spread},
            std::pair{&GridCell::lpips, &GridCell::lpips_spread}}) {
        double sum = 0, lo = group.front()->*value, hi = lo;
        for (const auto* r : group) {
          sum += r->*value;
          lo = std::min(lo, r->*value), hi = std::max(hi, r->*value);
        }
        mean.*value = sum / static_cast<double>(group.size());
        mean.*spread = std::isnan(sum) ? sum : (hi - lo) / 2;
      }
      if (group.size() > 1) mean.scenes = nullptr;  // a seed's scenes are not the mean's
      out.push_back(mean);
    }
  return out;
}

std::string grid_markdown(const std::vector<GridCell>& cells, bool with_gain, const std::vector<GridCell>& runs) {
  const auto series = series_of(cells);
  const auto settings = settings_of(cells);
  std::string out = "| Method |";
  for (const auto& s : settings) out += " " + s + " |";
  if (with_gain) out += " Avg. gain |";
  out += "\n|---|";
  for (size_t i = 0; i < settings.size() + (with_gain ? 1 : 0); ++i) out += "---|";
  out += "\n";
  for (const auto& name : series) {
    out += "| " + name + " |";
    for (const auto& s : settings) {
      const auto* c = find_cell(cells, name, s);
      if (!c || c->runs == 0) {
        out += " (not run) |";
        continue;
      }
      const auto spread = c->runs > 1 ? fmt::format(" ±{:.2f}", c->psnr_spread) : std::string();
      out += fmt::format(" {:.2f}{} / {:.3f} / {} |", c->psnr, spread, c->ssim, format_lpips(c->lpips));
    }
    if (with_gain) out += " " + gain_cell(runs.empty() ? cells : runs, name) + " |";
    out += "\n";
  }
  return out;
}

std::string grid_csv(const std::vector<GridCell>& cells) {
  std::string out = "series,setting,x,seed,psnr,ssim,lpips\n";
  for (const auto& c : cells)
    if (c.runs > 0)
      out += fmt::format("{},{},{},{},{:.6f},{:.6f},{}\n", c.series, c.setting, c.x, c.seed, c.psnr, c.ssim,
                         std::isnan(c.lpips) ? std::string() : fmt::format("{:.6f}", c.lpips));
  return out;
}

torch::Tensor grid_plot(const std::vector<GridCell>& cells, const std::string& metric, io::PlotOptions options) {
  // Where an x of 0 stands on a log axis: a decade left of the smallest positive x.
  double smallest = std::numeric_limits<double>::infinity();
  for (const auto& c : cells)
    if (c.x > 0) smallest = std::min(smallest, c.x);
  const double zero_at = std::isfinite(smallest) ? smallest / 10 : 1;
  auto plotted = [&](double x) { return options.log_x && x == 0 ? zero_at : x; };
  std::vector<double> xs;
  for (const auto& c : cells)
    if (std::find(xs.begin(), xs.end(), c.x) == xs.end()) xs.push_back(c.x);
  std::sort(xs.begin(), xs.end());
  options.x_ticks.clear(), options.x_tick_labels.clear();
  for (double x : xs) {
    options.x_ticks.push_back(plotted(x));
    // Three significant digits below 1 (a variance's sd 0.0316, not 0.0316228); whole scene counts as they are.
    options.x_tick_labels.push_back(x < 1 ? fmt::format("{:.3g}", x) : fmt::format("{:g}", x));
  }
  std::vector<io::Series> lines;
  for (const auto& name : series_of(cells)) {
    io::Series line{paper_name(name), {}, {}};
    line.markers = true;
    for (const auto& c : cells) {
      if (c.series != name || c.runs == 0) continue;
      line.x.push_back(plotted(c.x));
      line.y.push_back(metric_value(c, metric));
      line.y_err.push_back(c.runs > 1 ? spread_of(c, metric) : 0.0);
    }
    lines.push_back(std::move(line));
  }
  return io::plot_lines(lines, options);
}

}  // namespace uplvsm::study
