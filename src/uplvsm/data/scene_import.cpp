// import_scene: a user's photo folder (+ optional COLMAP / transforms.json model) -> one RawScene. Decides which
// images belong to the scene, where each camera comes from (model, EXIF, default field of view) and validates
// everything before a chunk is written. The format parsers: scene_import_colmap, _transforms and _exif.cpp.
#include "uplvsm/data/scene_import.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <set>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/exif.h"
#include "uplvsm/io/image.h"

namespace uplvsm::data {

namespace fs = std::filesystem;

namespace {

bool is_image_file(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".jpg" || ext == ".jpeg" || ext == ".png";
}

// "a, b, c and 7 more": error messages list what is wrong without flooding the terminal.
std::string list_some(const std::vector<std::string>& items, size_t max_items = 8) {
  std::string out;
  for (size_t i = 0; i < items.size() && i < max_items; ++i) out += (i ? ", " : "") + items[i];
  if (items.size() > max_items) out += fmt::format(" and {} more", items.size() - max_items);
  return out;
}

// One image of the scene before decoding: where it is and what the model says about it.
struct Entry {
  std::string name;  // for ordering and messages
  fs::path path;
  std::optional<Pose> w2c;
  std::optional<PinholeIntrinsics> model_k;      // COLMAP camera
  std::optional<TransformsIntrinsics> model_tk;  // transforms.json fields (resolved once the size is known)
};

// The folder name, or its parent's when the folder is the conventional "images" (or "images_2" etc.) of a
// COLMAP / nerfstudio project, where the parent names the scene.
std::string folder_scene_name(const fs::path& p) {
  const std::string name = p.filename().string();
  if ((name == "images" || name.rfind("images_", 0) == 0) && !p.parent_path().filename().empty())
    return p.parent_path().filename().string();
  return name;
}

// The model's intrinsics refer to its own image size; photos may since have been downscaled (nerfstudio's
// images_2, COLMAP run on full-size photos). Same aspect ratio: rescale; another one: the model does not describe
// this file.
PinholeIntrinsics fit_to_image(const PinholeIntrinsics& k, int width, int height, const std::string& what,
                               std::vector<std::string>& warnings, bool& warned) {
  if (k.width == width && k.height == height) return k;
  const double sx = static_cast<double>(width) / k.width, sy = static_cast<double>(height) / k.height;
  if (std::abs(sx / sy - 1.0) > 0.01)
    throw std::runtime_error(
        fmt::format("{}: the model's camera is {}x{} but the image is {}x{} (another aspect "
                    "ratio: the camera does not describe this file)",
                    what, k.width, k.height, width, height));
  if (!warned)
    warnings.push_back(
        fmt::format("{}: the model's camera is {}x{} but the image is {}x{}: intrinsics rescaled "
                    "(later images of other sizes are rescaled too)",
                    what, k.width, k.height, width, height));
  warned = true;
  return {k.fx * sx, k.fy * sy, k.cx * sx, k.cy * sy, width, height};
}

void check_finite(const std::vector<float>& row, const std::string& what) {
  static const char* names[6] = {"fx/W", "fy/H", "cx/W", "cy/H", "unused", "unused"};
  for (int i = 0; i < 18; ++i)
    if (!std::isfinite(row[i]))
      throw std::runtime_error(
          fmt::format("import: {}: camera field {} is not finite ({})", what,
                      i < 6 ? std::string(names[i]) : fmt::format("w2c[{}][{}]", (i - 6) / 4, (i - 6) % 4), row[i]));
}

}  // namespace

std::string sanitize_scene_key(const std::string& name) {
  std::string key;
  for (unsigned char c : name) key += (std::isalnum(c) || c == '-' || c == '_' || c == '.') ? char(c) : '_';
  while (!key.empty() && key[0] == '.') key.erase(0, 1);  // no hidden files, no "." / ".." chunk names
  return key.empty() ? "scene" : key;
}

std::vector<float> camera_row(const PinholeIntrinsics& k, const Pose& w2c) {
  std::vector<float> row(18, 0.0f);
  row[0] = static_cast<float>(k.fx / k.width);
  row[1] = static_cast<float>(k.fy / k.height);
  row[2] = static_cast<float>(k.cx / k.width);
  row[3] = static_cast<float>(k.cy / k.height);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) row[6 + 4 * r + c] = static_cast<float>(w2c.R[r][c]);
    row[6 + 4 * r + 3] = static_cast<float>(w2c.t[r]);
  }
  return row;
}

