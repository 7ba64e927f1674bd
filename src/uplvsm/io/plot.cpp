// Line plots on an RGB image (see plot.h). Layout: title on top, y label rotated on the left, tick labels next to
// the frame, x label at the bottom, legend in the top-right corner of the plotting area.
#include "uplvsm/io/plot.h"

#include <fmt/format.h>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "uplvsm/io/raster.h"

namespace uplvsm::io {
namespace {

const Rgb kBlack{0, 0, 0}, kWhite{255, 255, 255}, kGrid{225, 225, 225}, kLegendBorder{160, 160, 160};
// matplotlib's "tab10": distinct, colour-blind friendly enough, familiar.
const Rgb kColours[10] = {{31, 119, 180}, {255, 127, 14},  {44, 160, 44},   {214, 39, 40},  {148, 103, 189},
                          {140, 86, 75},  {227, 119, 194}, {127, 127, 127}, {188, 189, 34}, {23, 190, 207}};

// One axis: limits and ticks in plotted coordinates (log10 of the value on log axes).
struct Axis {
  bool log = false;
  double lo = 0, hi = 1;
  std::vector<double> ticks;
  std::vector<std::string> labels;
};

bool usable(double v, bool log) { return std::isfinite(v) && (!log || v > 0); }
double to_axis(double v, bool log) { return log ? std::log10(v) : v; }

double nice_step(double raw) {
  double e = std::pow(10.0, std::floor(std::log10(raw)));
  double f = raw / e;
  return (f < 1.5 ? 1 : f < 3 ? 2 : f < 7 ? 5 : 10) * e;
}

// A point's error bar half-length (0 without one).
double error_of(const Series& s, size_t i) { return i < s.y_err.size() && std::isfinite(s.y_err[i]) ? s.y_err[i] : 0; }

// Data range over all usable points of one coordinate (y with its error bars); false when there is none.
bool data_range(const std::vector<Series>& series, bool use_x, bool log_x, bool log_y, double& lo, double& hi) {
  lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const auto& s : series) {
    size_t n = std::min(s.x.size(), s.y.size());
    for (size_t i = 0; i < n; ++i) {
      if (!usable(s.x[i], log_x) || !usable(s.y[i], log_y)) continue;
      const double e = use_x ? 0 : error_of(s, i);
      for (double v : {(use_x ? s.x[i] : s.y[i]) - e, (use_x ? s.x[i] : s.y[i]) + e}) {
        if (!usable(v, use_x ? log_x : log_y)) continue;
        v = to_axis(v, use_x ? log_x : log_y);
        lo = std::min(lo, v), hi = std::max(hi, v);
      }
    }
  }
  return lo <= hi;
}

// Ticks exactly at opt.x_ticks (the measured settings), the axis spanning them and the data with a margin.
Axis data_tick_axis(const std::vector<Series>& series, const PlotOptions& opt) {
  Axis a;
  a.log = opt.log_x;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (size_t i = 0; i < opt.x_ticks.size(); ++i) {
    if (!usable(opt.x_ticks[i], a.log)) continue;
    const double t = to_axis(opt.x_ticks[i], a.log);
    a.ticks.push_back(t);
    lo = std::min(lo, t), hi = std::max(hi, t);
  }
  double dlo = 0, dhi = 0;
  if (data_range(series, true, opt.log_x, opt.log_y, dlo, dhi)) lo = std::min(lo, dlo), hi = std::max(hi, dhi);
  if (!(lo <= hi)) lo = 0, hi = 1;
  const double margin = hi > lo ? 0.06 * (hi - lo) : 0.5;
  a.lo = lo - margin, a.hi = hi + margin;
  const double step = a.ticks.size() > 1 ? std::abs(a.ticks[1] - a.ticks[0]) : 1.0;
  for (size_t i = 0; i < opt.x_ticks.size(); ++i)
    if (usable(opt.x_ticks[i], a.log))
      a.labels.push_back(i < opt.x_tick_labels.size() ? opt.x_tick_labels[i]
                         : a.log                      ? fmt::format("{:g}", opt.x_ticks[i])
                                                      : format_tick(opt.x_ticks[i], step));
  return a;
}

Axis linear_axis(double lo, double hi, int target) {
  Axis a;
  if (hi - lo <= std::max(std::abs(lo), std::abs(hi)) * 1e-12) {  // constant data: open a window around it
    double d = lo == 0 ? 1.0 : std::abs(lo) * 0.1;
    lo -= d, hi += d;
  }
  a.ticks = nice_ticks(lo, hi, target);
  double step = a.ticks.size() > 1 ? a.ticks[1] - a.ticks[0] : 1.0;
  a.lo = a.ticks.front(), a.hi = a.ticks.back();
  for (double t : a.ticks) a.labels.push_back(format_tick(t, step));
  return a;
}

std::string format_power(int e) {
  if (e >= -3 && e <= 4) return format_tick(std::pow(10.0, e), std::pow(10.0, std::min(e, 0)));
  return fmt::format("1e{}", e);
}

// Ticks at powers of ten (every k-th decade when there are many); with at most two decades also 2x and 5x.
Axis log_axis(double lo, double hi) {
  Axis a;
  a.log = true;
  int e0 = int(std::floor(lo + 1e-9)), e1 = int(std::ceil(hi - 1e-9));
  if (e1 <= e0) e1 = e0 + 1;
  a.lo = e0, a.hi = e1;
  int every = std::max(1, (e1 - e0 + 7) / 8);
  for (int e = e0; e <= e1; e += every) {
    a.ticks.push_back(e);
    a.labels.push_back(format_power(e));
    if (e1 - e0 > 2 || e == e1) continue;
    for (int m : {2, 5}) {
      a.ticks.push_back(e + std::log10(double(m)));
      a.labels.push_back(e >= -3 && e <= 4 ? format_tick(m * std::pow(10.0, e), std::pow(10.0, std::min(e, 0)))
                                           : fmt::format("{}e{}", m, e));
    }
  }
  return a;
}

Axis make_axis(const std::vector<Series>& series, bool is_x, const PlotOptions& opt, int pixels) {
  if (is_x && !opt.x_ticks.empty()) return data_tick_axis(series, opt);
  double lo = 0, hi = 1;
  bool log = is_x ? opt.log_x : opt.log_y;
  if (!data_range(series, is_x, opt.log_x, opt.log_y, lo, hi)) lo = 0, hi = 1;  // log: 1 to 10
  return log ? log_axis(lo, hi) : linear_axis(lo, hi, std::max(2, pixels / (is_x ? 90 : 55)));
}

struct Layout {
  int x0, y0, x1, y1;  // plotting frame, inclusive pixel coordinates
  int title_scale;
};

Layout compute_layout(const PlotOptions& opt, const Axis& ax, const Axis& ay) {
  const int pad = 8, tick = 4;
  Layout l;
  l.title_scale = opt.width >= 480 ? 2 : 1;
  int ytick_w = 0;
  for (const auto& s : ay.labels) ytick_w = std::max(ytick_w, text_width(s));
  int top = pad + (opt.title.empty() ? 0 : text_height(opt.title, l.title_scale) + pad);
  int left = pad + (opt.ylabel.empty() ? 0 : text_height(opt.ylabel) + pad) + ytick_w + tick + 3;
  int bottom = tick + 3 + text_height("0") + pad + (opt.xlabel.empty() ? 0 : text_height(opt.xlabel) + pad);
  int right = pad + (ax.labels.empty() ? 0 : text_width(ax.labels.back()) / 2);
  l.x0 = left, l.x1 = opt.width - 1 - right, l.y0 = top + text_height("0") / 2, l.y1 = opt.height - 1 - bottom;
  return l;
}

double to_pixel(double v, const Axis& a, int p0, int p1) { return p0 + (v - a.lo) / (a.hi - a.lo) * (p1 - p0); }

void draw_axes(torch::Tensor& img, const Layout& l, const Axis& ax, const Axis& ay) {
  for (size_t i = 0; i < ax.ticks.size(); ++i) {
    int x = int(std::lround(to_pixel(ax.ticks[i], ax, l.x0, l.x1)));
    draw_line(img, x, l.y0 + 1, x, l.y1 - 1, kGrid);
    draw_line(img, x, l.y1, x, l.y1 + 4, kBlack);
    draw_text(img, x - text_width(ax.labels[i]) / 2, l.y1 + 7, ax.labels[i], kBlack);
  }
  for (size_t i = 0; i < ay.ticks.size(); ++i) {
    int y = int(std::lround(to_pixel(ay.ticks[i], ay, l.y1, l.y0)));
    draw_line(img, l.x0 + 1, y, l.x1 - 1, y, kGrid);
    draw_line(img, l.x0 - 4, y, l.x0, y, kBlack);
    draw_text(img, l.x0 - 7 - text_width(ay.labels[i]), y - text_height("0") / 2, ay.labels[i], kBlack);
  }
  draw_rect(img, l.x0, l.y0, l.x1 - l.x0 + 1, l.y1 - l.y0 + 1, kBlack);
}

void draw_labels(torch::Tensor& img, const Layout& l, const PlotOptions& opt) {
  const int pad = 8;
  if (!opt.title.empty())
    draw_text(img, (opt.width - text_width(opt.title, l.title_scale)) / 2, pad, opt.title, kBlack, l.title_scale);
  if (!opt.xlabel.empty())
    draw_text(img, (l.x0 + l.x1 - text_width(opt.xlabel)) / 2, opt.height - pad - text_height(opt.xlabel), opt.xlabel,
              kBlack);
  if (!opt.ylabel.empty()) {  // drawn horizontally, then turned a quarter counter-clockwise
    torch::Tensor label = blank_image(text_height(opt.ylabel), text_width(opt.ylabel));
    draw_text(label, 0, 0, opt.ylabel, kBlack);
    torch::Tensor turned = torch::rot90(label, 1, {0, 1}).contiguous();
    paste(img, turned, pad, (l.y0 + l.y1 - int(turned.size(0))) / 2);
  }
}

// Series 1-10 solid, 11-20 dashed, 21-30 dotted, then again: the colour repeats every 10, the pair every 30.
struct LineStyle {
  Rgb colour;
  int on, off;  // pixels drawn, then skipped, along the line; off 0 is solid
};

LineStyle series_style(size_t i) {
  static const int kOn[3] = {1, 8, 2}, kOff[3] = {0, 5, 4};
  return {kColours[i % 10], kOn[(i / 10) % 3], kOff[(i / 10) % 3]};
}

void draw_styled_line(torch::Tensor& img, int x0, int y0, int x1, int y1, const LineStyle& st) {
  const double length = std::hypot(x1 - x0, y1 - y0);
  if (st.off == 0 || length < 1) return draw_line(img, x0, y0, x1, y1, st.colour, 2);
  auto at = [&](double t, int a, int b) { return int(std::lround(a + (b - a) * std::min(t, length) / length)); };
  for (double t = 0; t < length; t += st.on + st.off)
    draw_line(img, at(t, x0, x1), at(t, y0, y1), at(t + st.on, x0, x1), at(t + st.on, y0, y1), st.colour, 2);
}

// Series i's marker centred at (x, y): a filled square, a diamond, a triangle or an open square, in turn.
void draw_marker(torch::Tensor& img, int x, int y, size_t i, Rgb colour) {
  const int r = 4;
  switch (i % 4) {
    case 0: return fill_rect(img, x - r + 1, y - r + 1, 2 * r - 1, 2 * r - 1, colour);
    case 1:
      for (int dy = -r - 1; dy <= r + 1; ++dy)
        draw_line(img, x - (r + 1 - std::abs(dy)), y + dy, x + (r + 1 - std::abs(dy)), y + dy, colour);
      return;
    case 2:
      for (int dy = -r; dy <= r; ++dy)
        draw_line(img, x - (dy + r) / 2 - 1, y + dy, x + (dy + r) / 2 + 1, y + dy, colour);
      return;
    default: return draw_rect(img, x - r, y - r, 2 * r + 1, 2 * r + 1, colour, 2);
  }
}

// Lines between consecutive usable points, clipped to the frame; error bars with caps; markers at every point
// (s.markers) or at isolated points only (4x4 squares).
void draw_series(torch::Tensor& img, const Layout& l, const Axis& ax, const Axis& ay, const Series& s,
                 const LineStyle& style, size_t index) {
  if (l.y1 - l.y0 < 2 || l.x1 - l.x0 < 2) return;
  torch::Tensor area = img.narrow(0, l.y0 + 1, l.y1 - l.y0 - 1).narrow(1, l.x0 + 1, l.x1 - l.x0 - 1);
  size_t n = std::min(s.x.size(), s.y.size());
  auto ok = [&](size_t i) { return i < n && usable(s.x[i], ax.log) && usable(s.y[i], ay.log); };
  auto px = [&](size_t i) { return to_pixel(to_axis(s.x[i], ax.log), ax, l.x0, l.x1) - (l.x0 + 1); };
  auto py = [&](size_t i) { return to_pixel(to_axis(s.y[i], ay.log), ay, l.y1, l.y0) - (l.y0 + 1); };
  auto clamp_px = [](double v) { return int(std::lround(std::clamp(v, -1e8, 1e8))); };
  auto py_of = [&](double y) { return to_pixel(to_axis(y, ay.log), ay, l.y1, l.y0) - (l.y0 + 1); };
  for (size_t i = 0; i < n; ++i) {
    if (!ok(i)) continue;
    bool prev = i > 0 && ok(i - 1), next = ok(i + 1);
    if (next) draw_styled_line(area, clamp_px(px(i)), clamp_px(py(i)), clamp_px(px(i + 1)), clamp_px(py(i + 1)), style);
    const double e = error_of(s, i);
    if (e > 0 && usable(s.y[i] - e, ay.log)) {
      const int x = clamp_px(px(i)), top = clamp_px(py_of(s.y[i] + e)), bottom = clamp_px(py_of(s.y[i] - e));
      draw_line(area, x, top, x, bottom, style.colour, 2);
      draw_line(area, x - 5, top, x + 5, top, style.colour, 2);
      draw_line(area, x - 5, bottom, x + 5, bottom, style.colour, 2);
    }
    if (s.markers)
      draw_marker(area, clamp_px(px(i)), clamp_px(py(i)), index, style.colour);
    else if (!next && !prev)
      fill_rect(area, clamp_px(px(i)) - 2, clamp_px(py(i)) - 2, 4, 4, style.colour);
  }
}

void draw_legend(torch::Tensor& img, const Layout& l, const std::vector<Series>& series) {
  int name_w = 0, count = 0;
  for (const auto& s : series)
    if (!s.name.empty()) name_w = std::max(name_w, text_width(s.name)), ++count;
  if (count == 0) return;
  const int row = 14, sample = 18;
  int w = 6 + sample + 6 + name_w + 6, h = 6 + count * row;
  // The corner of the frame whose box covers the fewest series pixels (coloured: channels apart), top right first.
  int x = l.x1 - 8 - w, y = l.y0 + 8;
  int64_t fewest = -1;
  for (auto [cx, cy] : {std::pair{l.x1 - 8 - w, l.y0 + 8}, std::pair{l.x0 + 8, l.y0 + 8},
                        std::pair{l.x1 - 8 - w, l.y1 - 8 - h}, std::pair{l.x0 + 8, l.y1 - 8 - h}}) {
    if (cx < 0 || cy < 0 || cx + w > img.size(1) || cy + h > img.size(0)) continue;
    auto box = img.narrow(0, cy, h).narrow(1, cx, w).to(torch::kInt32);
    const int64_t covered = ((std::get<0>(box.max(2)) - std::get<0>(box.min(2))) > 40).sum().item<int64_t>();
    if (fewest < 0 || covered < fewest) fewest = covered, x = cx, y = cy;
  }
  fill_rect(img, x, y, w, h, kWhite);
  draw_rect(img, x, y, w, h, kLegendBorder);
  int yy = y + 5;
  for (size_t i = 0; i < series.size(); ++i) {
    if (series[i].name.empty()) continue;
    draw_styled_line(img, x + 6, yy + 4, x + 6 + sample, yy + 4, series_style(i));
    if (series[i].markers) draw_marker(img, x + 6 + sample / 2, yy + 4, i, series_style(i).colour);
    draw_text(img, x + 6 + sample + 6, yy, series[i].name, kBlack);
    yy += row;
  }
}

}  // namespace

