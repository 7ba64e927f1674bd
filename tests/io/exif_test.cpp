// io/exif.h: the EXIF tags of a user's JPEG (orientation, focal lengths) from a hand-written APP1 segment, the
// focal length in pixels (the 35 mm equivalent by the diagonal, implausible ones rejected), and the 8 orientations
// applied to pixels.
#include <gtest/gtest.h>

#include <array>
#include <cmath>

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
  // f35 times the image's diagonal over the full frame's: 26 * sqrt(16^2 + 8^2) / sqrt(36^2 + 24^2) = 10.7497 px.
  const auto focal = io::exif_focal_pixels(tags, 16, 8);
  ASSERT_TRUE(focal);
  EXPECT_NEAR(focal->pixels, 10.7497, 1e-4);
  EXPECT_EQ(focal->tag, "FocalLengthIn35mmFilm");
  EXPECT_TRUE(focal->usable());
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

// The Exif / CIPA definition of FocalLengthIn35mmFilm is by the diagonal: the image's diagonal subtends the angle
// the 36 x 24 mm frame's 43.2666 mm diagonal does. On a 3:2 image that is the long side over 36 mm; on a phone's 4:3
// image the long-side reading gives a focal length 4 % short (a view about 2 degrees too wide at 67).
TEST(ExifFocal, ThirtyFiveMillimetreEquivalentIsReadByTheDiagonal) {
  io::ExifTags tags;
  tags.focal_length_35mm = 26;
  // 3:2, 3000 x 2000: diagonal 3605.55 px; 26 * 3605.55 / 43.2666 = 2166.67 px = 26 / 36 * 3000.
  auto focal = io::exif_focal_pixels(tags, 3000, 2000);
  ASSERT_TRUE(focal);
  EXPECT_NEAR(focal->pixels, 2166.667, 1e-3);
  EXPECT_NEAR(focal->equivalent_35mm, 26.0, 1e-9);
  // 4:3, 4000 x 3000: diagonal 5000 px; 26 * 5000 / 43.2666 = 3004.62 px (the long-side reading: 2888.89 px), a
  // horizontal field of view of 2 atan(2000 / 3004.62) = 67.30 degrees (not 69.39).
  focal = io::exif_focal_pixels(tags, 4000, 3000);
  ASSERT_TRUE(focal);
  EXPECT_NEAR(focal->pixels, 3004.62, 1e-2);
  EXPECT_NEAR(2 * std::atan(2000 / focal->pixels) * 180 / M_PI, 67.30, 1e-2);
  // Held upright (3000 x 4000) the diagonal, and so the focal length, is the same.
  EXPECT_NEAR(io::exif_focal_pixels(tags, 3000, 4000)->pixels, focal->pixels, 1e-9);
  // The same tag read from a JPEG: a 40 x 30 image (diagonal 50 px) at 26 mm is 26 * 50 / 43.2666 = 30.0462 px.
  const auto jpeg = test::jpeg_with_exif(torch::zeros({30, 40, 3}, torch::kUInt8), 1, 26);
  focal = io::exif_focal_pixels(io::read_exif(jpeg.data(), jpeg.size()), 40, 30);
  ASSERT_TRUE(focal);
  EXPECT_NEAR(focal->pixels, 30.0462, 1e-4);
}

// A 35 mm equivalent outside [8, 3000] mm is not a camera's (a 1 mm tag would be a 174-degree view of a 3:2 image): it
// comes back flagged, with a message naming the tag, its value and the accepted range, from either pair of tags.
TEST(ExifFocal, ImplausibleFocalLengthIsRejectedNamingTheTagAndValue) {
  const auto jpeg = test::jpeg_with_exif(torch::zeros({30, 40, 3}, torch::kUInt8), 1, 1);
  auto focal = io::exif_focal_pixels(io::read_exif(jpeg.data(), jpeg.size()), 40, 30);
  ASSERT_TRUE(focal);
  EXPECT_FALSE(focal->usable());
  EXPECT_NE(focal->rejected.find("FocalLengthIn35mmFilm = 1 mm"), std::string::npos) << focal->rejected;
  EXPECT_NE(focal->rejected.find("[8, 3000] mm"), std::string::npos) << focal->rejected;
  io::ExifTags tags;
  for (const double f35 : {7.0, 3001.0, 65535.0}) {
    tags.focal_length_35mm = f35;
    EXPECT_FALSE(io::exif_focal_pixels(tags, 40, 30)->usable()) << f35;
  }
  for (const double f35 : {8.0, 13.0, 3000.0}) {
    tags.focal_length_35mm = f35;
    EXPECT_TRUE(io::exif_focal_pixels(tags, 40, 30)->usable()) << f35;
  }
  // FocalLength 4.5 mm at 10 px/cm on a 4000 x 3000 image: 4.5 px, a 35 mm equivalent of 4.5 * 43.27 / 5000 mm.
  tags = io::ExifTags{};
  tags.focal_length_mm = 4.5, tags.focal_plane_x_resolution = 10, tags.focal_plane_resolution_unit = 3;
  focal = io::exif_focal_pixels(tags, 4000, 3000);
  ASSERT_TRUE(focal);
  EXPECT_FALSE(focal->usable());
  EXPECT_NE(focal->rejected.find("FocalLength = 4.5 mm with FocalPlaneXResolution = 10 per cm"), std::string::npos)
      << focal->rejected;
  EXPECT_NE(focal->rejected.find("a 35 mm equivalent of 0.0389 mm"), std::string::npos) << focal->rejected;
  // ... while 10000 px/cm (a 1 um pixel pitch) is a phone camera: 4500 px, 4500 * 43.27 / 5000 = 38.9 mm.
  tags.focal_plane_x_resolution = 10000;
  focal = io::exif_focal_pixels(tags, 4000, 3000);
  ASSERT_TRUE(focal && focal->usable());
  EXPECT_NEAR(focal->equivalent_35mm, 4500 * io::kFullFrameDiagonalMm / 5000, 1e-9);
}
