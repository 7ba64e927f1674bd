// The EXIF focal length of a user's JPEG (libexif) and the default field of view when there is none (scene_import.h):
// the last two sources of intrinsics import_scene (scene_import.cpp) falls back on.
#include <libexif/exif-data.h>
#include <libexif/exif-utils.h>

#include <cmath>
#include <optional>

#include "uplvsm/data/scene_import.h"

namespace uplvsm::data {

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

std::optional<PinholeIntrinsics> exif_intrinsics(const uint8_t* data, size_t size, int width, int height) {
  const auto [seg, seg_size] = find_exif_segment(data, size);
  if (!seg) return std::nullopt;
  ExifData* ed = exif_data_new();
  if (!ed) return std::nullopt;
  // Read the tags as written: "following the specification" would make libexif add or drop entries on load.
  exif_data_unset_option(ed, EXIF_DATA_OPTION_FOLLOW_SPECIFICATION);
  exif_data_load_data(ed, seg, static_cast<unsigned int>(seg_size));
  std::optional<double> f_px;
  const auto f35 = exif_value(ed, EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM);
  if (f35 && *f35 > 0) {
    f_px = *f35 / 36.0 * std::max(width, height);
  } else {
    const auto f_mm = exif_value(ed, EXIF_TAG_FOCAL_LENGTH), res = exif_value(ed, EXIF_TAG_FOCAL_PLANE_X_RESOLUTION);
    const auto unit = exif_value(ed, EXIF_TAG_FOCAL_PLANE_RESOLUTION_UNIT).value_or(2);  // the spec's default: inch
    const double unit_mm = unit == 2 ? 25.4 : unit == 3 ? 10.0 : unit == 4 ? 1.0 : 0.0;
    if (f_mm && *f_mm > 0 && res && *res > 0 && unit_mm > 0) {
      // FocalPlaneXResolution counts pixels of the image the camera wrote (PixelXDimension wide): rescale to ours.
      const auto ref_width = exif_value(ed, EXIF_TAG_PIXEL_X_DIMENSION);
      const double scale = ref_width && *ref_width > 0 ? width / *ref_width : 1.0;
      f_px = *f_mm * (*res / unit_mm) * scale;
    }
  }
  exif_data_unref(ed);
  if (!f_px || !std::isfinite(*f_px) || !(*f_px > 0)) return std::nullopt;
  return PinholeIntrinsics{*f_px, *f_px, 0.5 * width, 0.5 * height, width, height};
}

PinholeIntrinsics default_fov_intrinsics(int width, int height, double fov_deg) {
  const double f = 0.5 * width / std::tan(fov_deg * M_PI / 360.0);
  return {f, f, 0.5 * width, 0.5 * height, width, height};
}

}  // namespace uplvsm::data
