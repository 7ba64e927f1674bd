// Users' own photo files as views of one scene: decoded (JPEG/PNG), turned upright by their EXIF orientation (a
// portrait phone photo is stored sideways), given a horizontal field of view (an explicit one, else the EXIF focal
// length's, else 60 degrees), then made views by data::preprocess_photo (resized and centre-cropped like the training
// data, a pinhole camera, identity pose). What `uplvsm render --images`, `study --images`, the viewer's uploads, the
// Python module and the C++ example feed the model.
#pragma once
#include <torch/torch.h>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "uplvsm/data/preprocess.h"
#include "uplvsm/data/scene.h"

namespace uplvsm::data {

// The horizontal field of view of photos without an explicit one or an EXIF focal length (degrees).
constexpr double kDefaultPhotoFovDeg = 60.0;

// What was done with one photo, for logs and output metadata.
struct PhotoInfo {
  std::string name;                      // the file or form field
  int width = 0, height = 0;             // upright, before preprocessing
  int orientation = 1;                   // the EXIF orientation applied (1: none)
  double fov_deg = kDefaultPhotoFovDeg;  // the horizontal field of view used
  std::string fov_source;                // "explicit", "exif" or "default"
  std::optional<double> exif_fov_deg;    // the EXIF focal length's, when the file has one (also under "explicit")
  std::string exif_tag;                  // the EXIF tag it came from (also when rejected)
  std::string exif_rejected;  // an implausible EXIF focal length, not used: names the tag, its value and the range
};

struct Photo {
  torch::Tensor hwc_u8;  // uint8 [H, W, 3], upright
  PhotoInfo info;
};

// JPEG/PNG bytes -> an upright photo and its field of view: `fov_deg` when given (it wins over EXIF), else the EXIF
// focal length's (FocalLengthIn35mmFilm, read by the diagonal convention, or FocalLength with the focal-plane
// resolution), else 60 degrees. An EXIF focal length whose 35 mm equivalent is outside io::kMinFocal35mm ..
// kMaxFocal35mm (8 .. 3000 mm) is not used: the photo goes on with the default, info.exif_rejected says why and a
// warning is logged. Decode errors name `what`; a given field of view outside (0, 180) is an std::invalid_argument.
Photo decode_photo(const uint8_t* data, size_t size, std::optional<double> fov_deg, const std::string& what);

// Reads and decodes each file (decode_photo) before anything heavier happens, so that a mistyped path is reported
// at once. Errors name the file: missing, unreadable, not a JPEG/PNG, or corrupt.
std::vector<Photo> read_photos(const std::vector<std::string>& paths, std::optional<double> fov_deg);

// Photos -> views: images [V, 3, H, W], fxfycxcy [V, 4] pixels, c2w [V, 4, 4] identity, frames 0..V-1. With a square
// crop every photo, portrait or landscape, fills image_size x image_size (a portrait photo is resized to image_size
// columns, not rows). Errors name the photo whose preprocessed size differs from the first's (no square crop).
SceneViews photo_views(const std::vector<Photo>& photos, const PreprocessOptions& opt);

// read_photos then photo_views. `fov_degrees` given: every photo gets it; nullopt: EXIF, else 60 degrees.
SceneViews load_photos(const std::vector<std::string>& paths, std::optional<double> fov_degrees,
                       const PreprocessOptions& opt);

// One line on the field of view: e.g. "52.3° from EXIF FocalLengthIn35mmFilm", "50° from --fov (overrides the
// EXIF 52.3°)", "60°, the default (no EXIF focal length; set --fov)", "60°, the default (EXIF FocalLengthIn35mmFilm
// = 1 mm rejected: ...; set --fov)". `option` names the explicit setting.
std::string describe_fov(const PhotoInfo& info, const std::string& option);

// The whole story of one photo: "<name>: WxH, turned upright (EXIF orientation 6); horizontal field of view ...".
std::string describe_photo(const PhotoInfo& info, const std::string& option);

// {name, width, height, exif_orientation, fov_deg, fov_source, exif_fov_deg (null when none), exif_tag,
// exif_rejected (null, or why the EXIF focal length was not used), note}: note is describe_photo's line.
nlohmann::json to_json(const PhotoInfo& info, const std::string& option);

}  // namespace uplvsm::data
