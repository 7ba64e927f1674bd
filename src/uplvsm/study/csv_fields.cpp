#include "uplvsm/study/csv_fields.h"

#include <cmath>
#include <stdexcept>

namespace uplvsm::study {

std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted && c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
      fields.back() += '"', ++i;
    } else if (c == '"') {
      quoted = !quoted;
    } else if (c == ',' && !quoted) {
      fields.emplace_back();
    } else {
      fields.back() += c;
    }
  }
  return fields;
}

double csv_number(const std::string& field) {
  size_t used = 0;
  const double v = std::stod(field, &used);  // throws std::invalid_argument on "" and words
  if (used != field.size() || !std::isfinite(v)) throw std::invalid_argument(field);
  return v;
}

}  // namespace uplvsm::study
