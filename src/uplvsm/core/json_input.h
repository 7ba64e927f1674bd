// Values from untrusted JSON files, read without undefined behaviour or deep recursion. nlohmann's get<int64_t>()
// casts any number (4e24 is undefined behaviour, found by fuzzing the config parser; 3.7 silently becomes 3), and
// its dump() recurses once per nesting level (a 64 kB file of '[' overflowed the stack in an error message).
#pragma once
#include <nlohmann/json.hpp>

#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

namespace uplvsm {

// A short description of a value for error messages: scalars as written, containers by type and size.
inline std::string json_excerpt(const nlohmann::json& v) {
  if (v.is_array()) return "an array of " + std::to_string(v.size());
  if (v.is_object()) return "an object of " + std::to_string(v.size()) + " fields";
  const std::string text = v.dump();
  return text.size() > 80 ? text.substr(0, 77) + "..." : text;
}

// A JSON integer within int64; `where` names the field in the error ("config x.json: training.warmup").
inline int64_t json_integer(const nlohmann::json& v, const std::string& where) {
  const bool fits =
      v.is_number_integer() &&
      (!v.is_number_unsigned() || v.get<uint64_t>() <= static_cast<uint64_t>(std::numeric_limits<int64_t>::max()));
  if (!fits) throw std::runtime_error(where + ": expected an integer, got " + json_excerpt(v));
  return v.get<int64_t>();
}

// A whole JSON file. Errors say "<what> <path>: cannot open" or "<what> <path>: not valid JSON (<parser message>)",
// `what` naming the kind of file ("subset manifest"; empty: the path alone).
nlohmann::json read_json_file(const std::string& path, const std::string& what = "");

}  // namespace uplvsm
