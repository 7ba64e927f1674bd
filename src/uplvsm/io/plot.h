// Minimal line plots rendered straight to an RGB image (training curves, metric sweeps) without any plotting
// library: axes with round-number ticks and numeric labels (or ticks only where the data is), optional log axes,
// markers at measured points, error bars, title, axis labels and a legend.
#pragma once
#include <torch/torch.h>

#include <string>
#include <utility>
#include <vector>

namespace uplvsm::io {

struct Series {
  Series() = default;
  Series(std::string name, std::vector<double> x, std::vector<double> y)
      : name(std::move(name)), x(std::move(x)), y(std::move(y)) {}

  std::string name;  // shown in the legend when non-empty
  std::vector<double> x, y;
  std::vector<double> y_err;  // each point's error bar, y - e to y + e (e.g. half the seeds' range); empty: none
  bool markers = false;       // a marker at every point (one shape per series), not only at isolated points
};

struct PlotOptions {
  std::string title, xlabel, ylabel;
  bool log_x = false;
  bool log_y = false;
  int width = 800, height = 480;
  // Ticks only at these x values (data units, e.g. the measured settings), labelled x_tick_labels[i] when given
  // (else the number); the axis then spans them with a margin. Empty: round-number ticks.
  std::vector<double> x_ticks{};
  std::vector<std::string> x_tick_labels{};
  // Spans of x (data units) shaded behind the lines, e.g. where a camera path lies between its inputs; clipped to
  // the axis.
  std::vector<std::pair<double, double>> x_bands{};
};

// uint8 [height, width, 3]. Points with a non-finite coordinate (or <= 0 on a log axis) are skipped and break the
// line there; isolated points are drawn as small squares. Empty series and all-empty plots are fine (unit axes).
// Series beyond 10 reuse the colours, dashed (11-20) then dotted (21-30). Throws when width < 160 or height < 120.
torch::Tensor plot_lines(const std::vector<Series>& series, const PlotOptions& opt);

// Round tick positions covering [lo, hi] (1, 2 or 5 times a power of ten, about `target` of them) and their labels;
// exposed for tests and other figures.
std::vector<double> nice_ticks(double lo, double hi, int target);
std::string format_tick(double value, double step);

}  // namespace uplvsm::io
