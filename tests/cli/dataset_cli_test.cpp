// `uplvsm dataset subset` + `uplvsm train --subset`, training's refusal of placeholder cameras (unposed.json), and
// `uplvsm dataset import` of phone photos (EXIF orientation and focal length).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "io/exif_jpeg.h"
#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"

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
  EXPECT_NE(out.find(" 2 scenes of "), std::string::npos) << out;  // the run plan's data line

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
  EXPECT_NE(out.find("unordered: any distinct frames"), std::string::npos) << out;  // the run plan's views line
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

// Phone photos held upright (stored sideways, EXIF orientation 6), one with a 1 mm FocalLengthIn35mmFilm: the
// import says what it turned and which tag it refused, and the chunk holds upright frames.
TEST(DatasetCli, ImportTurnsPhotosUprightAndReportsAnImplausibleFocalLength) {
  const auto dir = test::temp_dir("cli_import_exif");
  fs::create_directories(dir / "phone");
  const auto stored = test::stored_for_orientation_6(test::red_over_blue(80, 48));
  for (const auto& [name, focal] : {std::pair<std::string, int>{"a.jpg", 26}, {"b.jpg", 1}}) {
    const auto bytes = test::jpeg_with_exif(stored, 6, focal);
    io::write_file_atomic((dir / "phone" / name).string(), bytes.data(), bytes.size());
  }
  std::string out;
  ASSERT_EQ(
      test::run_cli("dataset import --images " + (dir / "phone").string() + " --out " + (dir / "data").string(), &out),
      0);
  EXPECT_NE(out.find("warning: 1 image(s) have an implausible EXIF focal length, e.g. " +
                     (dir / "phone/b.jpg").string() + ": EXIF FocalLengthIn35mmFilm = 1 mm rejected"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("2 frames (2 turned upright by their EXIF orientation), intrinsics exif+default-fov"),
            std::string::npos)
      << out;
  const auto scenes = data::read_chunk((dir / "data/test/phone.torch").string());
  ASSERT_EQ(scenes.size(), 1u);
  for (const auto& frame : scenes[0].images) {
    const auto pixels = io::decode_image(frame.data_ptr<uint8_t>(), frame.numel(), "frame");
    EXPECT_EQ(pixels.sizes(), torch::IntArrayRef({80, 48, 3}));
    EXPECT_TRUE(test::is_red_over_blue(pixels));
  }
  test::remove_tree(dir);
}
