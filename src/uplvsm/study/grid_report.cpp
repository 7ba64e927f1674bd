#include "uplvsm/study/grid_report.h"

#include <cmath>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"

namespace uplvsm::study {

namespace fs = std::filesystem;

namespace {

void write_text(const fs::path& path, const std::string& text) {
  io::write_file_atomic(path.string(), text.data(), text.size());
}

// curves.csv and curves.png: every trained run's held-out PSNR against the step, to show where it levels off.
bool write_curves(const std::vector<RunCurve>& runs, const fs::path& out, const std::string& title) {
  std::vector<io::Series> curves;
  std::string csv = "series,setting,seed,step,psnr\n";
  for (const auto& r : runs) {
    auto c = held_out_curve(r);
    for (size_t i = 0; i < c.x.size(); ++i)
      csv += fmt::format("{},{},{},{:g},{:.6f}\n", r.series, r.setting, r.seed, c.x[i], c.y[i]);
    if (!c.x.empty()) curves.push_back(std::move(c));
  }
  if (curves.empty()) return false;
  write_text(out / "curves.csv", csv);
  io::PlotOptions po;
  po.title = title + ": held-out PSNR during training";
  po.xlabel = "step";
  po.ylabel = "psnr";
  po.width = 1200;
  po.height = 720;
  io::write_png((out / "curves.png").string(), io::plot_lines(curves, po));
  return true;
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

std::string write_grid_report(const std::vector<GridCell>& runs, const std::vector<RunCurve>& curves,
                              const std::string& out_dir, const GridFigure& fig, const std::string& description) {
  const fs::path out(out_dir);
  const auto cells = mean_over_seeds(runs);
  const auto table = grid_markdown(cells, fig.with_gain);
  write_text(out / "table.md", table);
  write_text(out / "table.csv", grid_csv(runs));
  std::string readme = "# " + fig.title + "\n\n" + description +
                       "\n\nPSNR / SSIM / LPIPS on the test set (per-scene mean, then mean over scenes; over seeds, "
                       "the mean ± half the range). Every run: table.csv.\n\n" +
                       table + "\n";
  bool any_lpips = false;
  for (const auto& c : cells) any_lpips |= !std::isnan(c.lpips);
  for (std::string metric : {"psnr", "ssim", "lpips"}) {
    if (metric == "lpips" && !any_lpips) continue;
    io::PlotOptions po;
    po.width = 960;
    po.height = 600;
    po.title = fig.title + ": " + metric;
    po.xlabel = fig.xlabel;
    po.ylabel = metric;
    po.log_x = fig.log_x;
    io::write_png((out / (metric + ".png")).string(), grid_plot(cells, metric, po));
    readme += "![" + metric + "](" + metric + ".png)\n";
  }
  if (write_curves(curves, out, fig.title))
    readme += "\nHeld-out PSNR during training (curves.csv):\n\n![curves](curves.png)\n";
  write_text(out / "README.md", readme);
  return table;
}

}  // namespace uplvsm::study
