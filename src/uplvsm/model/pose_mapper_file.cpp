#include "uplvsm/model/pose_mapper_file.h"

#include <fmt/format.h>

#include <cstring>
#include <stdexcept>

#include "uplvsm/io/pose_mapper_file.h"
#include "uplvsm/io/state_dict.h"

namespace uplvsm::model {

namespace {

constexpr const char* kMapperPrefix = "pose_mapper.";  // the mapper's parameters inside the model

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

}  // namespace

std::string model_fingerprint(UPLVSMImpl& net) {
  Fnv64 fnv;
  for (const auto& item : net.named_parameters(true)) {
    if (item.key().rfind(kMapperPrefix, 0) == 0) continue;
    auto t = item.value().detach().to(torch::kCPU, torch::kFloat32).contiguous();
    fnv.bytes(item.key().data(), item.key().size());
    fnv.bytes(t.data_ptr(), static_cast<size_t>(t.numel()) * sizeof(float));
  }
  return fmt::format("{:016x}", fnv.h);
}

void save_pose_mapper(const std::string& path, PoseMapperImpl& mapper, const std::string& fingerprint,
                      const nlohmann::json& fit) {
  io::PoseMapperFile file{to_string(mapper.options.kind), mapper.options.hidden, io::state_dict(mapper), fingerprint,
                          fit};
  io::write_pose_mapper_file(path, file);
}

LoadedPoseMapper load_pose_mapper(const std::string& path) {
  auto file = io::read_pose_mapper_file(path);
  PoseMapperOptions options;
  try {
    options.kind = parse_pose_mapper_kind(file.kind);
  } catch (const std::logic_error& e) {
    throw std::runtime_error(fmt::format("{}: metadata kind/hidden: {}", path, e.what()));
  }
  options.hidden = file.hidden;
  LoadedPoseMapper out{PoseMapper(options), file.model_fingerprint, file.fit};
  io::load_state_dict(*out.mapper, file.tensors, path);  // strict: names and shapes must match the kind
  return out;
}

void attach_pose_mapper_file(UPLVSMImpl& net, const std::string& path) {
  auto loaded = load_pose_mapper(path);
  const auto mine = model_fingerprint(net);
  if (loaded.model_fingerprint != mine)
    throw std::runtime_error(
        fmt::format("{}: this pose mapper was fitted to another model (weights fingerprint {}, "
                    "this model's {}); fit one to this model with `uplvsm fit-mapper`",
                    path, loaded.model_fingerprint, mine));
  net.attach_pose_mapper(loaded.mapper);
}

}  // namespace uplvsm::model
