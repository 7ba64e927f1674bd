// A side-by-side HTML page of several models (the demo: the shipped model beside the `tiny` trained on the spot):
// one column per model with its results table, training curve, videos and a few scene grids, small renders shown
// large with nearest-neighbour upscaling. Each model's full report (eval/report.h) is written in a sub-folder and
// linked from its column.
#pragma once
#include <string>
#include <vector>

#include "uplvsm/eval/report.h"

namespace uplvsm::eval {

struct ComparedModel {
  std::string label;    // column heading, e.g. "Shipped demo model (96x96)"
  std::string caption;  // one line under the heading (may be empty)
  ReportInputs report;  // what its own full report shows
};

// Writes out_dir/index.html and out_dir/model_<i>/ (each model's write_report); returns index.html's path. Throws
// like write_report for a metrics.json that is not evaluate()'s.
std::string write_comparison_report(const std::string& out_dir, const std::string& title,
                                    const std::vector<ComparedModel>& models, const std::string& runtime_info = "");

}  // namespace uplvsm::eval
