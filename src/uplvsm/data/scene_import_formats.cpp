// The community camera formats a user's photo folder may come with (scene_import.h): COLMAP's text model
// (cameras.txt, images.txt), nerfstudio / instant-NGP transforms.json, and the EXIF focal length of a JPEG
// (libexif). Pure parsing: import_scene (scene_import.cpp) decides which source wins and builds the scene.
#include <libexif/exif-data.h>
#include <libexif/exif-utils.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "uplvsm/core/json_input.h"
#include "uplvsm/data/scene_import.h"

namespace uplvsm::data {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n"), e = s.find_last_not_of(" \t\r\n");
  return b == std::string::npos ? "" : s.substr(b, e - b + 1);
}

// Whitespace-separated tokens with their start offsets (COLMAP image names are "the rest of the line").
std::vector<std::pair<std::string, size_t>> tokens(const std::string& line) {
  std::vector<std::pair<std::string, size_t>> out;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i >= line.size()) break;
    const size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    out.emplace_back(line.substr(start, i - start), start);
  }
  return out;
}

// strtod over the whole token; NaN/Inf are refused here so every camera value that reaches a scene is finite.
double parse_number(const std::string& token, const std::string& where, const std::string& field) {
  char* end = nullptr;
  const double v = std::strtod(token.c_str(), &end);
  if (token.empty() || end != token.c_str() + token.size())
    throw std::runtime_error(fmt::format("{}: field {}: expected a number, got '{}'", where, field, token));
  if (!std::isfinite(v))
    throw std::runtime_error(fmt::format("{}: field {}: expected a finite number, got '{}'", where, field, token));
  return v;
}

int64_t parse_integer(const std::string& token, const std::string& where, const std::string& field) {
  char* end = nullptr;
  const long long v = std::strtoll(token.c_str(), &end, 10);
  if (token.empty() || end != token.c_str() + token.size())
    throw std::runtime_error(fmt::format("{}: field {}: expected an integer, got '{}'", where, field, token));
  return v;
}

std::vector<std::string> read_lines(const std::string& path, const char* what) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open {}", what, path));
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// COLMAP's camera models (colmap/src/colmap/sensor/models.h): parameter count, whether the focal length is one
// value (f) or two (fx fy), the parameter names for messages, and whether the projection is not a pinhole at all.
struct ColmapModel {
  const char* name;
  int num_params;
  bool single_focal;
  const char* params;
  bool fisheye;
};
constexpr std::array<ColmapModel, 11> kColmapModels = {{
    {"SIMPLE_PINHOLE", 3, true, "f cx cy", false},
    {"PINHOLE", 4, false, "fx fy cx cy", false},
    {"SIMPLE_RADIAL", 4, true, "f cx cy k", false},
    {"RADIAL", 5, true, "f cx cy k1 k2", false},
    {"OPENCV", 8, false, "fx fy cx cy k1 k2 p1 p2", false},
    {"OPENCV_FISHEYE", 8, false, "fx fy cx cy k1 k2 k3 k4", true},
    {"FULL_OPENCV", 12, false, "fx fy cx cy k1 k2 p1 p2 k3 k4 k5 k6", false},
    {"FOV", 5, false, "fx fy cx cy omega", false},
    {"SIMPLE_RADIAL_FISHEYE", 4, true, "f cx cy k", true},
    {"RADIAL_FISHEYE", 5, true, "f cx cy k1 k2", true},
    {"THIN_PRISM_FISHEYE", 12, false, "fx fy cx cy k1 k2 p1 p2 k3 k4 sx1 sy1", true},
}};

// R of a unit quaternion (w, x, y, z), as COLMAP's / Eigen's conversion.
void quaternion_to_rotation(double w, double x, double y, double z, double R[3][3]) {
  R[0][0] = 1 - 2 * (y * y + z * z), R[0][1] = 2 * (x * y - w * z), R[0][2] = 2 * (x * z + w * y);
  R[1][0] = 2 * (x * y + w * z), R[1][1] = 1 - 2 * (x * x + z * z), R[1][2] = 2 * (y * z - w * x);
  R[2][0] = 2 * (x * z - w * y), R[2][1] = 2 * (y * z + w * x), R[2][2] = 1 - 2 * (x * x + y * y);
}