namespace {

// Checks the options; returns the image folder, absolute, normalised and without a trailing slash.
fs::path checked_images_dir(const SceneImportOptions& opt) {
  if (opt.images_dir.empty()) throw std::runtime_error("import: no image folder given");
  fs::path dir = fs::absolute(opt.images_dir).lexically_normal();
  if (dir.filename().empty()) dir = dir.parent_path();  // "photos/" -> "photos"
  if (!fs::is_directory(dir))
    throw std::runtime_error(fmt::format("import: image folder {} is not a folder", dir.string()));
  if (!opt.colmap_dir.empty() && !opt.transforms_path.empty())
    throw std::runtime_error("import: give a COLMAP model or a transforms.json, not both");
  if (!(opt.fov_deg > 0 && opt.fov_deg < 180))
    throw std::runtime_error(fmt::format("import: field of view {} is not in (0, 180) degrees", opt.fov_deg));
  return dir;
}

// The folder's photos (top level only), sorted by name.
std::vector<fs::path> folder_images(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file() && is_image_file(e.path())) files.push_back(e.path().lexically_normal());
  std::sort(files.begin(), files.end());
  return files;
}

// The images a model describes (or the folder's own, without a model).
struct ModelImages {
  std::vector<Entry> entries;
  std::string model_file;  // names the model in messages; empty without a model
};

ModelImages colmap_images(const fs::path& dir, const fs::path& cdir, std::vector<std::string>& warnings) {
  const auto cameras_txt = (cdir / "cameras.txt").string(), images_txt = (cdir / "images.txt").string();
  for (const auto& f : {cameras_txt, images_txt})
    if (!fs::exists(f))
      throw std::runtime_error(fmt::format("import: {} not found{}", f,
                                           fs::exists(cdir / "cameras.bin")
                                               ? " (this is a binary model: convert it with `colmap model_converter "
                                                 "--input_path M --output_path M --output_type TXT`)"
                                               : " (expected a COLMAP text model: cameras.txt, images.txt)"));
  const auto cameras = read_colmap_cameras(cameras_txt, &warnings);
  ModelImages out{{}, images_txt};
  for (const auto& img : read_colmap_images(images_txt)) {
    const auto cam = cameras.find(img.camera_id);
    if (cam == cameras.end())
      throw std::runtime_error(fmt::format("import: {}: image '{}' uses camera {}, which {} does not define",
                                           images_txt, img.name, img.camera_id, cameras_txt));
    out.entries.push_back({img.name, (dir / img.name).lexically_normal(), img.w2c, cam->second.intrinsics, {}});
  }
  return out;
}

// Frames inside the image folder are named relative to it, others as the JSON writes them.
ModelImages transforms_images(const fs::path& dir, const std::string& transforms_path,
                              std::vector<std::string>& warnings) {
  ModelImages out{{}, transforms_path};
  for (const auto& f : read_transforms(transforms_path, &warnings)) {
    const fs::path p = fs::absolute(f.resolved).lexically_normal();
    const auto rel = p.lexically_relative(dir);
    const bool inside = !rel.empty() && rel.begin()->string() != "..";
    out.entries.push_back({inside ? rel.string() : f.file_path, p, f.w2c, std::nullopt, f.intrinsics});
  }
  return out;
}

