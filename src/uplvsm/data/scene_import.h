// "Bring your own scenes": a folder of photos (JPEG/PNG), optionally with a COLMAP text model or a nerfstudio
// transforms.json, turned into one RawScene (the pixelSplat chunk record) for evaluation, camera-control fine-tuning
// and rendering. The parsers are free functions so tests and other tools can use them alone; every error names the
// file, the line or field and what was expected. Parsers: scene_import_{colmap,transforms,exif}.cpp; the import:
// scene_import.cpp.
//
// Intrinsics come from, in this order of preference: the model (COLMAP cameras.txt / transforms.json), the JPEG's
// EXIF focal length (when plausible), or a default horizontal field of view (60 degrees, as `render --images`).
// Photos without a model are turned upright by their EXIF orientation (and their intrinsics with them); a model's
// cameras and poses describe the pixels as stored (COLMAP does not apply the orientation), so those stay as they are.
// Poses come only from a model; without one every camera gets the identity pose and poses_known is false (the
// unposed UP-LVSM never reads poses; tools that need ground-truth poses must refuse such scenes).
#pragma once
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "uplvsm/data/scene.h"

namespace uplvsm::data {

// The default horizontal field of view for photos without a model or EXIF focal length (degrees).
constexpr double kDefaultImportFovDeg = 60.0;

// A pinhole camera in pixels of an image of width x height (square pixels are not assumed).
struct PinholeIntrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;  // the image size these pixels refer to
};

// A world-to-camera pose in OpenCV axes (x right, y down, z forward): X_cam = R X_world + t.
struct Pose {
  double R[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  double t[3] = {0, 0, 0};
};

// ---- COLMAP text model ----

struct ColmapCamera {
  int64_t id = 0;
  std::string model;  // e.g. PINHOLE
  PinholeIntrinsics intrinsics;
  std::vector<double> distortion;  // model parameters after the pinhole ones (ignored; see warnings)
};

struct ColmapImage {
  int64_t id = 0;
  Pose w2c;  // COLMAP stores world-to-camera, quaternion (w,x,y,z), OpenCV axes: exactly pixelSplat's w2c
  int64_t camera_id = 0;
  std::string name;  // path relative to the image folder
};

// cameras.txt -> camera id -> camera. Distortion parameters are dropped: one warning per camera with non-zero
// distortion (or a fisheye model) is appended to *warnings.
std::map<int64_t, ColmapCamera> read_colmap_cameras(const std::string& path, std::vector<std::string>* warnings);

// images.txt -> images in file order. Each image is two lines (the second, its 2D points, may be empty).
std::vector<ColmapImage> read_colmap_images(const std::string& path);

// ---- nerfstudio / instant-NGP transforms.json ----

// The intrinsics fields of one frame (per-frame values override the top-level ones), as written.
struct TransformsIntrinsics {
  std::optional<double> fl_x, fl_y, cx, cy, camera_angle_x, camera_angle_y;
  int w = 0, h = 0;  // 0: not given (the image's own size)
};

struct TransformsFrame {
  std::string file_path;  // as written in the JSON
  std::string resolved;   // the image file (relative paths resolve against the JSON's folder); may not exist
  Pose w2c;               // converted from the OpenGL camera-to-world transform_matrix
  TransformsIntrinsics intrinsics;
};

// Parses transforms.json. Distortion coefficients or a fisheye camera_model add a warning.
std::vector<TransformsFrame> read_transforms(const std::string& path, std::vector<std::string>* warnings);

// A frame's pinhole camera for an image of width x height (used where the JSON has no w/h): fl_x, else
// instant-NGP's camera_angle_x (fl_x = 0.5 w / tan(angle / 2)); fl_y defaults to fl_x, cx/cy to the centre.
// nullopt when the JSON gives no focal length at all.
std::optional<PinholeIntrinsics> transforms_intrinsics(const TransformsIntrinsics& k, int width, int height);

// ---- EXIF ----

// The focal length in pixels of a JPEG (square pixels: fx = fy, principal point at the centre) of the given
// decoded size as stored (before any EXIF orientation), from its EXIF block: FocalLengthIn35mmFilm by the Exif /
// CIPA diagonal convention (fx = f35 * sqrt(W^2 + H^2) / 43.27 mm) or else FocalLength with FocalPlaneXResolution
// and FocalPlaneResolutionUnit (scaled when PixelXDimension says the resolution refers to another width). nullopt
// when the file has no usable EXIF focal length (PNG, no EXIF block, zero/invalid values), or when its 35 mm
// equivalent is outside [8, 3000] mm (io::kMinFocal35mm, kMaxFocal35mm): then *rejected, when given, says so,
// naming the tag and its value.
std::optional<PinholeIntrinsics> exif_intrinsics(const uint8_t* data, size_t size, int width, int height,
                                                 std::string* rejected = nullptr);

// The EXIF orientation (1..8; 1 for PNG or without EXIF) of image file bytes.
int exif_orientation(const uint8_t* data, size_t size);

// A camera of the image as stored -> the same camera of the image turned upright by EXIF `orientation`
// (io::apply_exif_orientation): the principal point follows the pixels; for 5..8 (a quarter turn, maybe mirrored)
// width and height and the focal lengths trade places.
PinholeIntrinsics upright_intrinsics(const PinholeIntrinsics& stored, int orientation);

// The pinhole camera of a `fov_deg` horizontal field of view, principal point at the centre, square pixels.
PinholeIntrinsics default_fov_intrinsics(int width, int height, double fov_deg);

// ---- the import ----

struct SceneImportOptions {
  std::string images_dir;                 // required
  std::string colmap_dir;                 // folder holding cameras.txt and images.txt (e.g. sparse/0); empty: none
  std::string transforms_path;            // nerfstudio transforms.json; empty: none (at most one of colmap/transforms)
  double fov_deg = kDefaultImportFovDeg;  // used when neither a model nor EXIF gives a focal length
  std::string scene_name;                 // scene key; empty: the folder name, sanitised
  // Skip (count and warn) folder images the model does not mention and model entries whose file is missing,
  // instead of refusing the import.
  bool skip_unmatched = false;
};

struct ImportedScene {
  RawScene scene;  // key, url "file://<folder>", timestamps 0..N-1, cameras [N,18], images = the files' bytes
  bool poses_known = false;
  std::string intrinsics_source;         // "colmap", "transforms", "exif", "default-fov", or e.g. "exif+default-fov"
  std::vector<std::string> image_names;  // in frame order (relative to the image folder / as the model names them)
  std::vector<std::string> warnings;
  int64_t skipped = 0;         // images or model entries left out (skip_unmatched)
  int64_t turned_upright = 0;  // photos turned by their EXIF orientation (stored re-encoded: see import_scene)
};

// The frames are the files' bytes, except photos turned upright by their EXIF orientation: loaders do not read EXIF,
// so those are stored as a JPEG (quality 95, no EXIF) of the upright pixels.
ImportedScene import_scene(const SceneImportOptions& options);

// A scene key from a folder or user-given name: [A-Za-z0-9._-], other characters become '_'; never empty.
std::string sanitize_scene_key(const std::string& name);

// The 18-float pixelSplat camera row: intrinsics normalised by the image's size, then the 3x4 w2c row-major.
std::vector<float> camera_row(const PinholeIntrinsics& k, const Pose& w2c);

}  // namespace uplvsm::data
