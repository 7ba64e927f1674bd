// `uplvsm eval --target-poses auto` evaluates a model with the protocol it was trained with; `--refine-poses` refines
// the estimator's poses and says so in metrics.json, and is refused for poses that do not come from the estimator;
// `--pose-noise-std` scores a posed model with the official evaluation's pose noise, recorded and printed.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "test_util.h"
#include "train/train_test_util.h"

using namespace uplvsm;
namespace fs = std::filesystem;

namespace {
nlohmann::json metrics(const fs::path& out) {
  std::ifstream in(out / "metrics.json");
  return nlohmann::json::parse(in);
}
std::string evaluated_target_poses(const fs::path& out) { return metrics(out).at("target_poses").get<std::string>(); }
}  // namespace

// A UP-LVSM trained from dataset cameras (the "SfM target poses" ablation) never trained its estimator: `auto`
// must score it from dataset cameras, and an explicit protocol still wins.
TEST(EvalCli, AutoTargetPosesFollowTheTrainingConfig) {
  const auto dir = test::temp_dir("cli_eval_auto");
  std::ifstream in(std::string(UPLVSM_SOURCE_DIR) + "/configs/tiny.json");
  auto config = nlohmann::json::parse(in);
  config["training"]["target_poses"] = "dataset";
  std::ofstream((dir / "sfm.json").string()) << config.dump();
  std::string out;
  ASSERT_EQ(test::run_cli("train --config " + (dir / "sfm.json").string() + " --data " + test::micro_dataset() +
                              " --run " + (dir / "run").string() + " --steps 1",
                          &out),
            0)
      << out;
  const std::string eval = "eval --checkpoint " + (dir / "run").string() + " --data " + test::micro_dataset();
  ASSERT_EQ(test::run_cli(eval + " --out " + (dir / "auto").string(), &out), 0) << out;
  EXPECT_EQ(evaluated_target_poses(dir / "auto"), "dataset");
  ASSERT_EQ(test::run_cli(eval + " --target-poses estimator --out " + (dir / "est").string(), &out), 0) << out;
  EXPECT_EQ(evaluated_target_poses(dir / "est"), "estimator");

  ASSERT_EQ(test::run_cli(eval + " --target-poses estimator --refine-poses 2 --refine-lr 0.05 --out " +
                              (dir / "refined").string(),
                          &out),
            0)
      << out;
  EXPECT_EQ(metrics(dir / "refined").at("pose_refinement"), (nlohmann::json{{"steps", 2}, {"lr", 0.05}}));
  EXPECT_FALSE(metrics(dir / "est").contains("pose_refinement"));
  EXPECT_NE(test::run_cli(eval + " --refine-poses 2 --out " + (dir / "refused").string(), &out), 0);
  EXPECT_NE(out.find("pose refinement refines the latent poses"), std::string::npos) << out;
  test::remove_tree(dir);
}

// `--pose-noise-std S --seed N` reaches LVSM's cameras (its scores move, the same seed repeats them), metrics.json and
// the printout say which cameras were scored; a negative or non-finite S is refused naming the flag.
TEST(EvalCli, PoseNoiseStdScoresAPosedModelWithNoisyCameras) {
  const auto dir = test::temp_dir("cli_eval_pose_noise");
  std::string out;
  ASSERT_EQ(test::run_cli("train --config " + std::string(UPLVSM_SOURCE_DIR) + "/configs/tiny_lvsm.json --data " +
                              test::micro_dataset() + " --run " + (dir / "run").string() + " --steps 1",
                          &out),
            0)
      << out;
  const std::string eval = "eval --checkpoint " + (dir / "run").string() + " --data " + test::micro_dataset();
  ASSERT_EQ(test::run_cli(eval + " --out " + (dir / "clean").string(), &out), 0) << out;
  EXPECT_NE(out.find("pose noise: none, clean test cameras"), std::string::npos) << out;
  EXPECT_EQ(metrics(dir / "clean").at("pose_noise").at("std"), 0.0);
  for (const char* run : {"noisy", "again"}) {
    ASSERT_EQ(test::run_cli(eval + " --pose-noise-std 0.05 --seed 3 --out " + (dir / run).string(), &out), 0) << out;
    EXPECT_NE(out.find("pose noise sd 0.05 (seed 3): the input and target dataset cameras"), std::string::npos) << out;
  }
  const auto noisy = metrics(dir / "noisy");
  EXPECT_EQ(noisy.at("pose_noise").at("std"), 0.05);
  EXPECT_EQ(noisy.at("pose_noise").at("seed"), 3);
  EXPECT_TRUE(noisy.at("pose_noise").at("reaches_model").get<bool>());
  EXPECT_NE(noisy.at("table").at("model").at("psnr"), metrics(dir / "clean").at("table").at("model").at("psnr"));
  EXPECT_EQ(noisy.at("table").at("model").at("psnr"), metrics(dir / "again").at("table").at("model").at("psnr"));
  for (const char* bad : {"=-0.1", " nan", " inf"}) {
    EXPECT_NE(test::run_cli(eval + " --pose-noise-std" + bad + " --out " + (dir / "bad").string(), &out), 0) << bad;
    EXPECT_NE(out.find("--pose-noise-std: expected a finite number >= 0"), std::string::npos) << out;
  }
  test::remove_tree(dir);
}

