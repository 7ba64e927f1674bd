#include "uplvsm/study/study_grid.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

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

double metric_of(const GridCell& c, const std::string& metric) {
  if (metric == "psnr") return c.psnr;
  if (metric == "ssim") return c.ssim;
  if (metric == "lpips") return c.lpips;
  throw std::invalid_argument("study grid: unknown metric '" + metric + "' (expected psnr, ssim or lpips)");
}

std::string format_lpips(double v) { return std::isnan(v) ? "-" : fmt::format("{:.3f}", v); }

}  // namespace

double average_gain(const std::vector<double>& values, bool higher_is_better) {
  if (values.size() < 2) return std::numeric_limits<double>::quiet_NaN();
  for (double v : values)
    if (std::isnan(v)) return std::numeric_limits<double>::quiet_NaN();
  const double change = (values.back() - values.front()) / static_cast<double>(values.size() - 1);
  return higher_is_better ? change : -change;
}

std::vector<std::string> series_of(const std::vector<GridCell>& cells) {
  return unique_in_order(cells, &GridCell::series);
}
std::vector<std::string> settings_of(const std::vector<GridCell>& cells) {
  return unique_in_order(cells, &GridCell::setting);
}

std::vector<GridCell> mean_over_seeds(const std::vector<GridCell>& runs) {
  std::vector<GridCell> out;
  for (const auto& series : series_of(runs))
    for (const auto& setting : settings_of(runs)) {
      std::vector<const GridCell*> group;
      for (const auto& r : runs)
        if (r.series == series && r.setting == setting) group.push_back(&r);
      if (group.empty()) continue;
      GridCell mean = *group.front();
      mean.psnr = mean.ssim = mean.lpips = 0;
      double lo = group.front()->psnr, hi = lo;
      for (const auto* r : group) {
        mean.psnr += r->psnr / static_cast<double>(group.size());
        mean.ssim += r->ssim / static_cast<double>(group.size());
        mean.lpips += r->lpips / static_cast<double>(group.size());  // NaN stays NaN: no made-up LPIPS
        lo = std::min(lo, r->psnr);
        hi = std::max(hi, r->psnr);
      }
      mean.runs = static_cast<int64_t>(group.size());
      mean.psnr_spread = (hi - lo) / 2;
      out.push_back(mean);
    }
  return out;
}

std::string grid_markdown(const std::vector<GridCell>& cells, bool with_gain) {
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
    std::vector<double> psnr, ssim, lpips;
    for (const auto& s : settings) {
      const auto* c = find_cell(cells, name, s);
      if (!c) {
        out += " (not run) |";
        psnr.push_back(std::nan(""));
        ssim.push_back(std::nan(""));
        lpips.push_back(std::nan(""));
        continue;
      }
      const auto spread = c->runs > 1 ? fmt::format(" ±{:.2f}", c->psnr_spread) : std::string();
      out += fmt::format(" {:.2f}{} / {:.3f} / {} |", c->psnr, spread, c->ssim, format_lpips(c->lpips));
      psnr.push_back(c->psnr);
      ssim.push_back(c->ssim);
      lpips.push_back(c->lpips);
    }
    if (with_gain) {
      auto gain = [](double v, int digits) {
        return std::isnan(v) ? std::string("-") : fmt::format("{:.{}f}", v, digits);
      };
      out += fmt::format(" {} / {} / {} |", gain(average_gain(psnr, true), 2), gain(average_gain(ssim, true), 3),
                         gain(average_gain(lpips, false), 3));
    }
    out += "\n";
  }
  return out;
}

std::string grid_csv(const std::vector<GridCell>& cells) {
  std::string out = "series,setting,x,seed,psnr,ssim,lpips\n";
  for (const auto& c : cells)
    out += fmt::format("{},{},{},{},{:.6f},{:.6f},{}\n", c.series, c.setting, c.x, c.seed, c.psnr, c.ssim,
                       std::isnan(c.lpips) ? std::string() : fmt::format("{:.6f}", c.lpips));
  return out;
}

torch::Tensor grid_plot(const std::vector<GridCell>& cells, const std::string& metric, io::PlotOptions options) {
  std::vector<io::Series> lines;
  for (const auto& name : series_of(cells)) {
    io::Series line{name, {}, {}};
    for (const auto& c : cells) {
      if (c.series != name) continue;
      line.x.push_back(c.x);
      line.y.push_back(metric_of(c, metric));
    }
    lines.push_back(std::move(line));
  }
  return io::plot_lines(lines, options);
}

}  // namespace uplvsm::study
