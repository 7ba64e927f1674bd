// The statistics a grid study reports, each with its interval (study/scaling_gain.h): every cell's mean over its
// seeds, every pair of models' difference at each setting, and in a scaling study every model's gain per 4x data (the
// paper's estimator) and every pair's difference of PSNR gains. stats.csv holds them all for a report or a figure to
// read back; the table and README show the gains.
#pragma once
#include <limits>
#include <string>
#include <vector>

#include "uplvsm/study/scaling_gain.h"
#include "uplvsm/study/study_grid.h"

namespace uplvsm::study {

struct GridStat {
  // "mean", "gain", and "difference" (series - other at a setting), "gain_difference" (series' gain - other's) for
  // each pair of models in the order they first appear
  std::string statistic;
  std::string series, other, setting, metric;
  double x = std::numeric_limits<double>::quiet_NaN();  // the setting's x ("mean", "difference")
  Interval interval;
};

// The runs' scores of one metric as the estimator reads them, with their per-scene scores where every run kept the
// same test scenes (matched by key, in the first run's order); without, none (the intervals then redraw seeds only).
std::vector<ScoredRun> scored_runs(const std::vector<GridCell>& runs, const std::string& metric);

// Every statistic above of the runs done (runs > 0); the gains only when with_gain.
std::vector<GridStat> grid_stats(const std::vector<GridCell>& runs, bool with_gain,
                                 const BootstrapOptions& options = {});

// stats.csv: statistic,series,other,setting,x,metric,estimate,lo,hi,seeds,scenes,resampled.
std::string grid_stats_csv(const std::vector<GridStat>& stats);
// The README's section: the PSNR gains and their differences with their intervals, and what each interval redraws.
std::string grid_stats_markdown(const std::vector<GridStat>& stats);

}  // namespace uplvsm::study