// `eval --trajectory dolly` scores camera control along a path past the inputs against the ray-traced truth of the
// rooms the checkpoint's dataset config makes: <out>/trajectory/camera_paths.json holds the frames inside and beyond
// the inputs' span for each method. A UP-LVSM without a mapper is refused before it is evaluated; a model whose
// dataset config makes other rooms (here a posed LVSM, which needs no mapper) is refused, not scored.
TEST(EvalCli, TrajectoryScoresCameraControlAlongAPathAgainstTheTruth) {
  const auto dir = test::temp_dir("cli_eval_trajectory");
  auto micro_config = [](const std::string& name) {
    std::ifstream in(std::string(UPLVSM_SOURCE_DIR) + "/configs/" + name);
    auto config = nlohmann::json::parse(in);
    // The rooms of test::micro_dataset().
    config["dataset"]["render_height"] = 36, config["dataset"]["render_width"] = 64;
    config["dataset"]["frames_per_scene"] = 12, config["dataset"]["frame_spacing"] = 1.0;
    config["dataset"]["eval_gap"] = 0;
    return config;
  };
  std::ofstream((dir / "micro.json").string()) << micro_config("tiny.json").dump();
  auto other = micro_config("tiny_lvsm.json");
  other["dataset"]["frames_per_scene"] = 10;  // another path through other objects: other rooms
  std::ofstream((dir / "other.json").string()) << other.dump();
  std::string out;
  for (const char* name : {"micro", "other"})
    ASSERT_EQ(test::run_cli("train --config " + (dir / (std::string(name) + ".json")).string() + " --data " +
                                test::micro_dataset() + " --run " + (dir / name).string() + " --steps 1",
                            &out),
              0)
        << out;
  const std::string eval = " --data " + test::micro_dataset() +
                           " --max-scenes 1 --trajectory dolly --trajectory-frames 6 --visualise 0 --out ";
  EXPECT_NE(test::run_cli("eval --checkpoint " + (dir / "micro").string() + eval + (dir / "none").string(), &out), 0);
  EXPECT_NE(out.find("has no camera mapper: give --mapper FILE"), std::string::npos) << out;
  EXPECT_EQ(out.find("PSNR"), std::string::npos) << out;  // refused before the evaluation
  const auto mapper = (dir / "linear.safetensors").string();
  ASSERT_EQ(test::run_cli("fit-mapper --checkpoint " + (dir / "micro").string() + " --data " + test::micro_dataset() +
                              " --kind linear --targets 2 --min-frame-dist 2 --max-frame-dist 6 --batch 2 --views 16 "
                              "--out " +
                              mapper,
                          &out),
            0)
      << out;
  ASSERT_EQ(
      test::run_cli(
          "eval --checkpoint " + (dir / "micro").string() + " --mapper " + mapper + eval + (dir / "e").string(), &out),
      0)
      << out;
  EXPECT_NE(out.find("dolly path"), std::string::npos) << out;
  std::ifstream paths(dir / "e" / "trajectory" / "camera_paths.json");
  ASSERT_TRUE(paths.good());
  const auto report = nlohmann::json::parse(paths);
  EXPECT_EQ(report.at("scenes"), 1);
  EXPECT_EQ(report.at("frames_inside").get<int64_t>() + report.at("frames_beyond").get<int64_t>(), 6);
  EXPECT_GT(report.at("frames_beyond").get<int64_t>(), 0);  // the dolly leaves the inputs' span
  ASSERT_FALSE(report.at("methods").empty()) << report.dump();
  for (const auto& m : report.at("methods")) EXPECT_TRUE(m.at("psnr_beyond").is_number()) << m.dump();
  EXPECT_NE(test::run_cli("eval --checkpoint " + (dir / "other").string() + eval + (dir / "o").string(), &out), 0);
  EXPECT_NE(out.find("not reproduced by the room options"), std::string::npos) << out;
  // Given the rooms' own config, the same model is scored.
  EXPECT_EQ(test::run_cli("eval --checkpoint " + (dir / "other").string() + eval + (dir / "o").string() +
                              " --room-config " + (dir / "micro.json").string(),
                          &out),
            0)
      << out;
  test::remove_tree(dir);
}
