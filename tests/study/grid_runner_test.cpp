// The grid studies through study:: without the binary: the plans (subsets, growing budgets, the pose-noise levels a
// model that never reads training cameras stands at) and a micro pose-noise grid trained, scored, reported and read
// back.
#include "uplvsm/study/grid_runner.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "train/train_test_util.h"

using namespace uplvsm;
namespace fs = std::filesystem;

namespace {

// A micro config of `variant` written to <dir>/<name>.json.
std::string micro_config_file(const fs::path& dir, const std::string& variant, int64_t steps) {
  auto c = test::micro_config();
  c.name = "micro_" + variant;
  c.model = test::micro_model(variant);
  c.training.train_steps = steps;
  const auto path = (dir / (c.name + ".json")).string();
  std::ofstream(path) << config_to_json(c).dump(2);
  return path;
}

}  // namespace

TEST(GridRunner, PlansSubsetsWithAGrowingBudgetAndPoseNoiseStandIns) {
  const auto dir = test::temp_dir("grid_plan");
  study::GridOptions o;
  o.configs = {micro_config_file(dir, "uplvsm", 10), micro_config_file(dir, "lvsm", 10)};
  o.data = test::micro_dataset();
  const auto scaling = study::scaling_plan(o, {"2", "full"}, 2.0, 0.0);
  ASSERT_EQ(scaling.runs.size(), 4u);
  EXPECT_EQ(scaling.runs[0].dir_name, "uplvsm__2");
  EXPECT_EQ(scaling.runs[1].setting, "full (6)");
  EXPECT_EQ(scaling.runs[1].x, 6);
  EXPECT_EQ(scaling.runs[0].config.training.train_steps, 10);
  EXPECT_EQ(scaling.runs[1].config.training.train_steps, 20);
  EXPECT_EQ(scaling.runs[0].config.training.max_train_scenes, 2);
  EXPECT_TRUE(scaling.figure.with_gain);
  EXPECT_THROW(study::scaling_plan(o, {"9"}, 1.0, 0.0), std::runtime_error);  // more scenes than the split has
  const auto noise = study::pose_noise_plan(o, study::noise_levels({0, 0.1}, {0.01}));
  ASSERT_EQ(noise.runs.size(), 4u);  // sd 0.1 and var 0.01 are one level
  EXPECT_EQ(noise.runs[1].setting, "noise sd 0.1 = var 0.01");
  EXPECT_EQ(noise.runs[1].same_as, "uplvsm__noise_sd0");  // UP-LVSM never reads training cameras
  EXPECT_EQ(noise.runs[3].same_as, "");                   // LVSM does
  EXPECT_EQ(noise.runs[3].config.training.pose_noise_std, 0.1);
}

TEST(GridRunner, TrainsAMicroGridOnceScoresItAndReadsItBack) {
  const auto dir = test::temp_dir("grid_runner");
  study::GridOptions o;
  o.configs = {micro_config_file(dir, "uplvsm", 2)};
  o.data = test::micro_dataset();
  o.out = (dir / "study").string();
  o.eval_scenes = 1;
  o.progress = false;
  const auto plan = study::pose_noise_plan(o, study::noise_levels({0, 0.1}, {}));
  const auto result = study::run_grid(plan, o);
  ASSERT_EQ(result.cells.size(), 2u);
  EXPECT_GT(result.cells[0].psnr, 5.0);
  EXPECT_EQ(result.cells[1].psnr, result.cells[0].psnr);  // trained once, standing at both levels
  EXPECT_EQ(result.cells[1].x, 0.1);
  EXPECT_TRUE(fs::exists(fs::path(o.out) / "runs" / "uplvsm__noise_sd0" / "result.json"));
  EXPECT_FALSE(fs::exists(fs::path(o.out) / "runs" / "uplvsm__noise_sd0.1"));
  EXPECT_NE(result.table.find("| Method | noise sd 0 | noise sd 0.1 |"), std::string::npos) << result.table;
  for (const auto* file : {"table.md", "table.csv", "study.json", "README.md"})
    EXPECT_TRUE(fs::exists(fs::path(o.out) / file)) << file;
  // The report alone, from the runs done: the same cells, nothing trained again.
  o.report_only = true;
  const auto again = study::run_grid(plan, o);
  ASSERT_EQ(again.cells.size(), 2u);
  EXPECT_EQ(again.cells[0].psnr, result.cells[0].psnr);
  EXPECT_EQ(again.table, result.table);
}
