// What `uplvsm train` was asked for, before any weights load: the config with its command-line overrides, and the
// plan a --dry-run prints with the checks that decide whether the run would start. The CLI only parses flags into
// a TrainRequest and prints what these return.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "uplvsm/core/config.h"
#include "uplvsm/train/run_plan.h"

namespace uplvsm::train {

struct TrainRequest {
  std::string config_path;
  std::vector<std::string> set;  // section.field=value overrides, applied in order
  int64_t steps = -1;            // > 0: overrides training.train_steps
  std::string amp;               // non-empty: overrides training.amp
  std::string subset;            // non-empty: overrides training.subset
  std::string stage = "main";    // main, mapper or tokenizer
  std::string init, resume = "auto", data, run, vgg19;
};

// The config file with --set and the other overrides applied; --stage mapper turns on the pose mapper.
Config train_config(const TrainRequest& request);

// The plan of a run on `ranks` data-parallel processes; with request.data, its train split is read for the scene
// count and how views are drawn.
RunPlan dry_run_plan(const TrainRequest& request, const Config& config, int64_t ranks, const std::string& device);

// Throws what the run itself would refuse to start with: a perceptual loss without weights, a tokenizer with no
// start.
void require_run_starts(const RunPlan& plan);

}  // namespace uplvsm::train
