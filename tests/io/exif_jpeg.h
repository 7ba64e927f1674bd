// Photos as a phone writes them: pixels stored sideways in a JPEG plus an EXIF APP1 segment saying how to turn them
// upright. The segment is written by hand (a little-endian TIFF header; IFD0 holding Orientation and the pointer to
// the EXIF IFD, which holds FocalLengthIn35mmFilm) so that the tests do not read EXIF with the code they test.
#pragma once
#include <torch/torch.h>

#include <algorithm>
#include <cstdint>
#include <vector>

#include "uplvsm/io/image.h"

namespace uplvsm::test {

// The APP1 segment: FF E1, its big-endian length, "Exif\0\0", the TIFF block. focal_35mm 0: no focal-length tag.
inline std::vector<uint8_t> exif_app1(int orientation, int focal_35mm) {
  std::vector<uint8_t> tiff = {'I', 'I'};
  auto u16 = [&](uint32_t v) {
    tiff.push_back(uint8_t(v & 0xFF));
    tiff.push_back(uint8_t((v >> 8) & 0xFF));
  };
  auto u32 = [&](uint32_t v) {
    u16(v & 0xFFFF);
    u16(v >> 16);
  };
  auto short_entry = [&](uint32_t tag, uint32_t value) {  // tag, type SHORT, count 1, value left-justified
    u16(tag), u16(3), u32(1), u16(value), u16(0);
  };
  u16(42), u32(8);                                     // TIFF magic, IFD0 at offset 8
  const uint32_t exif_ifd = 8 + 2 + 2 * 12 + 4;        // right after IFD0's two entries and its next-IFD link
  u16(2), short_entry(0x0112, orientation);            // Orientation
  u16(0x8769), u16(4), u32(1), u32(exif_ifd), u32(0);  // ExifIFDPointer (LONG); no IFD1
  u16(focal_35mm > 0 ? 1 : 0);
  if (focal_35mm > 0) short_entry(0xA405, focal_35mm);  // FocalLengthIn35mmFilm
  u32(0);
  const size_t length = 2 + 6 + tiff.size();
  std::vector<uint8_t> seg = {0xFF, 0xE1, uint8_t(length >> 8), uint8_t(length & 0xFF), 'E', 'x', 'i', 'f', 0, 0};
  seg.insert(seg.end(), tiff.begin(), tiff.end());
  return seg;
}

// The JPEG of `stored` (uint8 [H, W, 3]) with the EXIF segment right after its start-of-image marker.
inline std::vector<uint8_t> jpeg_with_exif(const torch::Tensor& stored, int orientation, int focal_35mm) {
  auto jpeg = io::encode_jpeg(stored, 95);
  const auto app1 = exif_app1(orientation, focal_35mm);
  jpeg.insert(jpeg.begin() + 2, app1.begin(), app1.end());
  return jpeg;
}

// An upright portrait picture (width < height): the top half red, the bottom half blue.
inline torch::Tensor red_over_blue(int64_t height, int64_t width) {
  auto img = torch::zeros({height, width, 3}, torch::kUInt8);
  img.slice(0, 0, height / 2).select(2, 0).fill_(255);
  img.slice(0, height / 2).select(2, 2).fill_(255);
  return img;
}

// How a phone held upright stores `upright` with orientation 6 ("rotate 90° clockwise to view"): turned 90°
// counter-clockwise, so the top of the picture is the left edge of the stored pixels.
inline torch::Tensor stored_for_orientation_6(const torch::Tensor& upright) {
  return upright.permute({1, 0, 2}).flip({0}).contiguous();
}

// True when uint8 [H, W, 3] (or float [3, H, W] in [0, 1]) is red in its top fifth and blue in its bottom fifth.
inline bool is_red_over_blue(torch::Tensor img) {
  if (img.is_floating_point()) img = img.permute({1, 2, 0}).mul(255);
  img = img.to(torch::kFloat32);
  const int64_t h = img.size(0), band = std::max<int64_t>(1, h / 5);
  const std::vector<int64_t> rows_and_columns = {0, 1};
  const auto top = img.slice(0, 0, band).mean(rows_and_columns), bottom = img.slice(0, h - band).mean(rows_and_columns);
  return top[0].item<float>() > 200 && top[2].item<float>() < 55 && bottom[2].item<float>() > 200 &&
         bottom[0].item<float>() < 55;
}

}  // namespace uplvsm::test
