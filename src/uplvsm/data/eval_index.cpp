// Evaluation index JSON reading/writing and overlap buckets.
#include "uplvsm/data/eval_index.h"

#include <algorithm>
#include <fstream>
#include <stdexcept>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "uplvsm/core/json_input.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"

namespace uplvsm::data {
namespace {

std::vector<int64_t> frame_list(const nlohmann::json& entry, const char* name, const std::string& where) {
  if (!entry.contains(name) || !entry[name].is_array() || entry[name].empty())
    throw std::runtime_error(fmt::format("{}: field '{}' must be a non-empty list of frame indices", where, name));
  std::vector<int64_t> frames;
  for (const auto& v : entry[name]) {
    if (!v.is_number_integer() || v.get<int64_t>() < 0)
      throw std::runtime_error(fmt::format("{}: field '{}' has a non-frame value {}", where, name, json_excerpt(v)));
    frames.push_back(v.get<int64_t>());
  }
  return frames;
}

EvalEntry parse_entry(const std::string& key, const nlohmann::json& value, const std::string& where) {
  if (!value.is_object())
    throw std::runtime_error(fmt::format("{}: expected an object or null, got {}", where, value.type_name()));
  EvalEntry e;
  e.key = key;
  e.context = frame_list(value, "context", where);
  e.target = frame_list(value, "target", where);
  if (value.contains("overlap") && !value["overlap"].is_null()) {
    if (!value["overlap"].is_number())
      throw std::runtime_error(fmt::format("{}: field 'overlap' must be a number", where));
    e.overlap = value["overlap"].get<double>();
  }
  return e;
}

}  // namespace

std::vector<EvalEntry> read_eval_index(const std::string& path, int64_t* num_null) {
  auto j = read_json_file(path, "evaluation index");
  if (!j.is_object())
    throw std::runtime_error(fmt::format("read_eval_index: {}: expected an object {{scene key: entry}}", path));
  std::vector<EvalEntry> entries;
  int64_t nulls = 0;
  for (auto& [key, value] : j.items()) {
    if (value.is_null()) {
      ++nulls;
      continue;
    }
    entries.push_back(parse_entry(key, value, fmt::format("read_eval_index: {}: key {}", path, key)));
  }
  std::sort(entries.begin(), entries.end(), [](const EvalEntry& a, const EvalEntry& b) { return a.key < b.key; });
  if (num_null) *num_null = nulls;
  return entries;
}

void write_eval_index(const std::string& path, const std::vector<EvalEntry>& entries) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& e : entries) {
    if (j.contains(e.key)) throw std::runtime_error(fmt::format("write_eval_index: {}: duplicate key {}", path, e.key));
    nlohmann::json entry = {{"context", e.context}, {"target", e.target}};
    if (e.overlap) entry["overlap"] = *e.overlap;
    j[e.key] = entry;
  }
  std::string text = j.dump(2) + "\n";
  io::write_file_atomic(path, text.data(), text.size());
}

std::string overlap_bucket(double overlap) {
  if (overlap >= 0.05 && overlap <= 0.3) return "small";
  if (overlap <= 0.55) return "medium";
  if (overlap <= 0.8) return "large";
  return "ignore";
}

}  // namespace uplvsm::data
