// Line plots: image size, drawn content inside the frame, ticks, and degenerate inputs.
#include <gtest/gtest.h>

#include <cmath>

#include "test_util.h"
#include "uplvsm/io/plot.h"

namespace uplvsm::io {
namespace {

const double kNaN = std::nan("");

// Pixels that are neither white, black nor grey (i.e. coloured series pixels).
int64_t coloured_pixels(const torch::Tensor& img) {
  auto f = img.to(torch::kInt32);
  auto spread = std::get<0>(f.max(2)) - std::get<0>(f.min(2));
  return (spread > 40).sum().item<int64_t>();
}

Series curve(const std::string& name, int n, double (*fn)(double)) {
  Series s{name, {}, {}};
  for (int i = 0; i < n; ++i) s.x.push_back(i), s.y.push_back(fn(i));
  return s;
}

TEST(Plot, NiceTicksAndLabels) {
  auto t = nice_ticks(0.13, 0.92, 5);
  EXPECT_DOUBLE_EQ(t.front(), 0.0);
  EXPECT_NEAR(t.back(), 1.0, 1e-12);
  EXPECT_NEAR(t[1] - t[0], 0.2, 1e-12);
  auto u = nice_ticks(-37, 1234, 6);
  EXPECT_DOUBLE_EQ(u[1] - u[0], 200);
  EXPECT_LE(u.front(), -37);
  EXPECT_GE(u.back(), 1234);
  EXPECT_EQ(format_tick(0.4, 0.2), "0.4");
  EXPECT_EQ(format_tick(1200, 200), "1200");
  EXPECT_EQ(format_tick(-1e-17, 0.1), "0.0");
  EXPECT_EQ(format_tick(2.5e-5, 5e-6), "2.5e-05");
  EXPECT_EQ(format_tick(3e7, 1e7), "3e+07");
  EXPECT_THROW(nice_ticks(1, 1, 5), std::runtime_error);
}

TEST(Plot, DrawsSeriesInsideThePlotArea) {
  PlotOptions opt;
  opt.title = "training loss";
  opt.xlabel = "step";
  opt.ylabel = "loss (MSE)";
  std::vector<Series> s = {curve("train", 200, [](double i) { return std::exp(-i / 50) + 0.1; }),
                           curve("val", 200, [](double i) { return std::exp(-i / 60) + 0.15; })};
  auto img = plot_lines(s, opt);
  ASSERT_EQ(img.sizes(), (std::vector<int64_t>{480, 800, 3}));
  EXPECT_EQ(img.scalar_type(), torch::kUInt8);
  // The middle of the image holds coloured series pixels; the outer border stays white.
  auto centre = img.narrow(0, 60, 360).narrow(1, 100, 650);
  EXPECT_GT(coloured_pixels(centre), 500);
  EXPECT_EQ(coloured_pixels(img.narrow(0, 0, 3)), 0);
  EXPECT_EQ(img[0][0][0].item<int>(), 255);
  // Both series colours (tab10 blue and orange) appear.
  auto has = [&](int r, int g, int b) {
    return ((img.select(2, 0) == r) & (img.select(2, 1) == g) & (img.select(2, 2) == b)).any().item<bool>();
  };
  EXPECT_TRUE(has(31, 119, 180));
  EXPECT_TRUE(has(255, 127, 14));
  // Axis labels and ticks are black text.
  EXPECT_GT(((img.sum(2) == 0)).sum().item<int64_t>(), 1000);
}

TEST(Plot, LogAxesAndNaNs) {
  PlotOptions opt;
  opt.log_x = true;
  opt.log_y = true;
  opt.width = 640;
  opt.height = 400;
  Series s{"psnr", {}, {}};
  for (int i = 1; i <= 1000; i *= 2) s.x.push_back(i), s.y.push_back(i == 16 ? kNaN : 1.0 / i);
  s.x.push_back(0), s.y.push_back(1);    // not plottable on a log axis: skipped
  s.x.push_back(-5), s.y.push_back(-1);  // idem
  auto img = plot_lines({s}, opt);
  EXPECT_EQ(img.sizes(), (std::vector<int64_t>{400, 640, 3}));
  EXPECT_GT(coloured_pixels(img), 300);
}

TEST(Plot, DegenerateInputsDoNotCrash) {
  PlotOptions opt;
  opt.width = 320;
  opt.height = 240;
  std::vector<std::vector<Series>> cases = {
      {},
      {Series{"empty", {}, {}}},
      {Series{"one point", {3.0}, {7.0}}},
      {Series{"constant", {0, 1, 2, 3}, {5, 5, 5, 5}}},
      {Series{"zero", {0, 0}, {0, 0}}},
      {Series{"all nan", {kNaN, kNaN}, {kNaN, 1.0}}},
      {Series{"mismatched", {1, 2, 3}, {1, 2}}},
      {Series{"huge", {0, 1}, {1e12, 3e12}}, Series{"", {0, 1}, {-1e12, 1e12}}},
      {Series{"tiny", {0, 1e-9}, {1e-12, 2e-12}}},
      {Series{"inf", {0, 1, 2}, {1, INFINITY, 2}}},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    torch::Tensor img;
    ASSERT_NO_THROW(img = plot_lines(cases[i], opt)) << "case " << i;
    EXPECT_EQ(img.sizes(), (std::vector<int64_t>{240, 320, 3})) << "case " << i;
  }
  auto single = plot_lines({Series{"one point", {3.0}, {7.0}}}, opt);
  EXPECT_GE(coloured_pixels(single), 16);  // the marker (plus the legend sample)
  opt.log_y = true;
  EXPECT_NO_THROW(plot_lines({Series{"const", {1, 2}, {10, 10}}}, opt));
  EXPECT_NO_THROW(plot_lines({}, opt));
  opt.width = 100;
  EXPECT_THROW(plot_lines({}, opt), std::runtime_error);
}

TEST(Plot, ManySeriesCycleColours) {
  std::vector<Series> s;
  for (int k = 0; k < 13; ++k) s.push_back(Series{"s" + std::to_string(k), {0, 1}, {double(k), double(k + 1)}});
  PlotOptions opt;
  auto img = plot_lines(s, opt);
  EXPECT_GT(coloured_pixels(img), 1000);
}

// Series 11 and 21 repeat series 1's colour; their lines are dashed and dotted so the three stay apart.
TEST(Plot, SeriesBeyondTheColoursAreDashedThenDotted) {
  auto blue_pixels_of_line_at = [](size_t index) {
    std::vector<Series> s(index + 1);  // the others empty: only the one line is drawn
    s[index] = Series{"", {0, 1}, {0.5, 0.5}};
    auto img = plot_lines(s, PlotOptions{});
    return ((img.select(2, 0) == 31) & (img.select(2, 1) == 119) & (img.select(2, 2) == 180)).sum().item<int64_t>();
  };
  const auto solid = blue_pixels_of_line_at(0), dashed = blue_pixels_of_line_at(10),
             dotted = blue_pixels_of_line_at(20);
  EXPECT_GT(solid, 1000);
  EXPECT_GT(dashed, solid / 2);
  EXPECT_LT(dashed, solid * 6 / 7);
  EXPECT_GT(dotted, solid / 5);
  EXPECT_LT(dotted, dashed);
  EXPECT_EQ(blue_pixels_of_line_at(30), solid);
}

}  // namespace
// A figure for a paper: a marker at every measured point, the seeds' spread as error bars (which the y axis makes room
// for), and x ticks only at the measured settings with their labels.
TEST(Plot, MarkersErrorBarsAndTicksAtTheData) {
  auto blue = [](const torch::Tensor& img) {
    return ((img.select(2, 0) == 31) & (img.select(2, 1) == 119) & (img.select(2, 2) == 180)).sum().item<int64_t>();
  };
  PlotOptions opt;
  opt.log_x = true;
  Series plain{"psnr", {125, 500, 2000, 8000}, {20, 21, 21.5, 21.7}};
  Series marked = plain;
  marked.markers = true;
  EXPECT_GT(blue(plot_lines({marked}, opt)), blue(plot_lines({plain}, opt)) + 4 * 30);  // four markers
  Series bars = plain;
  bars.y_err = {0.5, 0.5, 0.5, 0.5};
  EXPECT_GT(blue(plot_lines({bars}, opt)), blue(plot_lines({plain}, opt)) + 4 * 20);  // four bars with caps
  // Ticks only where the data is: the grid has one vertical line per tick, so only the four settings' columns (and
  // the frame) carry grid pixels in a row just above the bottom of the frame.
  opt.x_ticks = {125, 500, 2000, 8000};
  opt.x_tick_labels = {"125", "500", "2000", "8000"};
  auto img = plot_lines({plain}, opt);
  const auto grey = (img.select(2, 0) == 225) & (img.select(2, 1) == 225) & (img.select(2, 2) == 225);
  const int64_t row = opt.height - 60;  // inside the frame, below the data
  EXPECT_EQ(grey[row].sum().item<int64_t>(), 4) << "one grid column per tick";
  Series bad_error{"e", {1, 2}, {1, 2}};
  bad_error.y_err = {INFINITY, -1};  // ignored, never a crash
  EXPECT_NO_THROW(plot_lines({bad_error}, PlotOptions{}));
}

TEST(Plot, BandsShadeTheirSpanOfXOnly) {
  // x from 0 to 10 on a 400-pixel-wide plot: the band [2, 4] is shaded, x = 7 is not; a flat line at y = 0 keeps the
  // middle rows free of the series.
  Series line{"", {0, 10}, {0, 0}};
  PlotOptions o;
  o.width = 400;
  o.height = 200;
  o.x_bands = {{2.0, 4.0}, {-5.0, -1.0}};  // the second lies off the axis: clipped away
  auto img = plot_lines({line}, o).to(torch::kInt32);
  o.x_bands.clear();
  auto plain = plot_lines({line}, o).to(torch::kInt32);
  const auto shaded = (img - plain).abs().sum(2) > 0;  // pixels the bands changed
  ASSERT_GT(shaded.sum().item<int64_t>(), 0);
  auto cols = std::get<0>(shaded.max(0)).nonzero().squeeze(1);
  const int64_t first = cols.min().item<int64_t>(), last = cols.max().item<int64_t>();
  // The band spans a fifth of the axis's width (its data run 0..10) and sits left of its middle.
  EXPECT_GT(last - first, 40);
  EXPECT_LT(last - first, 110);
  EXPECT_LT((first + last) / 2, 180);
}

}  // namespace uplvsm::io
