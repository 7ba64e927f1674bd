#include "uplvsm/core/json_input.h"

#include <fstream>

namespace uplvsm {

nlohmann::json read_json_file(const std::string& path, const std::string& what) {
  const std::string name = what.empty() ? path : what + " " + path;
  std::ifstream in(path);
  if (!in) throw std::runtime_error(name + ": cannot open");
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(name + ": not valid JSON (" + e.what() + ")");
  }
}

}  // namespace uplvsm
