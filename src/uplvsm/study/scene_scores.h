// Each test scene's scores of a study's runs. A run's score is the mean over its test scenes, so how much that mean
// would move on other scenes drawn alike is read from these: the intervals of study/scaling_gain.h resample the
// scenes, the same draw for every run (paired: a scene hard for one model is hard for all, and that cancels in a
// difference). A study keeps them in scenes.csv beside table.csv, so its intervals can be redrawn from the committed
// files without the run folders.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace uplvsm::study {

struct SceneScores {
  std::vector<std::string> keys;
  std::vector<double> psnr, ssim, lpips;  // lpips NaN where the evaluation had no LPIPS weights
  // "psnr" | "ssim" | "lpips"; throws std::invalid_argument for any other name.
  const std::vector<double>& metric(const std::string& name) const;
};

// The evaluator's per_scene.csv (eval/result_files.cpp: key, ..., psnr, ssim, lpips, ...; the columns found by their
// names); throws naming the file and the line for anything else.
SceneScores read_eval_per_scene(const std::string& path);

// One run's scenes as a study's scenes.csv holds them.
struct RunScenes {
  std::string series, setting;
  int64_t seed = 0;
  SceneScores scores;
};

// scenes.csv: series,setting,seed,scene,psnr,ssim,lpips (lpips empty when unavailable), one line per run and scene,
// six decimals as table.csv: intervals redrawn from it match the run folders' to the digits any report prints.
std::string study_scenes_csv(const std::vector<RunScenes>& runs);
// Its runs, in the order the file first names them; throws naming the file and the line for anything else.
std::vector<RunScenes> read_study_scenes(const std::string& path);

}  // namespace uplvsm::study
