// What a training run will do, in a few lines a person reads before the hours start: the global batch and how it is
// reached, the schedule, the precision, the loss terms, the data and its shuffling. `uplvsm train` prints it at the
// start of every run, and `uplvsm train --dry-run` prints it and stops.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "uplvsm/core/config.h"
#include "uplvsm/train/global_batch.h"

namespace uplvsm::train {

struct RunPlan {
  Config config;
  BatchPlan batch;
  std::string device = "cpu";
  std::string perceptual_weights;       // the --vgg19 file; empty: none given
  std::string init;                     // --init weights; empty: from scratch (or the checkpoint resumed)
  bool resuming = false;                // the run goes on from its own checkpoint
  std::string data_root;                // empty: not given (a dry run)
  std::optional<int64_t> scenes;        // training scenes the run draws from, when the data was read
  std::optional<int64_t> split_scenes;  // scenes in the split (or subset) they are the first of
  std::optional<bool> ordered_views;    // from the dataset when read; else from training.view_sampler
};

// One "name  value" line per aspect, in a fixed order.
std::vector<std::string> describe_run_plan(const RunPlan& plan);

}  // namespace uplvsm::train
