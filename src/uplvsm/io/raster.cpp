// Bitmap text, lines, rectangles and labelled image grids (see raster.h).
#include "uplvsm/io/raster.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace uplvsm::io {
namespace {

// The classic 5x7 LCD font, ASCII 32..126: five column bytes per glyph, bit 0 = top row. g j p q y use an eighth
// row for their descenders.
const uint8_t kFont5x7[95][5] = {
    {0x00, 0x00, 0x00, 0x00, 0x00}, {0x00, 0x00, 0x5F, 0x00, 0x00}, {0x00, 0x07, 0x00, 0x07, 0x00},  //  !"
    {0x14, 0x7F, 0x14, 0x7F, 0x14}, {0x24, 0x2A, 0x7F, 0x2A, 0x12}, {0x23, 0x13, 0x08, 0x64, 0x62},  // #$%
    {0x36, 0x49, 0x55, 0x22, 0x50}, {0x00, 0x05, 0x03, 0x00, 0x00}, {0x00, 0x1C, 0x22, 0x41, 0x00},  // &'(
    {0x00, 0x41, 0x22, 0x1C, 0x00}, {0x08, 0x2A, 0x1C, 0x2A, 0x08}, {0x08, 0x08, 0x3E, 0x08, 0x08},  // )*+
    {0x00, 0x50, 0x30, 0x00, 0x00}, {0x08, 0x08, 0x08, 0x08, 0x08}, {0x00, 0x60, 0x60, 0x00, 0x00},  // ,-.
    {0x20, 0x10, 0x08, 0x04, 0x02}, {0x3E, 0x51, 0x49, 0x45, 0x3E}, {0x00, 0x42, 0x7F, 0x40, 0x00},  // /01
    {0x42, 0x61, 0x51, 0x49, 0x46}, {0x21, 0x41, 0x45, 0x4B, 0x31}, {0x18, 0x14, 0x12, 0x7F, 0x10},  // 234
    {0x27, 0x45, 0x45, 0x45, 0x39}, {0x3C, 0x4A, 0x49, 0x49, 0x30}, {0x01, 0x71, 0x09, 0x05, 0x03},  // 567
    {0x36, 0x49, 0x49, 0x49, 0x36}, {0x06, 0x49, 0x49, 0x29, 0x1E}, {0x00, 0x36, 0x36, 0x00, 0x00},  // 89:
    {0x00, 0x56, 0x36, 0x00, 0x00}, {0x08, 0x14, 0x22, 0x41, 0x00}, {0x14, 0x14, 0x14, 0x14, 0x14},  // ;<=
    {0x00, 0x41, 0x22, 0x14, 0x08}, {0x02, 0x01, 0x51, 0x09, 0x06}, {0x32, 0x49, 0x79, 0x41, 0x3E},  // >?@
    {0x7E, 0x11, 0x11, 0x11, 0x7E}, {0x7F, 0x49, 0x49, 0x49, 0x36}, {0x3E, 0x41, 0x41, 0x41, 0x22},  // ABC
    {0x7F, 0x41, 0x41, 0x22, 0x1C}, {0x7F, 0x49, 0x49, 0x49, 0x41}, {0x7F, 0x09, 0x09, 0x09, 0x01},  // DEF
    {0x3E, 0x41, 0x49, 0x49, 0x7A}, {0x7F, 0x08, 0x08, 0x08, 0x7F}, {0x00, 0x41, 0x7F, 0x41, 0x00},  // GHI
    {0x20, 0x40, 0x41, 0x3F, 0x01}, {0x7F, 0x08, 0x14, 0x22, 0x41}, {0x7F, 0x40, 0x40, 0x40, 0x40},  // JKL
    {0x7F, 0x02, 0x0C, 0x02, 0x7F}, {0x7F, 0x04, 0x08, 0x10, 0x7F}, {0x3E, 0x41, 0x41, 0x41, 0x3E},  // MNO
    {0x7F, 0x09, 0x09, 0x09, 0x06}, {0x3E, 0x41, 0x51, 0x21, 0x5E}, {0x7F, 0x09, 0x19, 0x29, 0x46},  // PQR
    {0x46, 0x49, 0x49, 0x49, 0x31}, {0x01, 0x01, 0x7F, 0x01, 0x01}, {0x3F, 0x40, 0x40, 0x40, 0x3F},  // STU
    {0x1F, 0x20, 0x40, 0x20, 0x1F}, {0x3F, 0x40, 0x38, 0x40, 0x3F}, {0x63, 0x14, 0x08, 0x14, 0x63},  // VWX
    {0x07, 0x08, 0x70, 0x08, 0x07}, {0x61, 0x51, 0x49, 0x45, 0x43}, {0x00, 0x7F, 0x41, 0x41, 0x00},  // YZ[
    {0x02, 0x04, 0x08, 0x10, 0x20}, {0x00, 0x41, 0x41, 0x7F, 0x00}, {0x04, 0x02, 0x01, 0x02, 0x04},  // \]^
    {0x40, 0x40, 0x40, 0x40, 0x40}, {0x00, 0x01, 0x02, 0x04, 0x00}, {0x20, 0x54, 0x54, 0x54, 0x78},  // _`a
    {0x7F, 0x48, 0x44, 0x44, 0x38}, {0x38, 0x44, 0x44, 0x44, 0x20}, {0x38, 0x44, 0x44, 0x48, 0x7F},  // bcd
    {0x38, 0x54, 0x54, 0x54, 0x18}, {0x08, 0x7E, 0x09, 0x01, 0x02}, {0x98, 0xA4, 0xA4, 0xA4, 0x7C},  // efg
    {0x7F, 0x08, 0x04, 0x04, 0x78}, {0x00, 0x44, 0x7D, 0x40, 0x00}, {0x40, 0x80, 0x88, 0x7A, 0x00},  // hij
    {0x7F, 0x10, 0x28, 0x44, 0x00}, {0x00, 0x41, 0x7F, 0x40, 0x00}, {0x7C, 0x04, 0x18, 0x04, 0x78},  // klm
    {0x7C, 0x08, 0x04, 0x04, 0x78}, {0x38, 0x44, 0x44, 0x44, 0x38}, {0xFC, 0x24, 0x24, 0x24, 0x18},  // nop
    {0x18, 0x24, 0x24, 0x24, 0xFC}, {0x7C, 0x08, 0x04, 0x04, 0x08}, {0x48, 0x54, 0x54, 0x54, 0x20},  // qrs
    {0x04, 0x3F, 0x44, 0x40, 0x20}, {0x3C, 0x40, 0x40, 0x20, 0x7C}, {0x1C, 0x20, 0x40, 0x20, 0x1C},  // tuv
    {0x3C, 0x40, 0x30, 0x40, 0x3C}, {0x44, 0x28, 0x10, 0x28, 0x44}, {0x9C, 0xA0, 0xA0, 0xA0, 0x7C},  // wxy
    {0x44, 0x64, 0x54, 0x4C, 0x44}, {0x00, 0x08, 0x36, 0x41, 0x00}, {0x00, 0x00, 0x7F, 0x00, 0x00},  // z{|
    {0x00, 0x41, 0x36, 0x08, 0x00}, {0x08, 0x04, 0x08, 0x10, 0x08},                                  // }~
};

// Raw pixel access to an image or a row-strided view of one.
struct Canvas {
  uint8_t* data;
  int64_t row_stride;
  int h, w;
  void set(int x, int y, const Rgb& c) {
    if (x < 0 || y < 0 || x >= w || y >= h) return;
    uint8_t* p = data + y * row_stride + 3 * x;
    p[0] = c[0], p[1] = c[1], p[2] = c[2];
  }
};

Canvas canvas(torch::Tensor& img) {
  if (!img.defined() || img.dim() != 3 || img.size(2) != 3 || img.scalar_type() != torch::kUInt8 || !img.is_cpu())
    throw std::runtime_error("raster: image must be a uint8 [H, W, 3] CPU tensor");
  if (img.stride(2) != 1 || img.stride(1) != 3)
    throw std::runtime_error("raster: image pixels must be packed RGB (column stride 3, channel stride 1)");
  return {img.data_ptr<uint8_t>(), img.stride(0), int(img.size(0)), int(img.size(1))};
}

void fill_clipped(Canvas& c, int x0, int y0, int x1, int y1, const Rgb& colour) {  // [x0, x1) x [y0, y1)
  x0 = std::max(x0, 0), y0 = std::max(y0, 0), x1 = std::min(x1, c.w), y1 = std::min(y1, c.h);
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) c.set(x, y, colour);
}

