// study camera-paths-summary: runs' per-scene files read back as written, methods compared scene by scene (matched
// by key, whatever order each run wrote its scenes in), only over the scenes every run scored, and the plot's bins.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "test_util.h"
#include "uplvsm/study/camera_paths_summary.h"

using namespace uplvsm;

namespace {

// A run of one method on `scenes` (in that order): wobble w(scene) and two frames per scene, one inside (position
// 0.5, PSNR p) and one beyond (position 2, PSNR p - 3).
study::CameraPathsReport fake_run(const std::vector<std::string>& scenes, double (*w)(int), double p) {
  study::CameraPathsReport r;
  for (const auto& key : scenes) {
    const int i = std::stoi(key.substr(1));
    r.scene_scores.push_back({key, "camera control", p - 1.5, p, p - 3, 0.8, 0.6, w(i)});
    r.frames.push_back({key, "camera control", 0, 0.5, true, p, 0.8});
    r.frames.push_back({key, "camera control", 1, 2.0, false, p - 3, 0.6});
  }
  r.scenes = static_cast<int64_t>(scenes.size());
  return r;
}

const study::PathMetricStat& stat(const study::CameraPathsSummary& s, const std::string& metric, const std::string& a,
                                  const std::string& b) {
  for (const auto& x : s.stats)
    if (x.metric == metric && x.a == a && x.b == b) return x;
  throw std::runtime_error("no stat " + metric + " " + a + " " + b);
}

}  // namespace

TEST(CameraPathsSummary, ComparesMethodsSceneBySceneOverTheScenesAllScored) {
  const auto dir = test::temp_dir("camera_paths_summary");
  // The scenes' wobbles spread widely (1 to 16), and B wobbles exactly 0.1 more than A on every scene: paired, the
  // difference is 0.1 in every redraw; matched by position in the file instead, it would spread over the scenes.
  auto a = fake_run(
      {"s1", "s2", "s3", "s4", "s5", "s6"}, [](int i) { return double(i * i) / 2; }, 25);
  auto b = fake_run(
      {"s5", "s3", "s1", "s2", "s4"}, [](int i) { return double(i * i) / 2 + 0.1; }, 24);
  study::write_camera_paths(a, (dir / "a").string());
  study::write_camera_paths(b, (dir / "b").string());
  const auto back = study::read_camera_paths_scenes((dir / "b" / "camera_paths_scenes.csv").string());
  ASSERT_EQ(back.size(), 5u);
  EXPECT_EQ(back[0].scene, "s5");
  EXPECT_DOUBLE_EQ(back[0].wobble, 12.6);
  EXPECT_DOUBLE_EQ(back[0].psnr_beyond, 21);
  const auto s = study::summarise_camera_paths({study::parse_camera_paths_run("A=" + (dir / "a").string()),
                                                study::parse_camera_paths_run((dir / "b").string())});
  ASSERT_EQ(s.methods, (std::vector<std::string>{"A", "b"}));
  const auto& d = stat(s, "wobble", "A", "b");
  EXPECT_EQ(d.interval.scenes, 5);  // s6 only A scored: left out
  EXPECT_NEAR(d.interval.estimate, -0.1, 1e-9);
  EXPECT_NEAR(d.interval.lo, -0.1, 1e-9);
  EXPECT_NEAR(d.interval.hi, -0.1, 1e-9);
  const auto& mean_a = stat(s, "wobble", "A", "");
  EXPECT_NEAR(mean_a.interval.estimate, (0.5 + 2 + 4.5 + 8 + 12.5) / 5, 1e-9);
  EXPECT_LT(mean_a.interval.lo, mean_a.interval.estimate - 1);  // one method's mean: the scenes' spread
  EXPECT_NEAR(stat(s, "psnr_beyond", "A", "b").interval.estimate, 1.0, 1e-9);
  // The plot: one line per method, its PSNR per bin of position (0.5 and 2 here).
  ASSERT_EQ(s.psnr_position.size(), 2u);
  EXPECT_EQ(s.psnr_position[0].x, (std::vector<double>{0.5, 2.0}));
  EXPECT_EQ(s.psnr_position[1].y, (std::vector<double>{24, 21}));
  study::write_camera_paths_summary(s, (dir / "summary").string());
  EXPECT_TRUE(std::filesystem::exists(dir / "summary" / "psnr_position.png"));
  EXPECT_EQ(study::summary_method_name("A", "estimator reading the truth"), "A (estimator reading the truth)");
  // A label with a comma stays one field of differences.csv.
  const auto quoted = study::summarise_camera_paths({{"A, exact", (dir / "a").string()}, {"b", (dir / "b").string()}});
  study::write_camera_paths_summary(quoted, (dir / "quoted").string());
  std::ifstream csv(dir / "quoted" / "differences.csv");
  std::string line;
  std::getline(csv, line);
  ASSERT_TRUE(std::getline(csv, line));
  EXPECT_EQ(line.rfind("wobble,\"A, exact\",,", 0), 0u) << line;
  const auto error = test::error_of([&] { study::summarise_camera_paths({{"A", (dir / "nothing").string()}}); });
  EXPECT_NE(error.find("not a camera-paths file"), std::string::npos) << error;
}