// Python's json.dump writes NaN / Infinity / -Infinity, which are not JSON: turn them (outside strings) into
// strings so the file still parses and the field check below can name the bad field instead of a parse offset.
std::string quote_non_finite_literals(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      out += c;
      if (c == '\\' && i + 1 < text.size()) out += text[++i];
      else if (c == '"') in_string = false;
      continue;
    }
    if (c == '"') in_string = true;
    bool replaced = false;
    for (const char* lit : {"-Infinity", "Infinity", "NaN"}) {
      const size_t n = std::char_traits<char>::length(lit);
      if (text.compare(i, n, lit) == 0) {
        out += std::string("\"") + lit + "\"";
        i += n - 1;
        replaced = true;
        break;
      }
    }
    if (!replaced) out += c;
  }
  return out;
}

double json_number(const json& v, const std::string& where) {
  if (v.is_string())  // a NaN / Infinity literal quoted above, or a number written as a string
    throw std::runtime_error(fmt::format("{}: expected a finite number, got {}", where, v.get<std::string>()));
  if (!v.is_number()) throw std::runtime_error(fmt::format("{}: expected a number, got {}", where, json_excerpt(v)));
  const double x = v.get<double>();
  if (!std::isfinite(x)) throw std::runtime_error(fmt::format("{}: expected a finite number, got {}", where, x));
  return x;
}

bool invert3(const double A[3][3], double out[3][3]) {
  const double det = A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1]) -
                     A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0]) +
                     A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0]);
  if (!(std::abs(det) > 1e-12)) return false;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      // cofactor of (c, r), divided by det: the adjugate formula
      const int r0 = (c + 1) % 3, r1 = (c + 2) % 3, c0 = (r + 1) % 3, c1 = (r + 2) % 3;
      out[r][c] = (A[r0][c0] * A[r1][c1] - A[r0][c1] * A[r1][c0]) / det;
    }
  return true;
}

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

std::map<int64_t, ColmapCamera> read_colmap_cameras(const std::string& path, std::vector<std::string>* warnings) {
  std::map<int64_t, ColmapCamera> cameras;
  const auto lines = read_lines(path, "COLMAP cameras");
  for (size_t n = 0; n < lines.size(); ++n) {
    const std::string line = trim(lines[n]);
    if (line.empty() || line[0] == '#') continue;
    const std::string where = fmt::format("{}:{}", path, n + 1);
    const auto tok = tokens(line);
    if (tok.size() < 4)
      throw std::runtime_error(fmt::format("{}: expected 'CAMERA_ID MODEL WIDTH HEIGHT PARAMS...', got '{}'", where,
                                           line));
    ColmapCamera cam;
    cam.id = parse_integer(tok[0].first, where, "CAMERA_ID");
    cam.model = tok[1].first;
    const auto* model = std::find_if(kColmapModels.begin(), kColmapModels.end(),
                                     [&](const ColmapModel& m) { return cam.model == m.name; });
    if (model == kColmapModels.end()) {
      std::string known;
      for (const auto& m : kColmapModels) known += std::string(known.empty() ? "" : ", ") + m.name;
      throw std::runtime_error(fmt::format("{}: unknown camera model '{}' (expected one of {})", where, cam.model,
                                           known));
    }
    const int64_t w = parse_integer(tok[2].first, where, "WIDTH"), h = parse_integer(tok[3].first, where, "HEIGHT");
    if (w <= 0 || h <= 0)
      throw std::runtime_error(fmt::format("{}: fields WIDTH HEIGHT: expected positive sizes, got {} {}", where, w, h));
    if (static_cast<int>(tok.size()) - 4 != model->num_params)
      throw std::runtime_error(fmt::format("{}: model {} expects {} parameters ({}), got {}", where, model->name,
                                           model->num_params, model->params, tok.size() - 4));
    const auto names = tokens(model->params);
    std::vector<double> p;
    for (int i = 0; i < model->num_params; ++i)
      p.push_back(parse_number(tok[4 + i].first, where, names[i].first));
    const int nf = model->single_focal ? 1 : 2;
    cam.intrinsics = {p[0], p[nf - 1], p[nf], p[nf + 1], static_cast<int>(w), static_cast<int>(h)};
    if (!(cam.intrinsics.fx > 0) || !(cam.intrinsics.fy > 0))
      throw std::runtime_error(fmt::format("{}: field {}: expected a positive focal length", where, names[0].first));
    cam.distortion.assign(p.begin() + nf + 2, p.end());
    if (cameras.count(cam.id)) throw std::runtime_error(fmt::format("{}: camera id {} defined twice", where, cam.id));
    const bool distorted = std::any_of(cam.distortion.begin(), cam.distortion.end(), [](double v) { return v != 0; });
    if (warnings && (distorted || model->fisheye))
      warnings->push_back(fmt::format(
          "{}: camera {} is {}{}: the distortion is ignored and the photos are used as pinhole images (undistort "
          "them first, e.g. with colmap image_undistorter, for exact cameras)",
          path, cam.id, model->name, model->fisheye ? " (a fisheye model)" : " with non-zero distortion"));
    cameras.emplace(cam.id, std::move(cam));
  }
  return cameras;
}

