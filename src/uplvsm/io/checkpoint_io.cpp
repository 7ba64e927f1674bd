#include "uplvsm/io/checkpoint_io.h"

#include <algorithm>
#include <filesystem>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/io/safetensors.h"

namespace uplvsm::io {

namespace fs = std::filesystem;

std::string resolve_checkpoint(const std::string& path) {
  fs::path p(path);
  if (!fs::exists(p)) throw std::runtime_error(fmt::format("checkpoint {}: no such file or directory", path));
  if (fs::is_regular_file(p)) return p.string();
  if (fs::is_directory(p / "checkpoints")) p /= "checkpoints";
  std::vector<std::string> found;
  for (const auto& e : fs::directory_iterator(p)) {
    auto name = e.path().filename().string();
    if (e.is_regular_file() && name.rfind("ckpt_", 0) == 0 && e.path().extension() == ".safetensors")
      found.push_back(e.path().string());
  }
  if (found.empty())
    throw std::runtime_error(fmt::format("checkpoint {}: directory holds no ckpt_*.safetensors files", p.string()));
  return *std::max_element(found.begin(), found.end());
}

CheckpointFile read_checkpoint(const std::string& path_in) {
  CheckpointFile out;
  out.path = resolve_checkpoint(path_in);
  auto st = io::read_safetensors(out.path);
  auto meta = [&](const char* key) -> const std::string& {
    auto it = st.metadata.find(key);
    if (it == st.metadata.end())
      throw std::runtime_error(
          fmt::format("checkpoint {}: header metadata lacks '{}' (not a uplvsm checkpoint; "
                      "official .pt files are read by `uplvsm convert`)",
                      out.path, key));
    return it->second;
  };
  if (meta("format") != kCheckpointFormat)
    throw std::runtime_error(
        fmt::format("checkpoint {}: format '{}', expected '{}'", out.path, meta("format"), kCheckpointFormat));
  try {
    out.config = config_from_json(nlohmann::json::parse(meta("config")), out.path + " (embedded config)");
    out.state = nlohmann::json::parse(meta("state"));
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(fmt::format("checkpoint {}: metadata is not valid JSON ({})", out.path, e.what()));
  }
  const std::string prefix = kOptimizerPrefix;
  for (auto& [name, tensor] : st.tensors) {
    if (name.rfind(prefix, 0) == 0)
      out.optimizer[name.substr(prefix.size())] = tensor;
    else
      out.model[name] = tensor;
  }
  return out;
}

void write_checkpoint(const std::string& path, const Config& config, const nlohmann::json& state,
                      const NamedTensors& model, const NamedTensors& optimizer) {
  io::TensorMap all(model.begin(), model.end());
  for (const auto& [name, tensor] : optimizer) all[kOptimizerPrefix + name] = tensor;
  io::write_safetensors(
      path, all, {{"format", kCheckpointFormat}, {"config", config_to_json(config).dump()}, {"state", state.dump()}});
}

}  // namespace uplvsm::io
