// Where a report's pieces come from: the directories `train`, `eval` and `render` wrote for one model, named by the
// `report` command's flags or by one --model 'label=...,eval=DIR,...' spec, read into what eval/report.h lays out.
#pragma once
#include <string>
#include <vector>

#include "uplvsm/eval/report.h"

namespace uplvsm::eval {

// What one model's report shows, from the directories `train`, `eval` and `render` wrote.
struct ModelDirs {
  std::string label, caption, run, eval;
  std::vector<std::string> videos;
};

// The report of `dirs`: the eval's metrics.json and scene grids (in name order), the run's config and training log,
// each render directory's first video, and this machine's runtime facts. Throws for a missing eval directory or one
// named that does not exist.
ReportInputs report_inputs(const ModelDirs& dirs);

// "label=NAME,run=DIR,eval=DIR,video=DIR[,video=DIR...][,caption=TEXT]" (values may not contain commas); throws
// naming the spec for an unknown key, an item without a value, or no label.
ModelDirs parse_model_spec(const std::string& spec);

}  // namespace uplvsm::eval