std::vector<ColmapImage> read_colmap_images(const std::string& path) {
  std::vector<ColmapImage> images;
  std::set<std::string> names;
  const auto lines = read_lines(path, "COLMAP images");
  // Each image is two lines: the pose line, then its 2D points, which is empty for an image without
  // observations. So only blank lines *between* pairs (and comments) are skipped, never the points line.
  for (size_t n = 0; n < lines.size();) {
    const std::string line = trim(lines[n]);
    if (line.empty() || line[0] == '#') {
      ++n;
      continue;
    }
    const std::string where = fmt::format("{}:{}", path, n + 1);
    const auto tok = tokens(line);
    if (tok.size() < 10)
      throw std::runtime_error(fmt::format(
          "{}: expected 'IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME', got '{}' ({} fields)", where, line,
          tok.size()));
    ColmapImage img;
    img.id = parse_integer(tok[0].first, where, "IMAGE_ID");
    double q[4], t[3];
    const char* qn[4] = {"QW", "QX", "QY", "QZ"};
    const char* tn[3] = {"TX", "TY", "TZ"};
    for (int i = 0; i < 4; ++i) q[i] = parse_number(tok[1 + i].first, where, qn[i]);
    for (int i = 0; i < 3; ++i) t[i] = parse_number(tok[5 + i].first, where, tn[i]);
    img.camera_id = parse_integer(tok[8].first, where, "CAMERA_ID");
    img.name = trim(line.substr(tok[9].second));  // names may contain spaces
    const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(norm > 1e-9))
      throw std::runtime_error(fmt::format("{}: fields QW QX QY QZ: expected a non-zero quaternion", where));
    quaternion_to_rotation(q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm, img.w2c.R);
    std::copy(t, t + 3, img.w2c.t);
    if (!names.insert(img.name).second)
      throw std::runtime_error(fmt::format("{}: image '{}' listed twice", where, img.name));
    images.push_back(std::move(img));
    n += 2;  // the pose line and its (possibly empty) points line
  }
  return images;
}

