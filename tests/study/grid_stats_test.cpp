#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <memory>

#include <fmt/format.h>

#include "test_util.h"
#include "uplvsm/study/grid_report.h"
#include "uplvsm/study/grid_stats.h"

using namespace uplvsm;

namespace {

std::shared_ptr<const study::SceneScores> scenes(std::vector<std::string> keys, std::vector<double> psnr) {
  const std::vector<double> none(psnr.size(), std::nan(""));
  return std::make_shared<const study::SceneScores>(study::SceneScores{std::move(keys), psnr, psnr, none});
}

const study::GridStat* find(const std::vector<study::GridStat>& stats, const std::string& statistic,
                            const std::string& series, const std::string& setting = "") {
  for (const auto& s : stats)
    if (s.statistic == statistic && s.series == series && s.setting == setting && s.metric == "psnr") return &s;
  return nullptr;
}

}  // namespace

// Per-scene scores are paired by scene key whatever order each run listed them in; a run without one of the scenes
// leaves every run without (the intervals then redraw seeds only).
TEST(GridStats, ScenesArePairedByKey) {
  study::GridCell a{"up", "125 scenes", 125, 21.0, 0.6, std::nan(""), 777};
  study::GridCell b{"lvsm", "125 scenes", 125, 23.0, 0.7, std::nan(""), 777};
  a.scenes = scenes({"s1", "s2"}, {20.0, 22.0});
  b.scenes = scenes({"s2", "s1"}, {24.0, 22.0});
  auto scored = study::scored_runs({a, b}, "psnr");
  ASSERT_EQ(scored.size(), 2u);
  EXPECT_EQ(scored[1].scenes, (std::vector<double>{22.0, 24.0}));  // in a's order: s1, s2
  b.scenes = scenes({"s2", "s3"}, {24.0, 22.0});
  scored = study::scored_runs({a, b}, "psnr");
  EXPECT_TRUE(scored[0].scenes.empty());
  EXPECT_TRUE(scored[1].scenes.empty());
}

// A scaling study's statistics: each cell's mean, each pair's difference at each setting, each model's gain and each
// pair's difference of gains, with what the interval redrew; stats.csv holds them, one line each.
TEST(GridStats, ScalingStudyReportsMeansDifferencesAndGains) {
  std::vector<study::GridCell> runs;
  for (int64_t seed : {777, 778})
    for (double x : {125.0, 8000.0}) {
      const double up = 26.0 + (x == 8000 ? 0.3 : 0) - (seed == 778 ? 0.5 : 0);
      runs.push_back({"uplvsm", fmt::format("{:g} scenes", x), x, up, 0.6, std::nan(""), seed});
      runs.push_back({"lvsm", fmt::format("{:g} scenes", x), x, 30.0, 0.7, std::nan(""), seed});
    }
  const auto stats = study::grid_stats(runs, true);
  const auto* mean = find(stats, "mean", "uplvsm", "125 scenes");
  ASSERT_TRUE(mean);
  EXPECT_NEAR(mean->interval.estimate, 25.75, 1e-9);
  EXPECT_NEAR(mean->interval.lo, 25.5, 1e-9);
  EXPECT_NEAR(mean->interval.hi, 26.0, 1e-9);
  const auto* lead = find(stats, "difference", "uplvsm", "8000 scenes");
  ASSERT_TRUE(lead);
  EXPECT_EQ(lead->other, "lvsm");
  EXPECT_NEAR(lead->interval.estimate, -3.95, 1e-9);
  const auto* gain = find(stats, "gain", "uplvsm");
  ASSERT_TRUE(gain);
  EXPECT_NEAR(gain->interval.estimate, 0.1, 1e-9);  // 0.3 dB over 64x = 3 rungs, both seeds alike
  const auto* gains = find(stats, "gain_difference", "uplvsm");
  ASSERT_TRUE(gains);
  EXPECT_NEAR(gains->interval.estimate, 0.1, 1e-9);
  EXPECT_EQ(gains->interval.resampled(), "seeds");
  const auto csv = study::grid_stats_csv(stats);
  EXPECT_EQ(csv.substr(0, csv.find('\n')),
            "statistic,series,other,setting,x,metric,estimate,lo,hi,seeds,scenes,resampled");
  EXPECT_NE(csv.find("\ngain,uplvsm,,,,psnr,0.100000,0.100000,0.100000,2,0,seeds\n"), std::string::npos) << csv;
  EXPECT_EQ(study::grid_stats(runs, false).size(), stats.size() - 5);  // gains of PSNR and SSIM, the PSNR gain pair
  EXPECT_NE(study::grid_stats_markdown(stats).find("| UP-LVSM - LVSM | 0.10 |"), std::string::npos);
}

// A study redrawn from its committed files: table.csv's runs get their per-scene scores from the scenes.csv beside
// it, so the intervals over test scenes are the same as from the run folders.
TEST(GridStats, TableCellsTakeTheirScenesFromScenesCsv) {
  const auto dir = test::temp_dir("grid_stats_scenes");
  study::GridCell a{"up", "125 scenes", 125, 21.0, 0.6, std::nan(""), 777};
  a.scenes = scenes({"s1", "s2"}, {20.0, 22.0});
  study::GridCell b{"lvsm", "125 scenes", 125, 23.0, 0.7, std::nan(""), 777};
  study::write_grid_report({a, b}, {}, dir.string(), study::GridFigure{"t", "x"}, "d");
  const auto cells = study::read_table_cells((dir / "table.csv").string());
  ASSERT_EQ(cells.size(), 2u);
  ASSERT_TRUE(cells[0].scenes);
  EXPECT_EQ(cells[0].scenes->keys, (std::vector<std::string>{"s1", "s2"}));
  EXPECT_FALSE(cells[1].scenes);  // b kept none
  test::remove_tree(dir);
}