// Liang-Barsky clip of a segment to [lo, hi]^2 boxes; false when nothing is left. Keeps Bresenham loops short even
// for far-away endpoints.
bool clip_segment(double& x0, double& y0, double& x1, double& y1, double xmin, double ymin, double xmax, double ymax) {
  double t0 = 0, t1 = 1, dx = x1 - x0, dy = y1 - y0;
  const double p[4] = {-dx, dx, -dy, dy}, q[4] = {x0 - xmin, xmax - x0, y0 - ymin, ymax - y0};
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0) {
      if (q[i] < 0) return false;
      continue;
    }
    double t = q[i] / p[i];
    if (p[i] < 0)
      t0 = std::max(t0, t);
    else
      t1 = std::min(t1, t);
    if (t0 > t1) return false;
  }
  double ox = x0, oy = y0;
  x0 = ox + t0 * dx, y0 = oy + t0 * dy, x1 = ox + t1 * dx, y1 = oy + t1 * dy;
  return true;
}

int cell_extent(const std::vector<std::vector<torch::Tensor>>& cells, size_t r, size_t c, int dim) {
  if (c >= cells[r].size() || !cells[r][c].defined()) return 0;
  return int(cells[r][c].size(dim));
}

}  // namespace

int text_width(const std::string& text, int scale) {
  int best = 0, cur = 0;
  for (char ch : text) {
    if (ch == '\n')
      best = std::max(best, cur), cur = 0;
    else
      ++cur;
  }
  best = std::max(best, cur);
  return best == 0 ? 0 : scale * (best * kGlyphAdvance - (kGlyphAdvance - kGlyphWidth));
}

