#include "uplvsm/data/photo.h"

#include <cmath>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/exif.h"
#include "uplvsm/io/image.h"

namespace uplvsm::data {

namespace {

void check_fov(double fov_deg, const std::string& what) {
  if (!(fov_deg > 0 && fov_deg < 180))
    throw std::invalid_argument(fmt::format("{}: field of view must be in (0, 180) degrees, got {:g}", what, fov_deg));
}

// The EXIF focal length as a horizontal field of view of the upright photo. The focal length is in pixels of the
// stored image; square pixels make it the same after a quarter turn, where the upright width is the stored height.
// An implausible one is recorded, not used (io::exif_focal_pixels names the tag, its value and the range).
void set_exif_fov(const io::ExifTags& tags, int stored_w, int stored_h, PhotoInfo& info) {
  const auto focal = io::exif_focal_pixels(tags, stored_w, stored_h);
  if (!focal) return;
  info.exif_tag = focal->tag;
  if (!focal->usable()) {
    info.exif_rejected = focal->rejected;
    return;
  }
  info.exif_fov_deg = 2.0 * std::atan(0.5 * info.width / focal->pixels) * 180.0 / M_PI;
}

// One photo as a view. The official preprocessing resizes to image_size rows, so with a square crop a portrait photo
// (narrower than tall) would become a square smaller than image_size, and smaller than a landscape photo's: a portrait
// photo is preprocessed transposed (a landscape photo of its vertical field of view) and transposed back, so that
// every photo fills image_size x image_size whichever way it was held.
SceneViews photo_view(const Photo& photo, const PreprocessOptions& opt) {
  const auto& img = photo.hwc_u8;
  const double width = static_cast<double>(img.size(1)), height = static_cast<double>(img.size(0));
  if (!opt.square_crop || width >= height) return preprocess_photo(img, photo.info.fov_deg, opt, photo.info.name);
  const double vertical_fov =
      2.0 * std::atan(std::tan(photo.info.fov_deg * M_PI / 360.0) * height / width) * 180 / M_PI;
  auto view = preprocess_photo(img.transpose(0, 1).contiguous(), vertical_fov, opt, photo.info.name);
  view.images = view.images.transpose(2, 3).contiguous();
  view.fxfycxcy = view.fxfycxcy.index_select(1, torch::tensor({1, 0, 3, 2}));  // x and y trade places
  return view;
}

}  // namespace

Photo decode_photo(const uint8_t* data, size_t size, std::optional<double> fov_deg, const std::string& what) {
  if (fov_deg) check_fov(*fov_deg, what);
  const auto stored = io::decode_image(data, size, what);
  const auto tags = io::read_exif(data, size);
  Photo photo;
  // Upright before anything else: the resize, the crop and the camera all refer to the photo as it is seen.
  photo.hwc_u8 = io::apply_exif_orientation(stored, tags.orientation);
  auto& info = photo.info;
  info.name = what;
  info.orientation = tags.orientation;
  info.height = static_cast<int>(photo.hwc_u8.size(0));
  info.width = static_cast<int>(photo.hwc_u8.size(1));
  set_exif_fov(tags, static_cast<int>(stored.size(1)), static_cast<int>(stored.size(0)), info);
  if (fov_deg) {
    info.fov_deg = *fov_deg;
    info.fov_source = "explicit";
  } else if (info.exif_fov_deg) {
    info.fov_deg = *info.exif_fov_deg;
    info.fov_source = "exif";
  } else {
    info.fov_deg = kDefaultPhotoFovDeg;
    info.fov_source = "default";
    // Not an error: the photo is usable with the default, but the run must not hide that its tag was refused.
    if (!info.exif_rejected.empty())
      spdlog::warn("{}: {}; the default {:g}° horizontal field of view is used instead", what, info.exif_rejected,
                   kDefaultPhotoFovDeg);
  }
  return photo;
}

std::vector<Photo> read_photos(const std::vector<std::string>& paths, std::optional<double> fov_deg) {
  if (paths.empty()) throw std::invalid_argument("load_photos: no photo given");
  // The field of view is the caller's argument, not a property of a file: refused before any photo is read.
  if (fov_deg) check_fov(*fov_deg, "load_photos");
  std::vector<Photo> photos;
  for (const auto& path : paths) {
    const auto bytes = io::read_file(path);  // errors name the path: missing, a directory, unreadable
    photos.push_back(decode_photo(bytes.data(), bytes.size(), fov_deg, path));
  }
  return photos;
}

SceneViews photo_views(const std::vector<Photo>& photos, const PreprocessOptions& opt) {
  if (photos.empty()) throw std::invalid_argument("load_photos: no photo given");
  std::vector<torch::Tensor> images, fxfycxcy, c2w;
  for (const auto& photo : photos) {
    auto view = photo_view(photo, opt);
    if (!images.empty() && view.images.sizes() != images[0].sizes())
      throw std::runtime_error(photo.info.name + ": preprocessed to " + c10::str(view.images.sizes()) + ", but " +
                               photos[0].info.name + " to " + c10::str(images[0].sizes()) +
                               " (photos of one scene need the same aspect)");
    images.push_back(view.images);
    fxfycxcy.push_back(view.fxfycxcy);
    c2w.push_back(view.c2w);
  }
  SceneViews out{torch::cat(images), torch::cat(fxfycxcy), torch::cat(c2w), {}};
  for (size_t i = 0; i < photos.size(); ++i) out.frames.push_back(static_cast<int64_t>(i));
  return out;
}

SceneViews load_photos(const std::vector<std::string>& paths, std::optional<double> fov_degrees,
                       const PreprocessOptions& opt) {
  return photo_views(read_photos(paths, fov_degrees), opt);
}

std::string describe_fov(const PhotoInfo& info, const std::string& option) {
  if (info.fov_source == "explicit")
    return fmt::format("{:.1f}° from {}", info.fov_deg, option) +
           (info.exif_fov_deg ? fmt::format(" (overrides the {:.1f}° of EXIF {})", *info.exif_fov_deg, info.exif_tag)
                              : std::string());
  if (info.fov_source == "exif") return fmt::format("{:.1f}° from EXIF {}", info.fov_deg, info.exif_tag);
  return fmt::format("{:.1f}°, the default ({}; set {})", info.fov_deg,
                     info.exif_rejected.empty() ? std::string("no EXIF focal length") : info.exif_rejected, option);
}

std::string describe_photo(const PhotoInfo& info, const std::string& option) {
  const std::string turned = info.orientation == 1
                                 ? std::string("as stored")
                                 : fmt::format("turned upright (EXIF orientation {})", info.orientation);
  return fmt::format("{}: {}x{}, {}; horizontal field of view {}", info.name, info.width, info.height, turned,
                     describe_fov(info, option));
}

nlohmann::json to_json(const PhotoInfo& info, const std::string& option) {
  return {{"name", info.name},
          {"width", info.width},
          {"height", info.height},
          {"exif_orientation", info.orientation},
          {"fov_deg", info.fov_deg},
          {"fov_source", info.fov_source},
          {"exif_fov_deg", info.exif_fov_deg ? nlohmann::json(*info.exif_fov_deg) : nlohmann::json()},
          {"exif_tag", info.exif_tag},
          {"exif_rejected", info.exif_rejected.empty() ? nlohmann::json() : nlohmann::json(info.exif_rejected)},
          {"note", describe_photo(info, option)}};
}

}  // namespace uplvsm::data