std::vector<double> nice_ticks(double lo, double hi, int target) {
  if (!std::isfinite(lo) || !std::isfinite(hi) || hi <= lo) throw std::runtime_error("nice_ticks: need lo < hi");
  double step = nice_step((hi - lo) / std::max(target, 1));
  double first = std::floor(lo / step + 1e-9), last = std::ceil(hi / step - 1e-9);
  std::vector<double> ticks;
  for (double k = first; k <= last + 0.5 && ticks.size() < 1000; ++k)
    ticks.push_back(std::abs(k) < 0.5 ? 0.0 : k * step);  // exact 0, never -0
  return ticks;
}

std::string format_tick(double value, double step) {
  if (std::abs(value) < std::abs(step) * 1e-9) value = 0;
  double mag = std::max(std::abs(value), std::abs(step));
  if (mag >= 1e6 || (value != 0 && std::abs(step) < 1e-4)) {
    // Scientific with just enough mantissa digits to tell neighbouring ticks apart.
    auto exponent = [](double v) { return int(std::floor(std::log10(std::abs(v)) + 1e-9)); };
    int digits = std::clamp(exponent(mag) - exponent(step), 0, 6);
    return fmt::format("{:.{}e}", value, digits);
  }
  int decimals = std::max(0, int(-std::floor(std::log10(std::abs(step)) + 1e-9)));
  return fmt::format("{:.{}f}", value, decimals);
}

