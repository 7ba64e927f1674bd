#include "uplvsm/serve/json_request.h"

#include <cmath>
#include <cstdlib>

#include <fmt/format.h>

#include "uplvsm/serve/http_error.h"

namespace uplvsm::serve {

namespace {
// Deepest [ / { nesting outside strings.
int json_depth(const std::string& s) {
  int depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (char c : s) {
    if (in_string) {
      if (escaped)
        escaped = false;
      else if (c == '\\')
        escaped = true;
      else if (c == '"')
        in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      deepest = std::max(deepest, ++depth);
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return deepest;
}
}  // namespace

nlohmann::json parse_json_body(const std::string& body) {
  if (body.empty()) return nlohmann::json::object();
  if (body.size() > kMaxJsonBytes)
    throw HttpError(413, fmt::format("request body of {} bytes: at most {} allowed", body.size(), kMaxJsonBytes));
  if (json_depth(body) > kMaxJsonDepth)
    throw HttpError(400, fmt::format("request body nests deeper than {} levels", kMaxJsonDepth));
  auto j = nlohmann::json::parse(body, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) throw HttpError(400, "request body is not valid JSON");
  if (!j.is_object()) throw HttpError(400, "request body must be a JSON object");
  return j;
}

torch::Tensor read_pose(const nlohmann::json& value, const std::string& field) {
  if (!value.is_array() || value.size() != 7)
    throw HttpError(400, field + ": expected 7 numbers [tx, ty, tz, qx, qy, qz, qw]");
  std::vector<double> v;
  for (const auto& x : value) {
    if (!x.is_number() || !std::isfinite(x.get<double>())) throw HttpError(400, field + ": expected finite numbers");
    v.push_back(x.get<double>());
  }
  auto pose = torch::tensor(v, torch::kFloat64);
  if (pose.slice(0, 0, 3).abs().max().item<double>() > 1e4)
    throw HttpError(400, field + ": translation out of range (|t| <= 1e4)");
  const double qn = pose.slice(0, 3, 7).norm().item<double>();
  if (qn < 1e-6) throw HttpError(400, field + ": zero quaternion");
  pose.slice(0, 3, 7).div_(qn);
  return pose;
}

torch::Tensor read_poses(const nlohmann::json& value, const std::string& field, size_t min, size_t max) {
  if (!value.is_array() || value.size() < min || value.size() > max)
    throw HttpError(400, fmt::format("{}: expected an array of {} to {} poses", field, min, max));
  std::vector<torch::Tensor> poses;
  for (size_t i = 0; i < value.size(); ++i) poses.push_back(read_pose(value[i], fmt::format("{}[{}]", field, i)));
  return torch::stack(poses);
}

double read_number(const nlohmann::json& body, const std::string& field, double fallback, double lo, double hi) {
  if (!body.contains(field)) return fallback;
  const auto& v = body[field];
  if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < lo || v.get<double>() > hi)
    throw HttpError(400, fmt::format("{}: expected a number in [{}, {}]", field, lo, hi));
  return v.get<double>();
}

std::string read_choice(const nlohmann::json& body, const std::string& field, const std::string& fallback,
                        std::initializer_list<const char*> allowed) {
  if (!body.contains(field)) return fallback;
  std::string names;
  for (const char* a : allowed) {
    if (body[field].is_string() && body[field].get<std::string>() == a) return a;
    names += (names.empty() ? "" : ", ") + std::string(a);
  }
  throw HttpError(400, fmt::format("{}: expected one of {}", field, names));
}

double parse_number(const std::string& text, const std::string& field, double lo, double hi) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v) || v < lo || v > hi)
    throw HttpError(400, fmt::format("{}: expected a number in [{}, {}], got \"{}\"", field, lo, hi, text));
  return v;
}

}  // namespace uplvsm::serve