int text_height(const std::string& text, int scale) {
  int lines = 1 + int(std::count(text.begin(), text.end(), '\n'));
  return scale * ((lines - 1) * kLineHeight + kGlyphHeight);
}

void draw_text(torch::Tensor& img, int x, int y, const std::string& text, Rgb colour, int scale) {
  Canvas c = canvas(img);
  scale = std::max(scale, 1);
  int cx = x, cy = y;
  for (char ch : text) {
    if (ch == '\n') {
      cx = x, cy += kLineHeight * scale;
      continue;
    }
    int code = (ch >= 32 && ch <= 126) ? ch - 32 : '?' - 32;
    for (int col = 0; col < kGlyphWidth; ++col)
      for (int row = 0; row < 8; ++row)
        if (kFont5x7[code][col] & (1 << row))
          fill_clipped(c, cx + col * scale, cy + row * scale, cx + (col + 1) * scale, cy + (row + 1) * scale, colour);
    cx += kGlyphAdvance * scale;
  }
}

void draw_line(torch::Tensor& img, int x0, int y0, int x1, int y1, Rgb colour, int thickness) {
  Canvas c = canvas(img);
  thickness = std::max(thickness, 1);
  double fx0 = x0, fy0 = y0, fx1 = x1, fy1 = y1, m = thickness + 1;
  if (!clip_segment(fx0, fy0, fx1, fy1, -m, -m, c.w + m, c.h + m)) return;
  int ax = int(std::lround(fx0)), ay = int(std::lround(fy0)), bx = int(std::lround(fx1)), by = int(std::lround(fy1));
  int dx = std::abs(bx - ax), dy = -std::abs(by - ay), sx = ax < bx ? 1 : -1, sy = ay < by ? 1 : -1;
  int err = dx + dy, lo = -(thickness - 1) / 2;
  while (true) {
    if (thickness == 1)
      c.set(ax, ay, colour);
    else
      fill_clipped(c, ax + lo, ay + lo, ax + lo + thickness, ay + lo + thickness, colour);
    if (ax == bx && ay == by) break;
    int e2 = 2 * err;
    if (e2 >= dy) err += dy, ax += sx;
    if (e2 <= dx) err += dx, ay += sy;
  }
}

void fill_rect(torch::Tensor& img, int x, int y, int w, int h, Rgb colour) {
  Canvas c = canvas(img);
  fill_clipped(c, x, y, x + w, y + h, colour);
}

void draw_rect(torch::Tensor& img, int x, int y, int w, int h, Rgb colour, int thickness) {
  Canvas c = canvas(img);
  int t = std::max(thickness, 1);
  fill_clipped(c, x, y, x + w, y + t, colour);
  fill_clipped(c, x, y + h - t, x + w, y + h, colour);
  fill_clipped(c, x, y, x + t, y + h, colour);
  fill_clipped(c, x + w - t, y, x + w, y + h, colour);
}

void paste(torch::Tensor& img, const torch::Tensor& src, int x, int y) {
  canvas(img);
  torch::Tensor s = to_hwc_u8(src);
  int x0 = std::max(x, 0), y0 = std::max(y, 0);
  int x1 = std::min<int>(x + int(s.size(1)), int(img.size(1)));
  int y1 = std::min<int>(y + int(s.size(0)), int(img.size(0)));
  if (x1 <= x0 || y1 <= y0) return;
  img.narrow(0, y0, y1 - y0).narrow(1, x0, x1 - x0).copy_(s.narrow(0, y0 - y, y1 - y0).narrow(1, x0 - x, x1 - x0));
}

