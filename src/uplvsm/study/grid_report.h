// What a grid study (`uplvsm study scaling`, `study pose-noise`) leaves in its folder for a person to read:
// table.md and table.csv, each run's per-scene scores (scenes.csv) and every statistic with its interval (stats.csv,
// study/grid_stats.h), one quick-look plot per metric against the setting, the trained runs' held-out curves
// (curves.csv, curves_<model>.png) and a README.md that shows them all. The figures of docs/research/thesis.md are
// drawn from these CSVs by tools/thesis/plot_thesis.py.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "uplvsm/study/study_grid.h"

namespace uplvsm::study {

struct GridFigure {
  std::string title, xlabel;
  bool log_x = false, with_gain = false;
  // Published numbers to show beside ours (e.g. the paper's table), drawn alike in reference_<metric>.png.
  std::vector<GridCell> reference{};
  std::string reference_title{};
};

// Reference cells from a CSV with the header series,setting,x,psnr,ssim,lpips (lpips may be empty); throws naming
// the file and line for anything else.
std::vector<GridCell> read_reference_cells(const std::string& path);
// Every run's cell from a study's own table.csv (series,setting,x,seed,psnr,ssim,lpips, as grid_csv writes it), to
// redraw a study whose run folders are on another machine, with its per-scene scores from the scenes.csv beside it
// where there is one; throws naming the file and line for anything else.
std::vector<GridCell> read_table_cells(const std::string& path);

// A study run's per-scene scores: <run_dir>/eval/per_scene.csv as the evaluator wrote it; null without the file.
std::shared_ptr<const SceneScores> run_scene_scores(const std::string& run_dir);

// One trained run's periodic evaluations: its legend label and its metrics.jsonl.
struct RunCurve {
  std::string series, setting, metrics_path;
  int64_t seed = 0;
};

// A run's held-out PSNR by step (the "eval" lines of its metrics.jsonl); empty without them.
io::Series held_out_curve(const RunCurve& run);

// A run's training PSNR near its end: -10 log10 of the mean training MSE (its metrics.jsonl's "mse" lines, skipped
// steps left out) over the last `window` steps. Its gap to the held-out PSNR holds a fixed offset (the two sample
// views alike, not identically); how the gap shrinks from small subsets to large shows over-fitting. NaN without any.
double training_psnr(const RunCurve& run, double window = 1000);

// Whether a held-out curve has levelled off: the least-squares slope of its points in the last `window` steps, in
// dB per 1000 steps; levelled when under kLevelledSlope (a falling curve, over-fitting, has levelled too).
inline constexpr double kLevelledSlope = 0.05;
struct Levelling {
  double last_step = 0, final_psnr = 0;
  double slope = 0;  // dB per 1000 steps; NaN with fewer than three points in the window
  int points = 0;
  bool levelled() const { return slope < kLevelledSlope; }  // false for NaN
};
Levelling levelling(const io::Series& curve, double window = 2000);

// Writes the files above into out_dir from every run's cell (seeds averaged for the table and plots, each run in
// table.csv; scenes.csv only where some run has per-scene scores) and the runs' curves (curves.* only where some run
// has periodic evaluations). Returns the table.
std::string write_grid_report(const std::vector<GridCell>& runs, const std::vector<RunCurve>& curves,
                              const std::string& out_dir, const GridFigure& fig, const std::string& description);

}  // namespace uplvsm::study
