// Multi-run studies (the paper's scalability study and pose-noise study): a grid of series (model variants) by
// settings (training-data subsets, pose-noise levels), each cell one trained and evaluated run. This file turns the
// cells into the paper-style table (Markdown and CSV), metric-vs-setting plots, and the paper's scalability
// measure, the average gain per 4x data (Table 3's "Avg. Gain", study/scaling_gain.h).
#pragma once
#include <torch/torch.h>

#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "uplvsm/io/plot.h"
#include "uplvsm/study/scene_scores.h"

namespace uplvsm::study {

struct GridCell {
  std::string series;   // e.g. "uplvsm"
  std::string setting;  // e.g. "little (100 scenes)" or "noise sd 0.01"
  double x = 0;         // the setting's value on the plot's x axis (scenes, noise level)
  double psnr = 0, ssim = 0;
  double lpips = std::numeric_limits<double>::quiet_NaN();  // NaN: LPIPS weights were not given
  int64_t seed = 0;                                         // the run's training seed
  int64_t runs = 1;  // seeds averaged into this cell (mean_over_seeds); 0: a planned run not done yet (no metrics)
  double psnr_spread = 0, ssim_spread = 0, lpips_spread = 0;  // half of each metric's range over those seeds
  // The run's score on each test scene (the evaluator's per_scene.csv, or the study's scenes.csv); null: not kept.
  std::shared_ptr<const SceneScores> scenes{};
};

// The cell's "psnr", "ssim" or "lpips"; throws std::invalid_argument for any other name.
double metric_value(const GridCell& cell, const std::string& metric);

// One cell per (series, setting), in order of first appearance: the mean over its seeds' runs, with their count
// and spreads.
std::vector<GridCell> mean_over_seeds(const std::vector<GridCell>& runs);

// Series and settings in the order they first appear in `cells`.
std::vector<std::string> series_of(const std::vector<GridCell>& cells);
// A series' name in the paper's words for legends and titles ("uplvsm" -> "UP-LVSM", "ptlvsm" -> "PT-LVSM", "lvsm" ->
// "LVSM"); any other name as it is. Tables and CSVs keep the variant names scripts read.
std::string paper_name(const std::string& series);
// A metric's axis label: "PSNR (dB)", "SSIM", "LPIPS".
std::string metric_label(const std::string& metric);
std::vector<std::string> settings_of(const std::vector<GridCell>& cells);

// Rows = series, columns = settings, "PSNR / SSIM / LPIPS" per cell (LPIPS "-" when unavailable; a mean over
// several seeds shows "PSNR ±half-range"), plus the average-gain column when with_gain: the paper's gain per 4x data
// (study/scaling_gain.h) of PSNR with its 95 % interval, of SSIM and of LPIPS, read from the per-seed `runs` (from
// `cells` without them). Missing cells read "(not run)".
std::string grid_markdown(const std::vector<GridCell>& cells, bool with_gain, const std::vector<GridCell>& runs = {});
// One row per cell: series,setting,x,seed,psnr,ssim,lpips (empty when unavailable).
std::string grid_csv(const std::vector<GridCell>& cells);
// metric "psnr" | "ssim" | "lpips" against x, one line per series, a marker per cell, the seeds' spread as error
// bars and x ticks only at the cells' x. On a log x axis an x of 0 (e.g. no pose noise) stands a decade left of the
// smallest positive x, labelled "0". uint8 [H, W, 3].
torch::Tensor grid_plot(const std::vector<GridCell>& cells, const std::string& metric, io::PlotOptions options);

}  // namespace uplvsm::study
