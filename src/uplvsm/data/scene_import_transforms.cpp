// nerfstudio / instant-NGP transforms.json of a user's photo folder (scene_import.h): pure parsing, with errors that
// name the file, the frame and the field. import_scene (scene_import.cpp) decides which source wins.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <stdexcept>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "uplvsm/core/json_input.h"
#include "uplvsm/data/scene_import.h"

namespace uplvsm::data {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

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
      if (c == '\\' && i + 1 < text.size())
        out += text[++i];
      else if (c == '"')
        in_string = false;
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
    throw std::runtime_error(
        fmt::format("{}: the rotation part is not orthonormal (|R^T R - I| = {:.3g}); expected "
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
      throw std::runtime_error(
          fmt::format("{}: fields 'camera_angle_x'/'camera_angle_y': expected angles in (0, pi) "
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
  return PinholeIntrinsics{
      *fx, *fy, k.cx.value_or(0.5 * w), k.cy.value_or(0.5 * h), static_cast<int>(w), static_cast<int>(h)};
}

}  // namespace uplvsm::data
