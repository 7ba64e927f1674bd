// `uplvsm dataset subset` + `uplvsm train --subset`, and training's refusal of placeholder cameras (unposed.json).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/data/chunk_dataset.h"

using namespace uplvsm;
namespace fs = std::filesystem;

namespace {
const std::string kConfigs = std::string(UPLVSM_SOURCE_DIR) + "/configs/";
}

TEST(DatasetCli, SubsetManifestRestrictsTraining) {
  const auto dir = test::temp_dir("cli_subset");
  const auto manifest = (dir / "two.json").string();
  std::string out;
  ASSERT_EQ(test::run_cli("dataset subset --data " + test::micro_dataset() + " --scenes 2 --out " + manifest, &out), 0);
  EXPECT_NE(out.find("2 scenes"), std::string::npos) << out;
  std::ifstream in(manifest);
  const auto j = nlohmann::json::parse(in);
  data::ChunkDataset ds(test::micro_dataset(), "train");
  EXPECT_EQ(j.at("scenes"), nlohmann::json({ds.key(0), ds.key(1)}));

  ASSERT_EQ(test::run_cli("train --config " + kConfigs + "tiny.json --data " + test::micro_dataset() + " --run " +
                              (dir / "run").string() + " --steps 2 --subset " + manifest,
                          &out),
            0);
  EXPECT_NE(out.find("on 2 scenes"), std::string::npos) << out;

  // An official name the dataset is too small for: a clear error with both counts.
  EXPECT_NE(
      test::run_cli("dataset subset --data " + test::micro_dataset() + " --subset medium --out " + manifest, &out), 0);
  EXPECT_NE(out.find("needs 304 chunks"), std::string::npos) << out;
}

TEST(DatasetCli, PosedTrainingRefusesScenesWithoutPoses) {
  const auto dir = test::temp_dir("cli_unposed");
  fs::copy(test::micro_dataset(), dir / "data", fs::copy_options::recursive);
  data::ChunkDataset ds((dir / "data").string(), "train");
  std::ofstream(dir / "data/train/unposed.json") << "[\"" << ds.key(3) << "\"]";
  std::string out;
  EXPECT_NE(test::run_cli("train --config " + kConfigs + "tiny_ptlvsm.json --data " + (dir / "data").string() +
                              " --run " + (dir / "pt").string() + " --steps 1",
                          &out),
            0);
  EXPECT_NE(out.find(ds.key(3)), std::string::npos) << out;
  EXPECT_NE(out.find("unposed.json"), std::string::npos) << out;
  // UP-LVSM never reads the cameras: the same data trains.
  EXPECT_EQ(test::run_cli("train --config " + kConfigs + "tiny.json --data " + (dir / "data").string() + " --run " +
                              (dir / "up").string() + " --steps 1",
                          &out),
            0);
}

// `make-dataset --kind objects`: unordered views. Training draws any distinct frames (the tiny config's
// min_frame_dist 4 would not matter), and eval's copy-nearest baseline picks inputs by viewing direction.
TEST(DatasetCli, ObjectsTrainAndEvaluateWithUnorderedViews) {
  const auto dir = test::temp_dir("cli_objects");
  const auto data = (dir / "objects").string();
  std::string out;
  ASSERT_EQ(test::run_cli("make-dataset --config " + kConfigs +
                              "tiny.json --kind objects --train-scenes 4 "
                              "--test-scenes 2 --out " +
                              data,
                          &out),
            0)
      << out;
  std::ifstream info(dir / "objects/dataset.json");
  EXPECT_EQ(nlohmann::json::parse(info).at("view_order"), "unordered");
  ASSERT_EQ(test::run_cli("train --config " + kConfigs + "tiny.json --data " + data + " --run " +
                              (dir / "run").string() + " --steps 2",
                          &out),
            0)
      << out;
  EXPECT_NE(out.find("views: unordered"), std::string::npos) << out;
  ASSERT_EQ(test::run_cli("eval --checkpoint " + (dir / "run").string() + " --data " + data + " --split test --out " +
                              (dir / "eval").string() + " --visualise 0",
                          &out),
            0)
      << out;
  std::ifstream metrics(dir / "eval/metrics.json");
  const auto j = nlohmann::json::parse(metrics);
  EXPECT_EQ(j.at("scenes"), 2);
  EXPECT_GT(j.at("table").at("copy_nearest").at("psnr").get<double>(), 5.0);
  test::remove_tree(dir);
}
