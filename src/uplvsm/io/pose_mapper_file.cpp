#include "uplvsm/io/pose_mapper_file.h"

#include <fmt/format.h>

#include <cstring>
#include <map>
#include <stdexcept>

#include "uplvsm/io/safetensors.h"

namespace uplvsm::io {

namespace {

constexpr const char* kPrefix = "pose_mapper.";

std::string meta(const std::map<std::string, std::string>& m, const std::string& key, const std::string& path) {
  auto it = m.find(key);
  if (it == m.end())
    throw std::runtime_error(
        fmt::format("{}: not a pose mapper file (metadata lacks \"{}\"; write one with "
                    "`uplvsm fit-mapper`)",
                    path, key));
  return it->second;
}

}  // namespace

void write_pose_mapper_file(const std::string& path, const PoseMapperFile& file) {
  TensorMap tensors;
  for (const auto& [name, t] : file.tensors) tensors[kPrefix + name] = t.to(torch::kFloat32);
  write_safetensors(path, tensors,
                    {{"format", kPoseMapperFormat},
                     {"kind", file.kind},
                     {"hidden", std::to_string(file.hidden)},
                     {"model_fingerprint", file.model_fingerprint},
                     {"fit", file.fit.dump()}});
}

PoseMapperFile read_pose_mapper_file(const std::string& path) {
  auto file = read_safetensors(path);
  const auto format = meta(file.metadata, "format", path);
  if (format != kPoseMapperFormat)
    throw std::runtime_error(
        fmt::format("{}: pose mapper format '{}', expected '{}'", path, format, kPoseMapperFormat));
  PoseMapperFile out;
  out.kind = meta(file.metadata, "kind", path);
  try {
    out.hidden = std::stoll(meta(file.metadata, "hidden", path));
  } catch (const std::logic_error& e) {
    throw std::runtime_error(fmt::format("{}: metadata kind/hidden: {}", path, e.what()));
  }
  if (out.hidden < 1 || out.hidden > 4096)
    throw std::runtime_error(fmt::format("{}: metadata hidden {} is outside 1..4096", path, out.hidden));
  for (const auto& [name, t] : file.tensors)
    out.tensors[name.rfind(kPrefix, 0) == 0 ? name.substr(std::strlen(kPrefix)) : name] = t;
  out.model_fingerprint = meta(file.metadata, "model_fingerprint", path);
  out.fit = nlohmann::json::parse(file.metadata.count("fit") ? file.metadata.at("fit") : "{}", nullptr, false);
  if (out.fit.is_discarded()) out.fit = nlohmann::json::object();
  return out;
}

}  // namespace uplvsm::io