ModelImages model_images(const SceneImportOptions& opt, const fs::path& dir, const std::vector<fs::path>& files,
                         std::vector<std::string>& warnings) {
  if (!opt.colmap_dir.empty()) return colmap_images(dir, fs::path(opt.colmap_dir), warnings);
  if (!opt.transforms_path.empty()) return transforms_images(dir, opt.transforms_path, warnings);
  ModelImages out;
  for (const auto& f : files) out.entries.push_back({f.filename().string(), f, std::nullopt, std::nullopt, {}});
  return out;
}

// Both directions of mismatch between the folder and the model: refuse, or skip and count when allowed. Keeps the
// entries whose file exists, sorted by name; returns how many were skipped.
int64_t match_model_to_folder(ModelImages& model, const std::vector<fs::path>& files, const fs::path& dir,
                              bool skip_unmatched, std::vector<std::string>& warnings) {
  const std::string& model_file = model.model_file;
  std::set<fs::path> mentioned;
  for (const auto& e : model.entries)
    if (!mentioned.insert(e.path).second)
      throw std::runtime_error(fmt::format("import: {}: image {} is listed twice", model_file, e.path.string()));
  std::vector<std::string> unmentioned, missing;
  for (const auto& f : files)
    if (!mentioned.count(f)) unmentioned.push_back(f.filename().string());
  std::vector<Entry> present;
  for (auto& e : model.entries) {
    if (fs::is_regular_file(e.path))
      present.push_back(std::move(e));
    else
      missing.push_back(e.name);
  }
  model.entries = std::move(present);
  if (!skip_unmatched && !missing.empty())
    throw std::runtime_error(
        fmt::format("import: {} image(s) of the model {} are not files under {}: {} (pass "
                    "--skip-unmatched to leave them out)",
                    missing.size(), model_file, dir.string(), list_some(missing)));
  if (!skip_unmatched && !unmentioned.empty())
    throw std::runtime_error(
        fmt::format("import: {} image(s) of {} are not in the model {}: {} (remove them, or "
                    "pass --skip-unmatched to leave them out)",
                    unmentioned.size(), dir.string(), model_file, list_some(unmentioned)));
  if (!unmentioned.empty())
    warnings.push_back(
        fmt::format("skipped {} image(s) the model does not mention: {}", unmentioned.size(), list_some(unmentioned)));
  if (!missing.empty())
    warnings.push_back(fmt::format("skipped {} model image(s) without a file: {}", missing.size(), list_some(missing)));
  std::sort(model.entries.begin(), model.entries.end(), [](const Entry& a, const Entry& b) { return a.name < b.name; });
  return static_cast<int64_t>(unmentioned.size() + missing.size());
}

// What the decode pass learns across the images, for the warnings written after it.
struct CameraTally {
  std::set<std::string> sources;  // where intrinsics came from: colmap, transforms, exif, default-fov
  int64_t no_model_focal = 0, other_size = 0;
  bool warned_rescale = false;
  int w0 = 0, h0 = 0;                     // the first image's size
  int64_t rejected_focal = 0;             // implausible EXIF focal lengths (the default field of view used)
  std::string first_rejected;             // "<file>: <why>" of the first
  int64_t oriented_with_model = 0;        // images with an EXIF orientation a model's camera keeps as stored
  std::string first_oriented_with_model;  // "<file> (orientation N)" of the first
};

// One image file as the scene stores it. A photo without a model is turned upright by its EXIF orientation, like
// `render --images` does; a model's cameras and poses were solved on the pixels as stored, so those stay.
struct SceneFrame {
  std::vector<uint8_t> file;   // the file's bytes (EXIF included)
  std::vector<uint8_t> bytes;  // what the chunk stores: the file, or a JPEG of the upright pixels
  int stored_w = 0, stored_h = 0;
  int orientation = 1;  // the EXIF orientation applied (1: none)
  int w = 0, h = 0;     // as stored in the chunk
};

