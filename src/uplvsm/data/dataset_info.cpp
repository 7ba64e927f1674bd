// dataset.json reading and writing; see dataset_info.h.
#include "uplvsm/data/dataset_info.h"

#include <filesystem>
#include <stdexcept>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "uplvsm/io/atomic_file.h"

namespace uplvsm::data {

DatasetInfo read_dataset_info(const std::string& root) {
  const auto path = (std::filesystem::path(root) / "dataset.json").string();
  DatasetInfo info;
  if (!std::filesystem::exists(path)) return info;
  const auto bytes = io::read_file(path);
  const auto j = nlohmann::json::parse(bytes.begin(), bytes.end(), nullptr, /*allow_exceptions=*/false);
  if (!j.is_object()) throw std::runtime_error(fmt::format("{}: expected a JSON object", path));
  if (j.contains("generator")) {
    if (!j["generator"].is_string())
      throw std::runtime_error(fmt::format("{}: field 'generator' must be a string", path));
    info.generator = j["generator"].get<std::string>();
  }
  if (j.contains("view_order")) {
    const auto& order = j["view_order"];
    if (!order.is_string() || (order != "ordered" && order != "unordered"))
      throw std::runtime_error(
          fmt::format("{}: field 'view_order' must be \"ordered\" or \"unordered\", got {}", path, order.dump()));
    info.ordered_views = order == "ordered";
  }
  return info;
}

void write_dataset_info(const std::string& root, const DatasetInfo& info) {
  const nlohmann::json j = {{"generator", info.generator},
                            {"view_order", info.ordered_views ? "ordered" : "unordered"}};
  const auto text = j.dump(2) + "\n";
  io::write_file_atomic((std::filesystem::path(root) / "dataset.json").string(), text.data(), text.size());
}

}  // namespace uplvsm::data
