// The multi-run studies through the binary at micro scale: study scaling (nested subsets, resumable, a budget that
// grows) and study pose-noise (UP-LVSM never reads training cameras, so it is trained once; LVSM's result moves).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "train/train_test_util.h"

namespace fs = std::filesystem;

namespace {
using uplvsm::test::run_cli;

nlohmann::json read_json(const fs::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in);
}

// Micro configs of two variants and a micro built-in dataset, written once.
struct StudyFixture {
  fs::path dir = uplvsm::test::temp_dir("study_grid");
  std::string uplvsm_cfg, lvsm_cfg, data;
  StudyFixture() {
    auto c = uplvsm::test::micro_config();
    c.training.train_steps = 6;
    c.dataset.num_train_scenes = 4;
    c.dataset.num_test_scenes = 2;
    c.dataset.render_height = 36;
    c.dataset.render_width = 64;
    c.dataset.eval_gap = 6;
    uplvsm_cfg = (dir / "micro.json").string();
    std::ofstream(uplvsm_cfg) << uplvsm::config_to_json(c).dump(2);
    c.name = "micro_lvsm";
    c.model = uplvsm::test::micro_model("lvsm");
    lvsm_cfg = (dir / "micro_lvsm.json").string();
    std::ofstream(lvsm_cfg) << uplvsm::config_to_json(c).dump(2);
    data = (dir / "data").string();
    EXPECT_EQ(run_cli("make-dataset --config " + uplvsm_cfg + " --out " + data), 0);
  }
};
}  // namespace

TEST(StudyGrid, ScalingTrainsEachSubsetOnceAndWritesTheTable) {
  StudyFixture f;
  const auto out = (f.dir / "scaling").string();
  const auto cmd = "study scaling --config " + f.uplvsm_cfg + " " + f.lvsm_cfg + " --data " + f.data +
                   " --subsets 2 full --steps 4 --out " + out;
  std::string text;
  ASSERT_EQ(run_cli(cmd, &text), 0);
  EXPECT_NE(text.find("| Method | 2 scenes | full (4) | Avg. gain |"), std::string::npos) << text;
  EXPECT_NE(text.find("first 2 of 4"), std::string::npos) << text;
  for (const auto* run : {"uplvsm__2", "uplvsm__full", "lvsm__2", "lvsm__full"}) {
    auto r = read_json(fs::path(out) / "runs" / run / "result.json");
    EXPECT_EQ(r.at("steps"), 4) << run;
    EXPECT_GT(r.at("psnr").get<double>(), 5.0) << run;
  }
  for (const auto* file : {"table.md", "table.csv", "psnr.png", "ssim.png", "README.md", "study.json"})
    EXPECT_TRUE(fs::exists(fs::path(out) / file)) << file;
  EXPECT_FALSE(fs::exists(fs::path(out) / "lpips.png"));  // no LPIPS weights given: no made-up LPIPS figure
  // Rerunning does not redo finished runs.
  ASSERT_EQ(run_cli(cmd, &text), 0);
  EXPECT_NE(text.find("already done"), std::string::npos) << text;
  EXPECT_EQ(text.find("training micro"), std::string::npos) << text;
  // A subset larger than the split is refused, naming the sizes.
  EXPECT_NE(
      run_cli("study scaling --config " + f.uplvsm_cfg + " --data " + f.data + " --subsets 9 --out " + out + "_bad",
              &text),
      0);
  EXPECT_NE(text.find("only 4 scenes"), std::string::npos) << text;
}

// Levels given both ways (sd 0.1 and variance 0.01 are one level), two seeds; UP-LVSM, which never reads training
// cameras, is trained once per seed and stands at every level; LVSM's result moves with the noise.
TEST(StudyGrid, PoseNoiseMovesLvsmButNotUplvsm) {
  StudyFixture f;
  const auto out = (f.dir / "noise").string();
  std::string text;
  ASSERT_EQ(run_cli("study pose-noise --config " + f.uplvsm_cfg + " " + f.lvsm_cfg + " --data " + f.data +
                        " --noise-std 0 0.1 --noise-variance 0.01 --seeds 5 6 --steps 4 --out " + out,
                    &text),
            0);
  for (const auto* seed : {"5", "6"}) {
    auto lv0 = read_json(fs::path(out) / (std::string("runs/lvsm__noise_sd0__seed") + seed) / "result.json");
    auto lv1 = read_json(fs::path(out) / (std::string("runs/lvsm__noise_sd0.1__seed") + seed) / "result.json");
    EXPECT_NE(lv0.at("psnr").get<double>(), lv1.at("psnr").get<double>()) << seed;
    EXPECT_EQ(lv1.at("seed"), std::stoi(seed));
    EXPECT_TRUE(fs::exists(fs::path(out) / (std::string("runs/uplvsm__noise_sd0__seed") + seed)));
    EXPECT_FALSE(fs::exists(fs::path(out) / (std::string("runs/uplvsm__noise_sd0.1__seed") + seed)));
  }
  EXPECT_NE(text.find("| Method | noise sd 0 | noise sd 0.1 = var 0.01 |"), std::string::npos) << text;
  std::ifstream csv_file(fs::path(out) / "table.csv");
  const std::string csv((std::istreambuf_iterator<char>(csv_file)), std::istreambuf_iterator<char>());
  EXPECT_NE(csv.find("uplvsm,noise sd 0.1 = var 0.01,0.1,6,"), std::string::npos) << csv;  // x: the level's sd
  for (const auto* file : {"README.md", "psnr.png", "ssim.png"}) EXPECT_TRUE(fs::exists(fs::path(out) / file)) << file;
}