SceneFrame read_scene_frame(const Entry& e, CameraTally& tally) {
  const std::string path = e.path.string();
  SceneFrame f;
  f.file = io::read_file(path);
  const auto hwc = io::decode_image(f.file.data(), f.file.size(), path);  // throws naming the file
  f.stored_h = f.h = static_cast<int>(hwc.size(0)), f.stored_w = f.w = static_cast<int>(hwc.size(1));
  const int orientation = exif_orientation(f.file.data(), f.file.size());
  if (orientation != 1 && e.w2c && tally.oriented_with_model++ == 0)
    tally.first_oriented_with_model = fmt::format("{} (orientation {})", path, orientation);
  if (orientation == 1 || e.w2c) {
    f.bytes = f.file;
    return f;
  }
  // Loaders (and pixelSplat's PIL) do not read EXIF: store the upright pixels, re-encoded without the tag.
  const auto upright = io::apply_exif_orientation(hwc, orientation);
  f.bytes = io::encode_jpeg(upright, 95);
  f.orientation = orientation;
  f.h = static_cast<int>(upright.size(0)), f.w = static_cast<int>(upright.size(1));
  return f;
}

// One image's camera (of the image as the chunk stores it) and where it came from: the model's (fitted to the
// file), else EXIF (plausible ones only; computed on the stored pixels, then turned upright), else the default
// field of view.
PinholeIntrinsics pick_intrinsics(const Entry& e, const SceneFrame& f, double fov_deg,
                                  std::vector<std::string>& warnings, CameraTally& tally) {
  const std::string path = e.path.string();
  std::optional<PinholeIntrinsics> k;
  std::string source;
  if (e.model_k) {
    k = fit_to_image(*e.model_k, f.w, f.h, path, warnings, tally.warned_rescale), source = "colmap";
  } else if (e.model_tk) {
    if (auto tk = transforms_intrinsics(*e.model_tk, f.w, f.h)) {
      k = fit_to_image(*tk, f.w, f.h, path, warnings, tally.warned_rescale), source = "transforms";
    } else {
      ++tally.no_model_focal;
    }
  }
  if (!k) {
    std::string rejected;
    if (auto exif = exif_intrinsics(f.file.data(), f.file.size(), f.stored_w, f.stored_h, &rejected)) {
      k = upright_intrinsics(*exif, f.orientation), source = "exif";
    } else if (!rejected.empty() && tally.rejected_focal++ == 0) {
      tally.first_rejected = path + ": " + rejected;
    }
  }
  if (!k) k = default_fov_intrinsics(f.w, f.h, fov_deg), source = "default-fov";
  tally.sources.insert(source);
  return *k;
}

// Reads and decodes image i once (validates it and gives its size), then stores its camera row and its bytes.
void add_scene_image(int64_t i, const Entry& e, double fov_deg, torch::Tensor& cameras, ImportedScene& out,
                     CameraTally& tally) {
  const std::string path = e.path.string();
  const SceneFrame f = read_scene_frame(e, tally);
  if (f.orientation != 1) ++out.turned_upright;
  if (i == 0) tally.w0 = f.w, tally.h0 = f.h;
  if (f.w != tally.w0 || f.h != tally.h0) ++tally.other_size;

  const auto k = pick_intrinsics(e, f, fov_deg, out.warnings, tally);
  const auto row = camera_row(k, e.w2c.value_or(Pose{}));
  check_finite(row, path);
  std::copy(row.begin(), row.end(), cameras[i].data_ptr<float>());
  auto t = torch::empty({static_cast<int64_t>(f.bytes.size())}, torch::kUInt8);
  std::copy(f.bytes.begin(), f.bytes.end(), t.data_ptr<uint8_t>());
  out.scene.images.push_back(t);
  out.image_names.push_back(e.name);
}

