// The EXIF block of a user's JPEG (libexif): the orientation tag (how the camera held the sensor: the decoded pixels
// must be turned upright before use) and the focal-length tags (the camera's field of view). One reader for
// `uplvsm dataset import` (data/scene_import_exif.cpp), `render --images` and the viewer's uploads (data/photo.h).
// Untrusted bytes: anything missing or malformed reads as absent, never as an error; an implausible focal length is
// flagged (ExifFocal::rejected) for the caller to report.
#pragma once
#include <torch/torch.h>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

namespace uplvsm::io {

struct ExifTags {
  int orientation = 1;                             // 1..8 (TIFF/EXIF Orientation); 1 (as stored) when absent or invalid
  std::optional<double> focal_length_35mm;         // FocalLengthIn35mmFilm (mm), > 0
  std::optional<double> focal_length_mm;           // FocalLength (mm), > 0
  std::optional<double> focal_plane_x_resolution;  // FocalPlaneXResolution (pixels per unit), > 0
  std::optional<double> focal_plane_resolution_unit;  // FocalPlaneResolutionUnit: 2 inch, 3 cm, 4 mm
  std::optional<double> pixel_x_dimension;            // PixelXDimension: the width the camera wrote
};

// The tags of the JPEG's APP1 "Exif" segment; defaults (orientation 1, no focal length) for PNG, a JPEG without
// EXIF, or a block libexif cannot read.
ExifTags read_exif(const uint8_t* data, size_t size);

// The 35 mm-equivalent focal length (FocalLengthIn35mmFilm) is defined by the diagonal, the Exif / CIPA convention:
// the image's diagonal subtends the angle that a 36 x 24 mm frame's 43.27 mm diagonal does at that focal length.
inline constexpr double kFullFrameDiagonalMm = 43.266615305567875;  // sqrt(36^2 + 24^2)
// A plausible 35 mm equivalent (mm). 8 mm is wider than any rectilinear lens (the widest full-frame ones are 9-10 mm,
// phones' ultra-wides 13-16 mm) and rejects the common fault of a phone writing its lens's real 4-7 mm focal length
// into the 35 mm tag; 3000 mm is the longest optical zoom of a consumer camera (Nikon P1000): beyond it a tag is
// garbage (65535).
inline constexpr double kMinFocal35mm = 8.0, kMaxFocal35mm = 3000.0;

// The focal length in pixels of the image as stored (width x height before any orientation is applied: the
// focal-plane resolution refers to the sensor's axes), and the tag it came from: FocalLengthIn35mmFilm
// (f35 * sqrt(W^2 + H^2) / 43.27 mm, the diagonal convention, whatever the aspect ratio), else FocalLength with
// FocalPlaneXResolution and FocalPlaneResolutionUnit (rescaled when PixelXDimension names another width).
struct ExifFocal {
  double pixels = 0;
  double equivalent_35mm = 0;  // the 35 mm-equivalent focal length (mm) it amounts to
  std::string tag;             // "FocalLengthIn35mmFilm" or "FocalLength+FocalPlaneXResolution"
  // Empty when plausible. Else why the tags must not be used (`pixels` is what they say): names the tags, their
  // values and the accepted range, e.g. "EXIF FocalLengthIn35mmFilm = 1 mm rejected: ...".
  std::string rejected;
  bool usable() const { return rejected.empty(); }
};
// nullopt when the tags give no focal length (absent, zero). An equivalent outside [kMinFocal35mm, kMaxFocal35mm]
// comes back with `rejected` set: callers fall back to another field of view and say so.
std::optional<ExifFocal> exif_focal_pixels(const ExifTags& tags, int width, int height);

// uint8 [H, W, C] as stored -> as it is meant to be seen, for each of the 8 EXIF orientations (PIL's
// ImageOps.exif_transpose): 2 mirror, 3 rotate 180, 4 flip, 5 transpose, 6 rotate 90 clockwise, 7 transverse,
// 8 rotate 90 counter-clockwise (5..8 swap width and height). 1 or an invalid value returns the input.
torch::Tensor apply_exif_orientation(const torch::Tensor& hwc, int orientation);

}  // namespace uplvsm::io