// The budget grows with the subset (--steps-growth), and the pose noise reaches every run's config.
TEST(StudyGrid, ScalingBudgetGrowsWithTheSubset) {
  StudyFixture f;
  const auto out = (f.dir / "scaling_growth").string();
  std::string text;
  ASSERT_EQ(
      run_cli("study scaling --config " + f.lvsm_cfg + " --data " + f.data +
                  " --subsets 1 4 --steps 2 --steps-growth 2 --noise-std 0.05 --set training.eval_every=2 --out " + out,
              &text),
      0);
  EXPECT_EQ(read_json(fs::path(out) / "runs/lvsm__1/result.json").at("steps"), 2);
  EXPECT_EQ(read_json(fs::path(out) / "runs/lvsm__4/result.json").at("steps"), 4);
  auto plan = read_json(fs::path(out) / "study.json");
  EXPECT_EQ(plan.at("runs")[1].at("config").at("training").at("pose_noise_std"), 0.05);
  // Held-out curves from the periodic evaluations (--set training.eval_every): steps 2 and 4 of the larger subset.
  std::ifstream curves(fs::path(out) / "curves.csv");
  const std::string text_csv((std::istreambuf_iterator<char>(curves)), std::istreambuf_iterator<char>());
  EXPECT_NE(text_csv.find("lvsm,4 scenes,777,4,"), std::string::npos) << text_csv;
  EXPECT_NE(text_csv.find("lvsm,4 scenes,777,2,"), std::string::npos) << text_csv;
  EXPECT_TRUE(fs::exists(fs::path(out) / "curves_lvsm.png"));
  EXPECT_TRUE(fs::exists(fs::path(out) / "levelling.md"));
  // --report-only with a subset not run yet: the table says so and nothing trains.
  ASSERT_EQ(run_cli("study scaling --config " + f.lvsm_cfg + " --data " + f.data +
                        " --subsets 1 2 4 --steps 2 --steps-growth 2 --noise-std 0.05 --set training.eval_every=2 "
                        "--report-only --out " +
                        out,
                    &text),
            0)
      << text;
  EXPECT_NE(text.find("| lvsm | "), std::string::npos) << text;
  EXPECT_NE(text.find("(not run)"), std::string::npos) << text;
  EXPECT_FALSE(fs::exists(fs::path(out) / "runs/lvsm__2"));
  // --from-table: the same report from table.csv alone, in a folder without runs (a study run on another machine).
  const auto moved = (f.dir / "scaling_from_table").string();
  const auto report = "study scaling --config " + f.lvsm_cfg + " --data " + f.data +
                      " --subsets 1 2 4 --steps 2 --steps-growth 2 --noise-std 0.05 --report-only --from-table " + out +
                      "/table.csv --out ";
  ASSERT_EQ(run_cli(report + moved, &text), 0) << text;
  auto read_text = [](const fs::path& p) {
    std::ifstream in(p);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  EXPECT_EQ(read_text(fs::path(moved) / "table.md"), read_text(fs::path(out) / "table.md"));
  EXPECT_TRUE(fs::exists(fs::path(moved) / "psnr.png"));
  EXPECT_FALSE(fs::exists(fs::path(moved) / "runs"));
  EXPECT_NE(run_cli("study scaling --config " + f.lvsm_cfg + " --data " + f.data + " --subsets 1 --from-table " + out +
                        "/table.csv --out " + moved + "_trained",
                    &text),
            0);  // --from-table only redraws
  EXPECT_NE(text.find("--report-only"), std::string::npos) << text;
}
