// Bitmap text, lines, rectangles and labelled grids.
#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/io/raster.h"

namespace uplvsm::io {
namespace {

int64_t count_colour(const torch::Tensor& img, Rgb c) {
  auto match = (img.select(2, 0) == c[0]) & (img.select(2, 1) == c[1]) & (img.select(2, 2) == c[2]);
  return match.sum().item<int64_t>();
}

TEST(Raster, TextMetrics) {
  EXPECT_EQ(text_width("", 1), 0);
  EXPECT_EQ(text_width("A", 1), 5);
  EXPECT_EQ(text_width("AB", 1), 11);
  EXPECT_EQ(text_width("AB", 3), 33);
  EXPECT_EQ(text_width("ABC\nD", 1), 17);
  EXPECT_EQ(text_height("x", 1), 8);
  EXPECT_EQ(text_height("x\ny", 2), 2 * (10 + 8));
}

TEST(Raster, DrawsTextInsideItsBox) {
  auto img = blank_image(40, 120);
  const std::string text = "PSNR=31.5% (a-b)/c_[0],+:";
  draw_text(img, 2, 3, text, {255, 0, 0});
  int64_t red = count_colour(img, {255, 0, 0});
  EXPECT_GT(red, 60);
  // Every red pixel is inside the text's box.
  auto box = img.narrow(0, 3, text_height(text)).narrow(1, 2, std::min(text_width(text), 118));
  EXPECT_EQ(count_colour(box, {255, 0, 0}), red);
  // Scale 2 draws four times the pixels of the same (fully visible) text.
  auto a = blank_image(30, 200), b = blank_image(30, 200);
  draw_text(a, 0, 0, "Hello 42", {0, 0, 0}, 1);
  draw_text(b, 0, 0, "Hello 42", {0, 0, 0}, 2);
  EXPECT_EQ(count_colour(b, {0, 0, 0}), 4 * count_colour(a, {0, 0, 0}));
}

TEST(Raster, EveryPrintableCharacterExceptSpaceHasPixels) {
  for (int ch = 33; ch <= 126; ++ch) {
    auto img = blank_image(9, 7);
    draw_text(img, 1, 1, std::string(1, char(ch)), {0, 0, 0});
    EXPECT_GT(count_colour(img, {0, 0, 0}), 0) << "character '" << char(ch) << "'";
  }
  auto img = blank_image(9, 7);
  draw_text(img, 1, 1, " ", {0, 0, 0});
  EXPECT_EQ(count_colour(img, {0, 0, 0}), 0);
}

TEST(Raster, TextIsClippedAtTheBorders) {
  auto img = blank_image(10, 10);
  draw_text(img, -3, -4, "WWWWWW", {0, 0, 255}, 2);
  draw_text(img, 8, 8, "M", {0, 0, 255}, 3);
  draw_text(img, 1000, -1000, "far away", {0, 0, 255});
  EXPECT_GT(count_colour(img, {0, 0, 255}), 0);
}

TEST(Raster, LinesAndRectangles) {
  auto img = blank_image(50, 60);
  draw_line(img, 0, 0, 59, 0, {0, 255, 0});
  EXPECT_EQ(count_colour(img, {0, 255, 0}), 60);
  draw_line(img, 5, 5, 5, 44, {0, 0, 255}, 3);
  EXPECT_EQ(count_colour(img, {0, 0, 255}), 3 * (40 + 2));  // the 3x3 stamp reaches one pixel past each end
  draw_line(img, 10, 10, 40, 40, {255, 0, 0});
  EXPECT_EQ(count_colour(img, {255, 0, 0}), 31);
  EXPECT_EQ(img[40][40][0].item<int>(), 255);
  // Far-away endpoints are clipped, not iterated pixel by pixel.
  draw_line(img, -1000000000, 25, 1000000000, 25, {9, 9, 9});
  EXPECT_EQ(count_colour(img, {9, 9, 9}), 60);
  fill_rect(img, 50, 40, 20, 20, {1, 2, 3});
  EXPECT_EQ(count_colour(img, {1, 2, 3}), 10 * 10);
  draw_rect(img, 20, 2, 10, 6, {4, 5, 6});
  EXPECT_EQ(count_colour(img, {4, 5, 6}), 2 * 10 + 2 * 4);
}

TEST(Raster, DrawingIntoAViewStaysInsideIt) {
  auto img = blank_image(30, 30);
  auto view = img.narrow(0, 10, 10).narrow(1, 10, 10);
  draw_line(view, -5, -5, 50, 50, {0, 0, 0}, 2);
  EXPECT_GT(count_colour(img, {0, 0, 0}), 0);
  EXPECT_EQ(count_colour(view, {0, 0, 0}), count_colour(img, {0, 0, 0}));
  auto wrong = torch::zeros({4, 4, 3}, torch::kFloat32);
  EXPECT_THROW(fill_rect(wrong, 0, 0, 1, 1, {0, 0, 0}), std::runtime_error);
}

TEST(Raster, ConvertsImagesToHwcU8) {
  auto chw = torch::full({3, 4, 5}, 0.5);
  auto a = to_hwc_u8(chw);
  EXPECT_EQ(a.sizes(), (std::vector<int64_t>{4, 5, 3}));
  EXPECT_EQ(a[0][0][0].item<int>(), 128);
  auto gray = to_hwc_u8(torch::full({1, 2, 2}, 2.0));  // clamped
  EXPECT_EQ(gray[1][1][2].item<int>(), 255);
  EXPECT_THROW(to_hwc_u8(torch::zeros({4, 4, 3})), std::runtime_error);  // float HWC is ambiguous: rejected
  EXPECT_THROW(to_hwc_u8(torch::zeros({4, 4, 2}, torch::kUInt8)), std::runtime_error);
}

TEST(Raster, GridHasLabelsAndCells) {
  auto red = blank_image(20, 30, {255, 0, 0});
  auto blue_chw = torch::zeros({3, 16, 24});
  blue_chw[2].fill_(1.0);
  std::vector<std::vector<torch::Tensor>> rows = {{red, blue_chw, red}, {blue_chw, torch::Tensor(), red}};
  auto grid = make_grid(rows, {"input", "ours"}, {"a", "b", "ground truth"}, 4);
  ASSERT_EQ(grid.dim(), 3);
  EXPECT_EQ(grid.scalar_type(), torch::kUInt8);
  int label_w = text_width("input"), label_h = text_height("a");
  int col2 = std::max(30, text_width("ground truth"));
  EXPECT_EQ(grid.size(1), 4 + label_w + 4 + (30 + 4) + (24 + 4) + (col2 + 4));
  EXPECT_EQ(grid.size(0), 4 + label_h + 4 + (20 + 4) + (20 + 4));
  EXPECT_EQ(count_colour(grid, {255, 0, 0}), 3 * 20 * 30);
  EXPECT_EQ(count_colour(grid, {0, 0, 255}), 2 * 16 * 24);
  EXPECT_GT(count_colour(grid, {0, 0, 0}), 50);  // label text
  // The top-left corner (row-label column, header row) holds no image pixels.
  EXPECT_EQ(grid[0][0][0].item<int>(), 255);
  EXPECT_THROW(make_grid(rows, {"only one"}, {}), std::runtime_error);
  auto bare = make_grid(rows, {}, {}, 0);
  EXPECT_EQ(bare.size(0), 40);
  EXPECT_EQ(bare.size(1), 30 + 24 + 30);
}

}  // namespace
}  // namespace uplvsm::io
