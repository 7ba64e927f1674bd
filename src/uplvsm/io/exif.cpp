#include "uplvsm/io/exif.h"

#include <libexif/exif-data.h>
#include <libexif/exif-utils.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include <fmt/format.h>

namespace uplvsm::io {

namespace {

// An EXIF entry of the EXIF sub-IFD, else IFD0 (not IFD1: that is the thumbnail's).
ExifEntry* find_entry(ExifData* ed, ExifTag tag) {
  if (auto* e = exif_content_get_entry(ed->ifd[EXIF_IFD_EXIF], tag)) return e;
  return exif_content_get_entry(ed->ifd[EXIF_IFD_0], tag);
}

std::optional<double> exif_value(ExifData* ed, ExifTag tag) {
  ExifEntry* e = find_entry(ed, tag);
  if (!e || !e->data || e->components < 1) return std::nullopt;
  const ExifByteOrder order = exif_data_get_byte_order(ed);
  const unsigned fsize = exif_format_get_size(e->format);
  if (fsize == 0 || e->size < fsize) return std::nullopt;
  switch (e->format) {
    case EXIF_FORMAT_SHORT: return exif_get_short(e->data, order);
    case EXIF_FORMAT_LONG: return exif_get_long(e->data, order);
    case EXIF_FORMAT_RATIONAL: {
      const ExifRational r = exif_get_rational(e->data, order);
      if (r.denominator == 0) return std::nullopt;
      return static_cast<double>(r.numerator) / r.denominator;
    }
    case EXIF_FORMAT_SRATIONAL: {
      const ExifSRational r = exif_get_srational(e->data, order);
      if (r.denominator == 0) return std::nullopt;
      return static_cast<double>(r.numerator) / r.denominator;
    }
    default: return std::nullopt;
  }
}

// A tag's value when it is a finite positive number (zero means "unknown" in EXIF; negatives are garbage).
std::optional<double> positive_value(ExifData* ed, ExifTag tag) {
  const auto v = exif_value(ed, tag);
  if (v && std::isfinite(*v) && *v > 0) return v;
  return std::nullopt;
}

// The payload of the JPEG's APP1 "Exif\0\0" segment (header included, as libexif expects), found by walking the
// marker segments up to the first scan. libexif's own ExifLoader stops at APPn markers it does not list.
std::pair<const uint8_t*, size_t> find_exif_segment(const uint8_t* d, size_t n) {
  if (n < 4 || d[0] != 0xFF || d[1] != 0xD8) return {nullptr, 0};
  size_t i = 2;
  while (i + 4 <= n) {
    if (d[i] != 0xFF) return {nullptr, 0};
    const uint8_t marker = d[i + 1];
    if (marker == 0xFF) {  // fill byte
      ++i;
      continue;
    }
    if (marker == 0xDA || marker == 0xD9) return {nullptr, 0};  // start of scan / end of image: no EXIF before
    const size_t len = (static_cast<size_t>(d[i + 2]) << 8) | d[i + 3];
    if (len < 2 || i + 2 + len > n) return {nullptr, 0};
    if (marker == 0xE1 && len >= 8 && std::equal(d + i + 4, d + i + 10, "Exif\0\0")) return {d + i + 4, len - 2};
    i += 2 + len;
  }
  return {nullptr, 0};
}

}  // namespace

ExifTags read_exif(const uint8_t* data, size_t size) {
  ExifTags tags;
  const auto [seg, seg_size] = find_exif_segment(data, size);
  if (!seg) return tags;
  ExifData* ed = exif_data_new();
  if (!ed) return tags;
  // Read the tags as written: "following the specification" would make libexif add or drop entries on load.
  exif_data_unset_option(ed, EXIF_DATA_OPTION_FOLLOW_SPECIFICATION);
  exif_data_load_data(ed, seg, static_cast<unsigned int>(seg_size));
  const auto orientation = exif_value(ed, EXIF_TAG_ORIENTATION);
  if (orientation && *orientation >= 1 && *orientation <= 8) tags.orientation = static_cast<int>(*orientation);
  tags.focal_length_35mm = positive_value(ed, EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM);
  tags.focal_length_mm = positive_value(ed, EXIF_TAG_FOCAL_LENGTH);
  tags.focal_plane_x_resolution = positive_value(ed, EXIF_TAG_FOCAL_PLANE_X_RESOLUTION);
  tags.focal_plane_resolution_unit = exif_value(ed, EXIF_TAG_FOCAL_PLANE_RESOLUTION_UNIT);
  tags.pixel_x_dimension = positive_value(ed, EXIF_TAG_PIXEL_X_DIMENSION);
  exif_data_unref(ed);
  return tags;
}

std::optional<ExifFocal> exif_focal_pixels(const ExifTags& tags, int width, int height) {
  const double diagonal_px = std::hypot(static_cast<double>(width), static_cast<double>(height));
  ExifFocal focal;
  std::string values;  // the tags as written, for the rejection message
  if (tags.focal_length_35mm) {
    focal.pixels = *tags.focal_length_35mm * diagonal_px / kFullFrameDiagonalMm;
    focal.tag = "FocalLengthIn35mmFilm";
    values = fmt::format("FocalLengthIn35mmFilm = {:g} mm", *tags.focal_length_35mm);
  } else {
    const double unit = tags.focal_plane_resolution_unit.value_or(2);  // the spec's default: inch
    const char* unit_name = unit == 2 ? "inch" : unit == 3 ? "cm" : unit == 4 ? "mm" : nullptr;
    const double unit_mm = unit == 2 ? 25.4 : unit == 3 ? 10.0 : unit == 4 ? 1.0 : 0.0;
    if (!tags.focal_length_mm || !tags.focal_plane_x_resolution || !unit_name) return std::nullopt;
    // FocalPlaneXResolution counts pixels of the image the camera wrote (PixelXDimension wide): rescale to ours.
    const double scale = tags.pixel_x_dimension ? width / *tags.pixel_x_dimension : 1.0;
    focal.pixels = *tags.focal_length_mm * (*tags.focal_plane_x_resolution / unit_mm) * scale;
    focal.tag = "FocalLength+FocalPlaneXResolution";
    values = fmt::format("FocalLength = {:g} mm with FocalPlaneXResolution = {:g} per {}", *tags.focal_length_mm,
                         *tags.focal_plane_x_resolution, unit_name);
  }
  if (!std::isfinite(focal.pixels) || !(focal.pixels > 0) || !(diagonal_px > 0)) return std::nullopt;
  focal.equivalent_35mm = focal.pixels * kFullFrameDiagonalMm / diagonal_px;
  if (!(focal.equivalent_35mm >= kMinFocal35mm && focal.equivalent_35mm <= kMaxFocal35mm))
    focal.rejected =
        fmt::format("EXIF {} rejected: {}outside the plausible 35 mm-equivalent range [{:g}, {:g}] mm", values,
                    tags.focal_length_35mm ? std::string()
                                           : fmt::format("a 35 mm equivalent of {:.3g} mm, ", focal.equivalent_35mm),
                    kMinFocal35mm, kMaxFocal35mm);
  return focal;
}

torch::Tensor apply_exif_orientation(const torch::Tensor& hwc, int orientation) {
  const auto transposed = [&] { return hwc.permute({1, 0, 2}); };
  switch (orientation) {
    case 2: return hwc.flip({1}).contiguous();
    case 3: return hwc.flip({0, 1}).contiguous();
    case 4: return hwc.flip({0}).contiguous();
    case 5: return transposed().contiguous();
    case 6: return transposed().flip({1}).contiguous();
    case 7: return transposed().flip({0, 1}).contiguous();
    case 8: return transposed().flip({0}).contiguous();
    default: return hwc;
  }
}

}  // namespace uplvsm::io
