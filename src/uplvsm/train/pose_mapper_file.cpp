#include "uplvsm/train/pose_mapper_file.h"

#include <cstring>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/state_dict.h"

namespace uplvsm::train {

namespace {

constexpr const char* kPrefix = "pose_mapper.";

// FNV-1a over 64-bit words (the tail byte-wise): fast enough for a 300M-parameter model (a second or so).
struct Fnv64 {
  uint64_t h = 1469598103934665603ull;
  void bytes(const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    size_t i = 0;
    for (; i + 8 <= n; i += 8) {
      uint64_t w;
      std::memcpy(&w, p + i, 8);
      h = (h ^ w) * 1099511628211ull;
    }
    for (; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
  }
};

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

std::string model_fingerprint(model::UPLVSMImpl& net) {
  Fnv64 fnv;
  for (const auto& item : net.named_parameters(true)) {
    if (item.key().rfind(kPrefix, 0) == 0) continue;
    auto t = item.value().detach().to(torch::kCPU, torch::kFloat32).contiguous();
    fnv.bytes(item.key().data(), item.key().size());
    fnv.bytes(t.data_ptr(), static_cast<size_t>(t.numel()) * sizeof(float));
  }
  return fmt::format("{:016x}", fnv.h);
}

void write_pose_mapper_file(const std::string& path, model::PoseMapperImpl& mapper, const std::string& fingerprint,
                            const nlohmann::json& fit) {
  io::TensorMap tensors;
  for (const auto& [name, t] : io::state_dict(mapper)) tensors[kPrefix + name] = t.to(torch::kFloat32);
  io::write_safetensors(path, tensors,
                        {{"format", kPoseMapperFormat},
                         {"kind", to_string(mapper.options.kind)},
                         {"hidden", std::to_string(mapper.options.hidden)},
                         {"model_fingerprint", fingerprint},
                         {"fit", fit.dump()}});
}

PoseMapperFile read_pose_mapper_file(const std::string& path) {
  auto file = io::read_safetensors(path);
  const auto format = meta(file.metadata, "format", path);
  if (format != kPoseMapperFormat)
    throw std::runtime_error(
        fmt::format("{}: pose mapper format '{}', expected '{}'", path, format, kPoseMapperFormat));
  model::PoseMapperOptions options;
  try {
    options.kind = model::parse_pose_mapper_kind(meta(file.metadata, "kind", path));
    options.hidden = std::stoll(meta(file.metadata, "hidden", path));
  } catch (const std::logic_error& e) {
    throw std::runtime_error(fmt::format("{}: metadata kind/hidden: {}", path, e.what()));
  }
  if (options.hidden < 1 || options.hidden > 4096)
    throw std::runtime_error(fmt::format("{}: metadata hidden {} is outside 1..4096", path, options.hidden));
  PoseMapperFile out;
  out.mapper = model::PoseMapper(options);
  io::NamedTensors tensors;
  for (const auto& [name, t] : file.tensors)
    tensors[name.rfind(kPrefix, 0) == 0 ? name.substr(std::strlen(kPrefix)) : name] = t;
  io::load_state_dict(*out.mapper, tensors, path);  // strict: names and shapes must match the kind
  out.model_fingerprint = meta(file.metadata, "model_fingerprint", path);
  out.fit = nlohmann::json::parse(file.metadata.count("fit") ? file.metadata.at("fit") : "{}", nullptr, false);
  if (out.fit.is_discarded()) out.fit = nlohmann::json::object();
  return out;
}

void attach_pose_mapper_file(model::UPLVSMImpl& net, const std::string& path) {
  auto file = read_pose_mapper_file(path);
  const auto mine = model_fingerprint(net);
  if (file.model_fingerprint != mine)
    throw std::runtime_error(
        fmt::format("{}: this pose mapper was fitted to another model (weights fingerprint {}, "
                    "this model's {}); fit one to this model with `uplvsm fit-mapper`",
                    path, file.model_fingerprint, mine));
  net.attach_pose_mapper(file.mapper);
}

}  // namespace uplvsm::train
