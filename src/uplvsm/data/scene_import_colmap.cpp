// COLMAP's text model of a user's photo folder (cameras.txt, images.txt; scene_import.h): pure parsing, with
// errors that name the file, the line and the field. import_scene (scene_import.cpp) decides which source wins.
#include <array>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/data/scene_import.h"

namespace uplvsm::data {

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
      throw std::runtime_error(
          fmt::format("{}: expected 'CAMERA_ID MODEL WIDTH HEIGHT PARAMS...', got '{}'", where, line));
    ColmapCamera cam;
    cam.id = parse_integer(tok[0].first, where, "CAMERA_ID");
    cam.model = tok[1].first;
    const auto* model = std::find_if(kColmapModels.begin(), kColmapModels.end(),
                                     [&](const ColmapModel& m) { return cam.model == m.name; });
    if (model == kColmapModels.end()) {
      std::string known;
      for (const auto& m : kColmapModels) known += std::string(known.empty() ? "" : ", ") + m.name;
      throw std::runtime_error(
          fmt::format("{}: unknown camera model '{}' (expected one of {})", where, cam.model, known));
    }
    const int64_t w = parse_integer(tok[2].first, where, "WIDTH"), h = parse_integer(tok[3].first, where, "HEIGHT");
    if (w <= 0 || h <= 0)
      throw std::runtime_error(fmt::format("{}: fields WIDTH HEIGHT: expected positive sizes, got {} {}", where, w, h));
    if (static_cast<int>(tok.size()) - 4 != model->num_params)
      throw std::runtime_error(fmt::format("{}: model {} expects {} parameters ({}), got {}", where, model->name,
                                           model->num_params, model->params, tok.size() - 4));
    const auto names = tokens(model->params);
    std::vector<double> p;
    for (int i = 0; i < model->num_params; ++i) p.push_back(parse_number(tok[4 + i].first, where, names[i].first));
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
      throw std::runtime_error(
          fmt::format("{}: expected 'IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME', got '{}' ({} fields)", where, line,
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

}  // namespace uplvsm::data
