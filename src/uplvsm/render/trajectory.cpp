#include "uplvsm/render/trajectory.h"

#include <cmath>
#include <fstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "uplvsm/core/json_input.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::render {

namespace {
double fraction(int64_t i, int64_t n) { return n <= 1 ? 0.0 : static_cast<double>(i) / static_cast<double>(n - 1); }

// A path is returned in float32 (float64 keys: float64), as the official render_video, never in the keys' lower
// precision: keys estimated under bf16 autocast would snap every in-between frame to a bf16 pose, and the video
// would step instead of moving smoothly.
torch::ScalarType path_dtype(const torch::Tensor& keys) {
  return keys.scalar_type() == torch::kFloat64 ? torch::kFloat64 : torch::kFloat32;
}
}  // namespace

torch::Tensor interpolate_poses(const torch::Tensor& keys, int64_t n) {
  TORCH_CHECK(keys.dim() == 2 && keys.size(1) == 7 && keys.size(0) >= 2,
              "interpolate_poses: expected [K >= 2, 7] key poses, got ", keys.sizes());
  TORCH_CHECK(n >= 1, "interpolate_poses: frames per segment must be >= 1");
  auto k = keys.to(torch::kFloat64);
  std::vector<torch::Tensor> frames;
  for (int64_t s = 0; s + 1 < k.size(0); ++s) {
    auto q0 = k[s].slice(0, 3, 7), q1 = k[s + 1].slice(0, 3, 7);
    q0 = q0 / q0.norm();
    q1 = q1 / q1.norm();
    auto t0 = k[s].slice(0, 0, 3), t1 = k[s + 1].slice(0, 0, 3);
    for (int64_t i = 0; i < n; ++i) {
      double a = fraction(i, n);
      auto q = geometry::quat_slerp(q0, q1, a);
      frames.push_back(torch::cat({t0 * (1 - a) + t1 * a, q}));
    }
  }
  return torch::stack(frames).to(path_dtype(keys));
}

torch::Tensor interpolate_intrinsics(const torch::Tensor& keys, int64_t n) {
  TORCH_CHECK(keys.dim() == 2 && keys.size(1) == 4 && keys.size(0) >= 2,
              "interpolate_intrinsics: expected [K >= 2, 4], got ", keys.sizes());
  auto k = keys.to(torch::kFloat64);
  std::vector<torch::Tensor> frames;
  for (int64_t s = 0; s + 1 < k.size(0); ++s)
    for (int64_t i = 0; i < n; ++i) {
      double a = fraction(i, n);
      frames.push_back(k[s] * (1 - a) + k[s + 1] * a);
    }
  return torch::stack(frames).to(path_dtype(keys));
}

torch::Tensor look_at_pose(const torch::Tensor& position_in, const torch::Tensor& target_in) {
  auto position = position_in.to(torch::kFloat64), target = target_in.to(torch::kFloat64);
  auto z = target - position;
  TORCH_CHECK(z.norm().item<double>() > 1e-9, "look_at_pose: the camera sits on its target");
  z = z / z.norm();
  auto down = torch::tensor({0.0, 1.0, 0.0}, torch::kFloat64);
  auto x = torch::linalg_cross(down, z);
  TORCH_CHECK(x.norm().item<double>() > 1e-9, "look_at_pose: viewing direction parallel to the up axis");
  x = x / x.norm();
  auto y = torch::linalg_cross(z, x);
  auto R = torch::stack({x, y, z}, 1);  // columns: camera axes in the first view's frame
  return torch::cat({position, geometry::rotation_to_quat(R)});
}

torch::Tensor camera_path_preset(const std::string& name, int64_t frames, const PresetOptions& o) {
  TORCH_CHECK(frames >= 2, "camera path: need at least 2 frames");
  const auto focus = torch::tensor({0.0, 0.0, o.focus_distance}, torch::kFloat64);
  std::vector<torch::Tensor> poses;
  for (int64_t i = 0; i < frames; ++i) {
    const double phase = 2.0 * M_PI * static_cast<double>(i) / static_cast<double>(frames);  // one loop
    if (name == "orbit") {
      const double theta = 0.5 * o.arc_degrees * M_PI / 180.0 * std::sin(phase);
      auto p = torch::tensor({o.focus_distance * std::sin(theta), 0.0, o.focus_distance * (1 - std::cos(theta))},
                             torch::kFloat64);
      poses.push_back(look_at_pose(p, focus));
    } else if (name == "spiral") {
      auto p = torch::tensor(
          {o.radius * std::sin(phase), o.radius * (1 - std::cos(phase)) * 0.5, 0.25 * o.radius * (1 - std::cos(phase))},
          torch::kFloat64);
      poses.push_back(look_at_pose(p, focus));
    } else if (name == "dolly") {
      poses.push_back(torch::tensor({0.0, 0.0, o.radius * std::sin(phase), 0.0, 0.0, 0.0, 1.0}, torch::kFloat64));
    } else {
      throw std::invalid_argument("camera path preset '" + name + "': expected orbit, spiral or dolly");
    }
  }
  return torch::stack(poses);
}