torch::Tensor blank_image(int height, int width, Rgb colour) {
  auto img = torch::empty({std::max(height, 0), std::max(width, 0), 3}, torch::kUInt8);
  for (int ch = 0; ch < 3; ++ch) img.select(2, ch).fill_(int(colour[size_t(ch)]));
  return img;
}

torch::Tensor to_hwc_u8(const torch::Tensor& image) {
  if (!image.defined() || image.dim() != 3) throw std::runtime_error("raster: image must be [H, W, C] or [C, H, W]");
  torch::Tensor t = image.detach().to(torch::kCPU);
  if (t.scalar_type() == torch::kUInt8) {
    if (t.size(2) == 1) t = t.expand({t.size(0), t.size(1), 3});
    if (t.size(2) != 3) throw std::runtime_error("raster: uint8 images must be HWC with 1 or 3 channels");
    return t.contiguous();
  }
  if (!t.is_floating_point() || (t.size(0) != 1 && t.size(0) != 3))
    throw std::runtime_error("raster: float images must be CHW in [0, 1] with 1 or 3 channels");
  t = t.to(torch::kFloat32).clamp(0, 1).mul(255).round().to(torch::kUInt8).permute({1, 2, 0});
  if (t.size(2) == 1) t = t.expand({t.size(0), t.size(1), 3});
  return t.contiguous();
}

torch::Tensor make_grid(const std::vector<std::vector<torch::Tensor>>& rows, const std::vector<std::string>& row_labels,
                        const std::vector<std::string>& col_labels, int pad) {
  size_t n_rows = rows.size(), n_cols = 0;
  for (const auto& r : rows) n_cols = std::max(n_cols, r.size());
  n_cols = std::max(n_cols, col_labels.size());
  if (!row_labels.empty() && row_labels.size() != n_rows)
    throw std::runtime_error("make_grid: " + std::to_string(row_labels.size()) + " row labels for " +
                             std::to_string(n_rows) + " rows");
  std::vector<std::vector<torch::Tensor>> cells(n_rows);
  for (size_t r = 0; r < n_rows; ++r)
    for (const auto& cell : rows[r]) cells[r].push_back(cell.defined() ? to_hwc_u8(cell) : torch::Tensor());
  pad = std::max(pad, 0);
  // Labels scale with the images so they stay readable on large renders.
  int widest = 0;
  for (size_t r = 0; r < n_rows; ++r)
    for (size_t c = 0; c < n_cols; ++c) widest = std::max(widest, cell_extent(cells, r, c, 1));
  int scale = widest >= 256 ? 2 : 1;
  std::vector<int> col_w(n_cols, 0), row_h(n_rows, 0);
  for (size_t c = 0; c < n_cols; ++c) {
    if (c < col_labels.size()) col_w[c] = text_width(col_labels[c], scale);
    for (size_t r = 0; r < n_rows; ++r) col_w[c] = std::max(col_w[c], cell_extent(cells, r, c, 1));
  }
  for (size_t r = 0; r < n_rows; ++r)
    for (size_t c = 0; c < n_cols; ++c) row_h[r] = std::max(row_h[r], cell_extent(cells, r, c, 0));
  int label_w = 0, label_h = 0;
  for (const auto& s : row_labels) label_w = std::max(label_w, text_width(s, scale));
  for (const auto& s : col_labels) label_h = std::max(label_h, text_height(s, scale));
  int left = pad + (label_w ? label_w + pad : 0), top = pad + (label_h ? label_h + pad : 0);
  int width = left, height = top;
  for (int w : col_w) width += w + pad;
  for (int h : row_h) height += h + pad;
  torch::Tensor img = blank_image(height, width);
  const Rgb black{0, 0, 0};
  int x = left;
  for (size_t c = 0; c < n_cols; ++c) {
    if (c < col_labels.size())
      draw_text(img, x + (col_w[c] - text_width(col_labels[c], scale)) / 2, pad, col_labels[c], black, scale);
    x += col_w[c] + pad;
  }
  int y = top;
  for (size_t r = 0; r < n_rows; ++r) {
    if (!row_labels.empty())
      draw_text(img, pad, y + (row_h[r] - text_height(row_labels[r], scale)) / 2, row_labels[r], black, scale);
    x = left;
    for (size_t c = 0; c < n_cols; ++c) {
      if (c < cells[r].size() && cells[r][c].defined()) {
        const auto& cell = cells[r][c];
        paste(img, cell, x + (col_w[c] - int(cell.size(1))) / 2, y + (row_h[r] - int(cell.size(0))) / 2);
      }
      x += col_w[c] + pad;
    }
    y += row_h[r] + pad;
  }
  return img;
}

}  // namespace uplvsm::io
