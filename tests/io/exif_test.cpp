// io/exif.h: the EXIF tags of a user's JPEG (orientation, focal lengths) from a hand-written APP1 segment, the
// focal length in pixels, and the 8 orientations applied to pixels.
#include <gtest/gtest.h>

#include <array>

#include "io/exif_jpeg.h"
#include "uplvsm/io/exif.h"
#include "uplvsm/io/image.h"

using namespace uplvsm;

namespace {

// A stored image (4 rows x 6 columns) whose every pixel differs, so a corner tells where it came from.
torch::Tensor numbered_image() { return torch::arange(4 * 6 * 3).view({4, 6, 3}).to(torch::kUInt8).contiguous(); }

torch::Tensor corner(const torch::Tensor& img, bool bottom, bool right) {
  return img[bottom ? img.size(0) - 1 : 0][right ? img.size(1) - 1 : 0];
}

}  // namespace

// Each EXIF orientation says which stored corner is seen at the top left and which at the top right (the EXIF
// specification's "0th row / 0th column" table); two adjacent corners fix the turn or mirror entirely.
TEST(ExifOrientation, AllEightTurnTheStoredPixelsUpright) {
  struct Case {
    int orientation;
    std::array<bool, 2> top_left, top_right;  // {bottom, right} of the stored corner
    bool swaps;                               // width and height trade places
  };
  const Case cases[] = {{1, {false, false}, {false, true}, false}, {2, {false, true}, {false, false}, false},
                        {3, {true, true}, {true, false}, false},   {4, {true, false}, {true, true}, false},
                        {5, {false, false}, {true, false}, true},  {6, {true, false}, {false, false}, true},
                        {7, {true, true}, {false, true}, true},    {8, {false, true}, {true, true}, true}};
  const auto stored = numbered_image();
  for (const auto& c : cases) {
    SCOPED_TRACE("orientation " + std::to_string(c.orientation));
    const auto up = io::apply_exif_orientation(stored, c.orientation);
    EXPECT_EQ(up.sizes(), c.swaps ? torch::IntArrayRef({6, 4, 3}) : torch::IntArrayRef({4, 6, 3}));
    EXPECT_TRUE(up.is_contiguous());
    EXPECT_TRUE(torch::equal(corner(up, false, false), corner(stored, c.top_left[0], c.top_left[1])));
    EXPECT_TRUE(torch::equal(corner(up, false, true), corner(stored, c.top_right[0], c.top_right[1])));
  }
  for (int invalid : {0, 9, -1, 65535}) EXPECT_TRUE(torch::equal(io::apply_exif_orientation(stored, invalid), stored));
}

TEST(ExifTags, OrientationAndFocalLengthFromTheApp1Segment) {
  const auto img = torch::zeros({8, 16, 3}, torch::kUInt8);
  const auto jpeg = test::jpeg_with_exif(img, 6, 26);
  const auto tags = io::read_exif(jpeg.data(), jpeg.size());
  EXPECT_EQ(tags.orientation, 6);
  ASSERT_TRUE(tags.focal_length_35mm);
  EXPECT_EQ(*tags.focal_length_35mm, 26);
  // f35 / 36 mm times the long side, whichever way the photo is held.
  const auto focal = io::exif_focal_pixels(tags, 16, 8);
  ASSERT_TRUE(focal);
  EXPECT_NEAR(focal->pixels, 26.0 / 36.0 * 16, 1e-9);
  EXPECT_EQ(focal->tag, "FocalLengthIn35mmFilm");
  // The segment does not disturb the decode.
  EXPECT_EQ(io::decode_image(jpeg.data(), jpeg.size(), "exif.jpg").sizes(), torch::IntArrayRef({8, 16, 3}));
}

TEST(ExifTags, AbsentOrInvalidTagsReadAsAbsent) {
  const auto img = torch::zeros({8, 16, 3}, torch::kUInt8);
  for (const auto& bytes :
       {io::encode_jpeg(img), io::encode_png(img), test::jpeg_with_exif(img, 0, 0), test::jpeg_with_exif(img, 9, 0)}) {
    const auto tags = io::read_exif(bytes.data(), bytes.size());
    EXPECT_EQ(tags.orientation, 1);
    EXPECT_FALSE(io::exif_focal_pixels(tags, 16, 8));
  }
  // A segment cut short (its length runs past the file) is no EXIF at all, not a crash.
  auto cut = test::jpeg_with_exif(img, 6, 26);
  cut.resize(20);
  EXPECT_EQ(io::read_exif(cut.data(), cut.size()).orientation, 1);
}
