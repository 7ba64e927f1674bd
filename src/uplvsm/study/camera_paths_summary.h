// Several `study camera-paths` runs read together (`uplvsm study camera-paths-summary`, issue 82): each run scores one
// model's camera control (and maybe its estimator) on the same rooms along the same path, so two methods are compared
// scene by scene. A difference of means over 16 rooms moves with the rooms drawn, and a scene hard for one method is
// hard for the other; the interval of a difference is therefore a paired percentile bootstrap over the scenes (one
// draw shared by both methods, study/scaling_gain.h), and a difference is a finding only when it excludes 0. The
// summary also draws PSNR against the frame's position along the inputs' baseline, the span between them shaded.
#pragma once
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "uplvsm/io/plot.h"
#include "uplvsm/study/camera_paths.h"
#include "uplvsm/study/scaling_gain.h"

namespace uplvsm::study {

struct CameraPathsRun {
  std::string label, dir;  // dir holds camera_paths.csv and camera_paths_scenes.csv
};

// "LABEL=DIR" (or DIR alone, labelled by its folder name).
CameraPathsRun parse_camera_paths_run(const std::string& arg);

// camera_paths_scenes.csv and camera_paths.csv as write_camera_paths() writes them; throw naming the file and line.
std::vector<PathSceneScore> read_camera_paths_scenes(const std::string& path);
std::vector<PathFrameScore> read_camera_paths_frames(const std::string& path);

// A method's name in the summary: the run's label for its camera control, "LABEL (METHOD)" for any other method.
std::string summary_method_name(const std::string& label, const std::string& method);

struct PathMetricStat {
  std::string metric;  // wobble, psnr_inside, psnr_beyond
  std::string a, b;    // b empty: a's mean over scenes; else a − b, paired over the scenes both scored
  Interval interval;
};

struct CameraPathsSummary {
  std::vector<std::string> methods;       // in the runs' order
  std::vector<PathMetricStat> stats;      // means, then every pair's differences, per metric
  std::vector<io::Series> psnr_position;  // one line per method: mean PSNR per position bin
};

// The runs' methods compared on the scenes every method scored (the paths must match: same frames per scene).
CameraPathsSummary summarise_camera_paths(const std::vector<CameraPathsRun>& runs, double bin_width = 0.25,
                                          const BootstrapOptions& options = {});

// summary.json (the stats), differences.csv (one row per stat) and psnr_position.png.
void write_camera_paths_summary(const CameraPathsSummary& summary, const std::string& out_dir);

}  // namespace uplvsm::study
