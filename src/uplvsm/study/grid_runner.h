// The grid studies (`uplvsm study scaling`, `study pose-noise`) as library calls: grids of training runs whose series
// are model configs (UP-LVSM, PT-LVSM, LVSM) and whose settings are nested training-data subsets (the paper's
// scalability study, Table 3) or Gaussian noise on the training poses (the appendix's pose-noise study), each for one
// or more training seeds, every run scored on one fixed test set. <out>/runs/<series>__<setting>/ is an ordinary run
// directory (resumable training, eval/); a run whose result.json exists is not redone. The grid's table, CSV, plots
// and README.md (study/grid_report.h) land in <out>/.
#pragma once
#include <torch/torch.h>

#include <string>
#include <utility>
#include <vector>

#include "uplvsm/core/config.h"
#include "uplvsm/study/grid_report.h"
#include "uplvsm/study/study_grid.h"
#include "uplvsm/train/perceptual_loss.h"

namespace uplvsm::study {

// What every grid study takes (the command's shared flags).
struct GridOptions {
  std::vector<std::string> configs;  // one config file per series
  std::string data, out;             // dataset root (train/, test/ + evaluation_index.json); study directory
  std::string vgg19, init;           // perceptual-loss weights and starting weights of every run, as for train
  train::VggInput vgg19_input = train::VggInput::Auto;
  std::string lpips_net = "vgg", lpips_backbone, lpips_lin;  // LPIPS weights; none: LPIPS unavailable
  int64_t steps = -1;                                        // training steps of every run (<= 0: each config's)
  int64_t eval_scenes = 0;                                   // test scenes scored per run (0: the whole index)
  std::vector<int64_t> seeds;                                // empty: each config's training.seed
  std::vector<std::string> overrides;                        // section.field=value, applied to every config
  bool report_only = false;                              // tables and plots from the runs already done; nothing trains
  std::string reference, reference_title = "reference";  // published numbers drawn beside ours
  std::string from_table;  // with report_only: cells from a study's table.csv instead of runs/
  torch::Device device = torch::kCPU;
  bool progress = true;  // the trainer's progress bar
};

struct GridRun {
  std::string series, setting, dir_name;
  double x = 0;
  Config config;
  // dir_name of an earlier run whose result this one is (a model that never reads training cameras is trained
  // once for every pose-noise level: its runs would be identical, as tests/cli/study_grid_slow_test.cpp checks).
  std::string same_as;
};

// A study's runs, what its figures are called and the README's description of a run.
struct GridPlan {
  std::vector<GridRun> runs;
  GridFigure figure;
  std::string description;
};

struct GridResult {
  std::vector<GridCell> cells;  // one per run (and seed), in plan order
  std::string table;            // the Markdown table, as table.md holds it
};

// "100", "full" -> scene counts (0: every training scene), checked against the train split's size.
std::vector<int64_t> parse_subsets(const std::vector<std::string>& tokens, int64_t available);
// The noise levels as standard deviations (the official noise_scale), from stds and variances (their square roots:
// the paper's caption writes sigma^2), each labelled with how it was given; sorted, repeats once.
std::vector<std::pair<double, std::string>> noise_levels(const std::vector<double>& stds,
                                                         const std::vector<double>& variances);

// The scalability study: each series on each subset ("25", "full"; of the train split); subset i trains
// steps x growth^i steps, every run with the given pose noise.
GridPlan scaling_plan(const GridOptions& options, const std::vector<std::string>& subsets, double growth,
                      double noise_std);
// The pose-noise study at these levels (noise_levels; empty: sd 0, 0.001, 0.01, 0.1).
GridPlan pose_noise_plan(const GridOptions& options, std::vector<std::pair<double, std::string>> levels);

// Trains (or resumes) and scores every run of the plan, once per seed, then writes the report; with report_only,
// the report from the runs done (or options.from_table). Every run's loss and tokenizer are checked first.
GridResult run_grid(const GridPlan& plan, const GridOptions& options);

}  // namespace uplvsm::study