namespace {
// A field's numbers: a list, or a list of rows (a matrix). Deeper nesting is an error, not recursed into (a file of
// '[' would overflow the stack).
std::vector<double> numbers(const nlohmann::json& j, const std::string& where) {
  std::vector<double> out;
  auto number = [&](const nlohmann::json& v) {
    if (!v.is_number())
      throw std::runtime_error(where + ": expected numbers or rows of numbers, got " + json_excerpt(v));
    out.push_back(v.get<double>());
  };
  if (!j.is_array()) throw std::runtime_error(where + ": expected a list of numbers, got " + json_excerpt(j));
  for (const auto& row : j) {
    if (!row.is_array())
      number(row);
    else
      for (const auto& v : row) number(v);
  }
  for (double x : out)
    if (!std::isfinite(x)) throw std::runtime_error(where + ": not a finite number");
  return out;
}
}  // namespace

CameraPath read_camera_path(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("camera path " + path + ": cannot open");
  nlohmann::json j;
  try {
    in >> j;
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error("camera path " + path + ": invalid JSON (" + e.what() + ")");
  }
  if (!j.is_object() || !j.contains("frames") || !j["frames"].is_array() || j["frames"].empty())
    throw std::runtime_error("camera path " + path + ": expected an object with a non-empty \"frames\" list");
  if (j["frames"].size() > static_cast<size_t>(kMaxVideoFrames))
    throw std::runtime_error("camera path " + path + ": " + std::to_string(j["frames"].size()) + " frames, more than " +
                             "the " + std::to_string(kMaxVideoFrames) + " a video may have");
  const std::string units = j.value("units", "baseline");
  if (units != "baseline" && units != "latent")
    throw std::runtime_error("camera path " + path +
                             ": \"units\" must be \"baseline\" (real cameras, translations in "
                             "input baselines) or \"latent\" (the model's latent poses)");
  std::vector<torch::Tensor> poses, intrinsics;
  for (size_t i = 0; i < j["frames"].size(); ++i) {
    const auto& f = j["frames"][i];
    const std::string where = "camera path " + path + ": frames[" + std::to_string(i) + "]";
    if (f.contains("pose")) {
      auto v = numbers(f["pose"], where + ".pose");
      if (v.size() != 7) throw std::runtime_error(where + ".pose: expected 7 numbers (tx ty tz qx qy qz qw)");
      auto pose = torch::tensor(v, torch::kFloat64);
      const double qn = pose.slice(0, 3, 7).norm().item<double>();
      if (qn < 1e-9) throw std::runtime_error(where + ".pose: zero quaternion");
      pose.slice(0, 3, 7).div_(qn);
      poses.push_back(pose);
    } else if (f.contains("c2w")) {
      auto v = numbers(f["c2w"], where + ".c2w");
      if (v.size() != 16 && v.size() != 12) throw std::runtime_error(where + ".c2w: expected 4x4 or 3x4 numbers");
      auto m = geometry::pad_to_4x4(torch::tensor(v, torch::kFloat64).view({-1, 4}).slice(0, 0, 3));
      auto R = m.slice(0, 0, 3).slice(1, 0, 3);
      if ((torch::matmul(R.t(), R) - torch::eye(3, torch::kFloat64)).abs().max().item<double>() > 1e-3)
        throw std::runtime_error(where + ".c2w: the rotation part is not orthonormal");
      poses.push_back(geometry::c2w_to_pose_encoding(m));
    } else {
      throw std::runtime_error(where + ": needs \"pose\" or \"c2w\"");
    }
    if (f.contains("fxfycxcy")) {
      auto v = numbers(f["fxfycxcy"], where + ".fxfycxcy");
      if (v.size() != 4 || v[0] <= 0 || v[1] <= 0)
        throw std::runtime_error(where + ".fxfycxcy: expected 4 numbers (normalised fx fy cx cy, fx, fy > 0)");
      intrinsics.push_back(torch::tensor(v, torch::kFloat64));
    }
  }
  if (!intrinsics.empty() && intrinsics.size() != poses.size())
    throw std::runtime_error("camera path " + path + ": give \"fxfycxcy\" on every frame or on none");
  return {torch::stack(poses), intrinsics.empty() ? torch::Tensor() : torch::stack(intrinsics), units == "latent"};
}

}  // namespace uplvsm::render