// "exif+default-fov": the sources in a fixed order, whatever order the images came in.
std::string joined_sources(const std::set<std::string>& sources) {
  std::string out;
  for (const char* s : {"colmap", "transforms", "exif", "default-fov"})
    if (sources.count(s)) out += (out.empty() ? "" : "+") + std::string(s);
  return out;
}

void warn_about_cameras(const CameraTally& tally, int64_t n, const std::string& model_file, double fov_deg,
                        std::vector<std::string>& warnings) {
  if (tally.no_model_focal > 0)
    warnings.push_back(
        fmt::format("{}: no focal length (fl_x / camera_angle_x) for {} frame(s): EXIF or the "
                    "default field of view used",
                    model_file, tally.no_model_focal));
  if (tally.other_size > 0)
    warnings.push_back(
        fmt::format("{} image(s) are not {}x{} like the first: loaders skip frames whose size differs "
                    "from frame 0's",
                    tally.other_size, tally.w0, tally.h0));
  if (n < 2) warnings.push_back("only one image: a scene needs at least two views (the model's context pair)");
  if (tally.rejected_focal > 0)
    warnings.push_back(fmt::format(
        "{} image(s) have an implausible EXIF focal length, e.g. {}: a {:g} degree horizontal field of view used "
        "for them (--fov)",
        tally.rejected_focal, tally.first_rejected, fov_deg));
  if (tally.oriented_with_model > 0)
    warnings.push_back(fmt::format(
        "{} image(s) have an EXIF orientation that was not applied, e.g. {}: {} describes the pixels as stored (as "
        "COLMAP reads them)",
        tally.oriented_with_model, tally.first_oriented_with_model, model_file));
  if (tally.sources.count("default-fov"))
    warnings.push_back(
        fmt::format("no focal length known for some images: a {:g} degree horizontal field of view "
                    "assumed (--fov)",
                    fov_deg));
}

// The scene key: the user's name or the folder's, sanitised (a warning when the user's name had to change).
std::string imported_scene_key(const SceneImportOptions& opt, const fs::path& dir, std::vector<std::string>& warnings) {
  const std::string wanted = opt.scene_name.empty() ? folder_scene_name(dir) : opt.scene_name;
  std::string key = sanitize_scene_key(wanted);
  if (!opt.scene_name.empty() && key != opt.scene_name)
    warnings.push_back(fmt::format("scene name '{}' stored as '{}'", opt.scene_name, key));
  return key;
}

}  // namespace

ImportedScene import_scene(const SceneImportOptions& opt) {
  ImportedScene out;
  auto& warnings = out.warnings;
  const fs::path dir = checked_images_dir(opt);
  const std::vector<fs::path> files = folder_images(dir);
  ModelImages model = model_images(opt, dir, files, warnings);
  if (!model.model_file.empty()) out.skipped = match_model_to_folder(model, files, dir, opt.skip_unmatched, warnings);
  if (model.entries.empty())
    throw std::runtime_error(
        model.model_file.empty()
            ? fmt::format("import: no JPEG/PNG images (*.jpg, *.jpeg, *.png) in {}", dir.string())
            : fmt::format("import: no image of the model {} is a file under {}", model.model_file, dir.string()));

  const int64_t n = static_cast<int64_t>(model.entries.size());
  out.poses_known = !model.model_file.empty();
  auto cameras = torch::empty({n, 18}, torch::kFloat32);
  CameraTally tally;
  for (int64_t i = 0; i < n; ++i) add_scene_image(i, model.entries[i], opt.fov_deg, cameras, out, tally);
  out.intrinsics_source = joined_sources(tally.sources);
  warn_about_cameras(tally, n, model.model_file, opt.fov_deg, warnings);

  out.scene.key = imported_scene_key(opt, dir, warnings);
  out.scene.url = "file://" + dir.string();
  out.scene.timestamps = torch::arange(n, torch::kInt64);
  out.scene.cameras = cameras;
  return out;
}

}  // namespace uplvsm::data
