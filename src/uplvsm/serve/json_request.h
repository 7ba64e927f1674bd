// Reading what a viewer client sends: JSON bodies parsed only after a size and nesting-depth check (a recursive
// parser must not be handed "[[[[..." from the network), and the typed fields the API takes (7-D poses, numbers in
// a range, enums). Every failure is an HttpError 400 naming the field and what was expected.
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>
#include <string>

namespace uplvsm::serve {

inline constexpr size_t kMaxJsonBytes = size_t{1} << 20;
inline constexpr int kMaxJsonDepth = 16;

// An object parsed from `body`; an empty body is an empty object.
nlohmann::json parse_json_body(const std::string& body);

// pose: 7 finite numbers (tx ty tz qx qy qz qw), |t| <= 1e4, a non-zero quaternion (normalised) -> float64 [7].
torch::Tensor read_pose(const nlohmann::json& value, const std::string& field);
// poses: an array of [min, max] poses -> float64 [F, 7].
torch::Tensor read_poses(const nlohmann::json& value, const std::string& field, size_t min, size_t max);
// A number in [lo, hi] (the default when absent).
double read_number(const nlohmann::json& body, const std::string& field, double fallback, double lo, double hi);
// One of `allowed` (the default when absent).
std::string read_choice(const nlohmann::json& body, const std::string& field, const std::string& fallback,
                        std::initializer_list<const char*> allowed);
// A number given as a query parameter (the default when absent).
double parse_number(const std::string& text, const std::string& field, double lo, double hi);

}  // namespace uplvsm::serve