namespace {

void draw_bands(torch::Tensor& img, const Layout& l, const Axis& ax, const PlotOptions& opt) {
  const Rgb shade{228, 236, 246};
  for (const auto& [lo, hi] : opt.x_bands) {
    if (ax.log && (lo <= 0 || hi <= 0)) continue;
    const double a = to_pixel(to_axis(lo, ax.log), ax, l.x0, l.x1), b = to_pixel(to_axis(hi, ax.log), ax, l.x0, l.x1);
    const int x0 = std::max(l.x0 + 1, int(std::lround(std::min(a, b))));
    const int x1 = std::min(l.x1 - 1, int(std::lround(std::max(a, b))));
    if (x1 >= x0) fill_rect(img, x0, l.y0 + 1, x1 - x0 + 1, l.y1 - l.y0 - 1, shade);
  }
}

}  // namespace

torch::Tensor plot_lines(const std::vector<Series>& series, const PlotOptions& opt) {
  if (opt.width < 160 || opt.height < 120)
    throw std::runtime_error(
        fmt::format("plot_lines: size {}x{} is too small (at least 160x120)", opt.width, opt.height));
  Axis ax = make_axis(series, true, opt, opt.width - 120);
  Axis ay = make_axis(series, false, opt, opt.height - 100);
  Layout l = compute_layout(opt, ax, ay);
  torch::Tensor img = blank_image(opt.height, opt.width, kWhite);
  draw_bands(img, l, ax, opt);
  draw_axes(img, l, ax, ay);
  for (size_t i = 0; i < series.size(); ++i) draw_series(img, l, ax, ay, series[i], series_style(i), i);
  draw_legend(img, l, series);
  draw_labels(img, l, opt);
  return img;
}

}  // namespace uplvsm::io
