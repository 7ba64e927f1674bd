// The fields of one line of the CSV files a study reads back: its own table.csv and scenes.csv, the paper's
// reference cells and the evaluator's per_scene.csv (whose scene keys are quoted when they hold a comma or a quote).
#pragma once
#include <string>
#include <vector>

namespace uplvsm::study {

// The comma-separated fields of `line`; a field in double quotes may hold commas, and "" stands for one quote.
std::vector<std::string> csv_fields(const std::string& line);

// The whole field as a finite number ("2000abc", "", "nan" and "inf" throw std::invalid_argument): a table's number
// is read exactly as it was written or not at all.
double csv_number(const std::string& field);

}  // namespace uplvsm::study