namespace {

// The file as JSON (non-finite literals quoted so they are refused by field, not by the parser), with its frames.
json read_transforms_json(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(fmt::format("transforms: cannot open {}", path));
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  json j;
  try {
    j = json::parse(quote_non_finite_literals(text));
  } catch (const std::exception& e) {
    throw std::runtime_error(fmt::format("{}: not valid JSON: {}", path, e.what()));
  }
  if (!j.is_object() || !j.contains("frames") || !j["frames"].is_array() || j["frames"].empty())
    throw std::runtime_error(fmt::format("{}: expected an object with a non-empty 'frames' list", path));
  return j;
}

// Intrinsics may sit at the top level and/or in each frame; the frame's value wins.
const json* frame_field(const json& root, const json& frame, const char* name) {
  if (frame.contains(name) && !frame[name].is_null()) return &frame[name];
  if (root.contains(name) && !root[name].is_null()) return &root[name];
  return nullptr;
}

// The frame's image file: relative paths resolve against the JSON's folder.
std::string resolve_frame_path(const fs::path& folder, const std::string& file_path) {
  fs::path p(file_path);
  if (p.is_relative()) p = folder / p;
  p = p.lexically_normal();
  if (!fs::exists(p) && !p.has_extension())  // Blender synthetic scenes name "./train/r_0" without ".png"
    for (const char* ext : {".png", ".jpg", ".jpeg", ".PNG", ".JPG", ".JPEG"})
      if (fs::exists(fs::path(p.string() + ext))) {
        p = p.string() + ext;
        break;
      }
  return p.string();
}

// The frame's transform_matrix: 4x4 finite numbers whose last row is 0 0 0 1.
void read_c2w(const json& f, const std::string& mwhere, double c2w[4][4]) {
  const json* m = f.contains("transform_matrix") ? &f["transform_matrix"] : nullptr;
  if (!m || !m->is_array() || m->size() != 4)
    throw std::runtime_error(fmt::format("{}: expected a 4x4 list of numbers (camera-to-world)", mwhere));
  for (int r = 0; r < 4; ++r) {
    if (!(*m)[r].is_array() || (*m)[r].size() != 4)
      throw std::runtime_error(fmt::format("{}[{}]: expected a row of 4 numbers", mwhere, r));
    for (int c = 0; c < 4; ++c) c2w[r][c] = json_number((*m)[r][c], fmt::format("{}[{}][{}]", mwhere, r, c));
  }
  if (std::abs(c2w[3][0]) > 1e-4 || std::abs(c2w[3][1]) > 1e-4 || std::abs(c2w[3][2]) > 1e-4 ||
      std::abs(c2w[3][3] - 1) > 1e-4)
    throw std::runtime_error(fmt::format("{}[3]: expected the last row 0 0 0 1, got {} {} {} {}", mwhere, c2w[3][0],
                                         c2w[3][1], c2w[3][2], c2w[3][3]));
}

// An OpenGL camera-to-world matrix -> the OpenCV world-to-camera pose; refuses a non-rigid rotation.
Pose opengl_c2w_to_w2c(const double c2w[4][4], const std::string& mwhere) {
  // OpenGL/Blender camera axes (x right, y up, z back) -> OpenCV (x right, y down, z forward): negate the y and
  // z columns of the rotation. The camera centre (last column) is unchanged.
  double R[3][3], Rinv[3][3];
  for (int r = 0; r < 3; ++r) {
    R[r][0] = c2w[r][0], R[r][1] = -c2w[r][1], R[r][2] = -c2w[r][2];
  }
  double err = 0;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) {
      double dot = 0;
      for (int k = 0; k < 3; ++k) dot += R[k][a] * R[k][b];
      err = std::max(err, std::abs(dot - (a == b ? 1.0 : 0.0)));
    }
  if (err > 1e-2 || !invert3(R, Rinv))
    throw std::runtime_error(fmt::format("{}: the rotation part is not orthonormal (|R^T R - I| = {:.3g}); expected "
                                         "a rigid camera-to-world transform",
                                         mwhere, err));
  // w2c = inverse of c2w: R^-1 (exact inverse, so the chunk's c2w reproduces the file's) and -R^-1 t.
  Pose w2c;
  for (int r = 0; r < 3; ++r) {
    w2c.t[r] = 0;
    for (int c = 0; c < 3; ++c) {
      w2c.R[r][c] = Rinv[r][c];
      w2c.t[r] -= Rinv[r][c] * c2w[c][3];
    }
  }
  return w2c;
}

// A numeric intrinsics field of the frame (or the top level); nullopt when absent.
std::optional<double> frame_number(const json& root, const json& f, const char* name, const std::string& where) {
  const json* v = frame_field(root, f, name);
  if (!v) return std::nullopt;
  return json_number(*v, fmt::format("{}: field '{}'", where, name));
}

