#include "uplvsm/study/grid_report.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <stdexcept>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"
#include "uplvsm/study/csv_fields.h"
#include "uplvsm/study/grid_stats.h"

namespace uplvsm::study {

namespace fs = std::filesystem;

namespace {

void write_text(const fs::path& path, const std::string& text) {
  io::write_file_atomic(path.string(), text.data(), text.size());
}

// curves.csv, one curves_<series>.png per series (every trained run's held-out PSNR against the step) and
// levelling.md (has each run levelled off?); returns the README's section, empty without any curve.
std::string write_curves(const std::vector<RunCurve>& runs, const fs::path& out, const std::string& title) {
  std::map<std::string, std::vector<io::Series>> by_series;
  std::string csv = "series,setting,seed,step,psnr\n";
  std::string table = fmt::format(
      "| run | steps | held-out PSNR | training PSNR, last 1000 steps | slope, last 2000 steps (dB / 1000) | "
      "levelled (< {:g}) |\n|---|---|---|---|---|---|\n",
      kLevelledSlope);
  for (const auto& r : runs) {
    auto c = held_out_curve(r);
    for (size_t i = 0; i < c.x.size(); ++i)
      csv += fmt::format("{},{},{},{:g},{:.6f}\n", r.series, r.setting, r.seed, c.x[i], c.y[i]);
    if (c.x.empty()) continue;
    const auto l = levelling(c);
    const double train = training_psnr(r);
    table += fmt::format("| {} | {:g} | {:.2f} | {} | {} | {} |\n", c.name, l.last_step, l.final_psnr,
                         std::isnan(train) ? std::string("-") : fmt::format("{:.2f}", train),
                         std::isnan(l.slope) ? std::string("-") : fmt::format("{:+.3f}", l.slope),
                         std::isnan(l.slope) ? "too few points"
                         : l.levelled()      ? "yes"
                                             : "no");
    c.name = fmt::format("{} s{}", r.setting, r.seed);
    c.markers = true;
    by_series[r.series].push_back(std::move(c));
  }
  if (by_series.empty()) return "";
  write_text(out / "curves.csv", csv);
  write_text(out / "levelling.md", table);
  std::string readme =
      "\nHeld-out PSNR during training (curves.csv), the training PSNR at the end (the two sample views alike, not\n"
      "identically: compare its gap to the held-out PSNR across subsets) and whether each run levelled off:\n\n" +
      table;
  for (const auto& [series, curves] : by_series) {
    io::PlotOptions po;
    po.title = fmt::format("{}: {}, held-out PSNR during training", title, paper_name(series));
    po.xlabel = "step";
    po.ylabel = metric_label("psnr");
    po.width = 1200;
    po.height = 720;
    const auto file = "curves_" + series + ".png";
    io::write_png((out / file).string(), io::plot_lines(curves, po));
    readme += "\n![" + series + " curves](" + file + ")\n";
  }
  return readme;
}

}  // namespace

io::Series held_out_curve(const RunCurve& run) {
  io::Series curve{fmt::format("{} {} s{}", run.series, run.setting, run.seed), {}, {}};
  std::ifstream in(run.metrics_path);
  for (std::string line; std::getline(in, line);) {
    auto j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (j.is_discarded() || !j.contains("eval") || !j["eval"].contains("psnr") || !j.contains("step")) continue;
    curve.x.push_back(j["step"].get<double>());
    curve.y.push_back(j["eval"]["psnr"].get<double>());
  }
  return curve;
}

double training_psnr(const RunCurve& run, double window) {
  std::vector<std::pair<double, double>> step_mse;
  std::ifstream in(run.metrics_path);
  for (std::string line; std::getline(in, line);) {
    auto j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (j.is_discarded() || !j.contains("mse") || !j["mse"].is_number() || !j.contains("step")) continue;
    if (j.value("skipped", false)) continue;
    step_mse.emplace_back(j["step"].get<double>(), j["mse"].get<double>());
  }
  if (step_mse.empty()) return std::nan("");
  const double last = step_mse.back().first;
  double sum = 0;
  int n = 0;
  for (const auto& [step, mse] : step_mse)
    if (step > last - window) sum += mse, ++n;
  return -10 * std::log10(sum / n);
}

namespace {

// Cells from a CSV of series,setting,x[,seed],psnr,ssim,lpips (lpips may be empty); `what` names the option in
// errors, which name the file and the line.
std::vector<GridCell> read_cells_csv(const std::string& path, bool with_seed, const std::string& what) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(what + " " + path + ": cannot open file");
  const std::string header = with_seed ? "series,setting,x,seed,psnr,ssim,lpips" : "series,setting,x,psnr,ssim,lpips";
  std::string line;
  if (!std::getline(in, line) || line != header)
    throw std::runtime_error(fmt::format("{} {}: line 1 must be '{}'", what, path, header));
  std::vector<GridCell> cells;
  for (int n = 2; std::getline(in, line); ++n) {
    if (line.empty()) continue;
    const auto f = csv_fields(line);
    GridCell c;
    try {
      if (f.size() != (with_seed ? 7u : 6u)) throw std::invalid_argument("fields");
      const size_t k = with_seed ? 1 : 0;  // the metrics' offset past the seed
      c.series = f[0], c.setting = f[1], c.x = csv_number(f[2]);
      if (with_seed) {
        const double seed = csv_number(f[3]);
        if (seed < 0 || seed > 9e15 || seed != std::floor(seed)) throw std::invalid_argument(f[3]);
        c.seed = static_cast<int64_t>(seed);
      }
      c.psnr = csv_number(f[3 + k]), c.ssim = csv_number(f[4 + k]);
      c.lpips = f[5 + k].empty() ? std::nan("") : csv_number(f[5 + k]);
    } catch (const std::exception&) {
      throw std::runtime_error(fmt::format("{} {} line {}: expected {}, got '{}'", what, path, n, header, line));
    }
    cells.push_back(c);
  }
  return cells;
}

}  // namespace

