// Tiny drawing utilities on uint8 [H, W, 3] RGB images (CPU): an embedded 5x7 bitmap font for printable ASCII,
// lines, rectangles, pasting, and labelled image grids for reports and figures. No external font or image library.
#pragma once
#include <torch/torch.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace uplvsm::io {

using Rgb = std::array<uint8_t, 3>;

// Images passed by reference must be uint8 [H, W, 3] on the CPU with packed pixels (stride 3 between columns, 1
// between channels); row-strided views (img.narrow(0, ...).narrow(1, ...)) are fine and clip drawing to the view.
// Everything is clipped to the image; nothing throws for out-of-range coordinates.

// Glyph cell at scale 1: 5x7 pixels plus one descender row (g j p q y), advancing 6 pixels per character and 10
// pixels per line ('\n').
constexpr int kGlyphWidth = 5, kGlyphHeight = 8, kGlyphAdvance = 6, kLineHeight = 10;
int text_width(const std::string& text, int scale = 1);   // widest line, without the trailing spacing column
int text_height(const std::string& text, int scale = 1);  // all lines

// (x, y) is the top-left corner of the first character. Characters outside 32..126 draw as '?'.
void draw_text(torch::Tensor& img, int x, int y, const std::string& text, Rgb colour, int scale = 1);
// Bresenham line from (x0, y0) to (x1, y1) inclusive; thickness > 1 stamps a square of that size on each point.
void draw_line(torch::Tensor& img, int x0, int y0, int x1, int y1, Rgb colour, int thickness = 1);
void fill_rect(torch::Tensor& img, int x, int y, int w, int h, Rgb colour);
void draw_rect(torch::Tensor& img, int x, int y, int w, int h, Rgb colour, int thickness = 1);  // outline
// Copies `src` (uint8 [h, w, 3]) with its top-left corner at (x, y), clipped.
void paste(torch::Tensor& img, const torch::Tensor& src, int x, int y);

// uint8 [H, W, 3] filled with one colour.
torch::Tensor blank_image(int height, int width, Rgb colour = {255, 255, 255});
// HWC uint8 (1 or 3 channels) passes through; CHW floating point in [0, 1] (1 or 3 channels) is clamped, scaled and
// rounded. Returns a contiguous uint8 [H, W, 3]. Throws for anything else.
torch::Tensor to_hwc_u8(const torch::Tensor& image);

// A labelled grid on white: rows[r][c] is a cell (HWC uint8 or CHW float in [0, 1]; undefined = empty cell). Each
// column is as wide as its widest cell (or its label) and each row as tall as its tallest cell; cells are centred.
// col_labels go above the columns and row_labels left of the rows (either may be empty, else one per column/row).
torch::Tensor make_grid(const std::vector<std::vector<torch::Tensor>>& rows, const std::vector<std::string>& row_labels,
                        const std::vector<std::string>& col_labels, int pad = 4);

}  // namespace uplvsm::io