TransformsIntrinsics read_frame_intrinsics(const json& root, const json& f, const std::string& where) {
  auto num = [&](const char* name) { return frame_number(root, f, name, where); };
  TransformsIntrinsics k;
  k.fl_x = num("fl_x"), k.fl_y = num("fl_y"), k.cx = num("cx"), k.cy = num("cy");
  k.camera_angle_x = num("camera_angle_x"), k.camera_angle_y = num("camera_angle_y");
  const auto w = num("w"), h = num("h");
  k.w = w ? static_cast<int>(std::lround(*w)) : 0;
  k.h = h ? static_cast<int>(std::lround(*h)) : 0;
  if ((w && k.w <= 0) || (h && k.h <= 0))
    throw std::runtime_error(fmt::format("{}: fields 'w'/'h': expected positive image sizes", where));
  if ((k.fl_x && !(*k.fl_x > 0)) || (k.fl_y && !(*k.fl_y > 0)))
    throw std::runtime_error(fmt::format("{}: fields 'fl_x'/'fl_y': expected positive focal lengths", where));
  for (const auto& a : {k.camera_angle_x, k.camera_angle_y})
    if (a && !(*a > 0 && *a < M_PI))
      throw std::runtime_error(fmt::format("{}: fields 'camera_angle_x'/'camera_angle_y': expected angles in (0, pi) "
                                           "radians, got {}",
                                           where, *a));
  return k;
}

// Why the frame is not a plain pinhole camera (for the one warning), or nullptr. Reads the distortion fields even
// when no warning is wanted, so a malformed one is refused either way.
const char* frame_distortion(const json& root, const json& f, const std::string& where) {
  bool distorted = false;
  for (const char* d : {"k1", "k2", "k3", "k4", "p1", "p2"})
    distorted |= frame_number(root, f, d, where).value_or(0.0) != 0.0;
  const json* model = frame_field(root, f, "camera_model");
  const bool fisheye = model && model->is_string() && model->get<std::string>().find("FISHEYE") != std::string::npos;
  if (fisheye) return "fisheye camera_model";
  return distorted ? "non-zero distortion coefficients" : nullptr;
}

TransformsFrame read_frame(const json& root, const json& f, const fs::path& folder, const std::string& where) {
  if (!f.is_object()) throw std::runtime_error(fmt::format("{}: expected an object", where));
  if (!f.contains("file_path") || !f["file_path"].is_string())
    throw std::runtime_error(fmt::format("{}.file_path: expected a string (the image path)", where));
  TransformsFrame out;
  out.file_path = f["file_path"].get<std::string>();
  out.resolved = resolve_frame_path(folder, out.file_path);
  const std::string mwhere = where + ".transform_matrix";
  double c2w[4][4];
  read_c2w(f, mwhere, c2w);
  out.w2c = opengl_c2w_to_w2c(c2w, mwhere);
  out.intrinsics = read_frame_intrinsics(root, f, where);
  return out;
}

}  // namespace

std::vector<TransformsFrame> read_transforms(const std::string& path, std::vector<std::string>* warnings) {
  const json j = read_transforms_json(path);
  const fs::path folder = fs::absolute(fs::path(path)).parent_path();
  std::vector<TransformsFrame> frames;
  bool warned_distortion = false;
  for (size_t i = 0; i < j["frames"].size(); ++i) {
    const json& f = j["frames"][i];
    const std::string where = fmt::format("{}: frames[{}]", path, i);
    TransformsFrame frame = read_frame(j, f, folder, where);
    const char* distortion = frame_distortion(j, f, where);
    if (warnings && distortion && !warned_distortion) {
      warnings->push_back(
          fmt::format("{}: {}: the distortion is ignored and the photos are used as pinhole images", path, distortion));
      warned_distortion = true;
    }
    frames.push_back(std::move(frame));
  }
  return frames;
}

std::optional<PinholeIntrinsics> transforms_intrinsics(const TransformsIntrinsics& k, int width, int height) {
  const double w = k.w > 0 ? k.w : width, h = k.h > 0 ? k.h : height;
  std::optional<double> fx = k.fl_x, fy = k.fl_y;
  if (!fx && k.camera_angle_x) fx = 0.5 * w / std::tan(0.5 * *k.camera_angle_x);  // instant-NGP
  if (!fy && k.camera_angle_y) fy = 0.5 * h / std::tan(0.5 * *k.camera_angle_y);
  if (!fx && fy) fx = fy;
  if (!fx) return std::nullopt;
  if (!fy) fy = fx;
  return PinholeIntrinsics{*fx, *fy, k.cx.value_or(0.5 * w), k.cy.value_or(0.5 * h), static_cast<int>(w),
                           static_cast<int>(h)};
}

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