std::vector<GridCell> read_reference_cells(const std::string& path) {
  return read_cells_csv(path, false, "study --reference");
}

std::vector<GridCell> read_table_cells(const std::string& path) {
  auto cells = read_cells_csv(path, true, "study --from-table");
  const auto scenes_path = fs::path(path).parent_path() / "scenes.csv";
  if (!fs::exists(scenes_path)) return cells;
  for (auto& run : read_study_scenes(scenes_path.string()))
    for (auto& c : cells)
      if (c.series == run.series && c.setting == run.setting && c.seed == run.seed)
        c.scenes = std::make_shared<const SceneScores>(run.scores);
  return cells;
}

std::shared_ptr<const SceneScores> run_scene_scores(const std::string& run_dir) {
  const auto path = fs::path(run_dir) / "eval" / "per_scene.csv";
  if (!fs::exists(path)) return nullptr;
  return std::make_shared<const SceneScores>(read_eval_per_scene(path.string()));
}

Levelling levelling(const io::Series& curve, double window) {
  Levelling l;
  if (curve.x.empty()) return l;
  l.last_step = curve.x.back(), l.final_psnr = curve.y.back();
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (size_t i = 0; i < curve.x.size(); ++i) {
    if (curve.x[i] < l.last_step - window) continue;
    const double x = curve.x[i] / 1000, y = curve.y[i];
    sx += x, sy += y, sxx += x * x, sxy += x * y, ++l.points;
  }
  const double n = l.points, denominator = n * sxx - sx * sx;
  l.slope = l.points >= 3 && denominator > 0 ? (n * sxy - sx * sy) / denominator : std::nan("");
  return l;
}

std::string write_grid_report(const std::vector<GridCell>& runs, const std::vector<RunCurve>& curves,
                              const std::string& out_dir, const GridFigure& fig, const std::string& description) {
  const fs::path out(out_dir);
  const auto cells = mean_over_seeds(runs);
  const auto table = grid_markdown(cells, fig.with_gain, runs);
  write_text(out / "table.md", table);
  write_text(out / "table.csv", grid_csv(runs));
  std::vector<RunScenes> scenes;
  for (const auto& r : runs)
    if (r.runs > 0 && r.scenes) scenes.push_back({r.series, r.setting, r.seed, *r.scenes});
  if (!scenes.empty()) write_text(out / "scenes.csv", study_scenes_csv(scenes));
  const auto stats = grid_stats(runs, fig.with_gain);
  write_text(out / "stats.csv", grid_stats_csv(stats));
  std::string readme = "# " + fig.title + "\n\n" + description +
                       "\n\nPSNR / SSIM / LPIPS on the test set (per-scene mean, then mean over scenes; over seeds, "
                       "the mean ± half the range). Every run: table.csv.\n\n" +
                       table + "\n" + grid_stats_markdown(stats) +
                       "\nEvery mean, difference and gain with its interval: stats.csv; each run's score on each test "
                       "scene: scenes.csv.\n\n";
  bool any_lpips = false;
  for (const auto& c : cells) any_lpips |= !std::isnan(c.lpips);
  for (std::string metric : {"psnr", "ssim", "lpips"}) {
    if (metric == "lpips" && !any_lpips) continue;
    io::PlotOptions po;
    po.width = 960;
    po.height = 600;
    po.title = fig.title + ": " + metric_label(metric);
    po.xlabel = fig.xlabel;
    po.ylabel = metric_label(metric);
    po.log_x = fig.log_x;
    io::write_png((out / (metric + ".png")).string(), grid_plot(cells, metric, po));
    readme += "![" + metric + "](" + metric + ".png)";
    if (!fig.reference.empty()) {
      po.title = fig.reference_title + ": " + metric_label(metric);
      io::write_png((out / ("reference_" + metric + ".png")).string(), grid_plot(fig.reference, metric, po));
      readme += " ![" + fig.reference_title + "](reference_" + metric + ".png)";
    }
    readme += "\n";
  }
  readme += write_curves(curves, out, fig.title);
  write_text(out / "README.md", readme);
  return table;
}

}  // namespace uplvsm::study
