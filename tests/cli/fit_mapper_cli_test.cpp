// Camera control for the authors' released model without fine-tuning it: `fit-mapper` on the official-format
// checkpoint fixture (any UP-LVSM the authors' code writes), then the mapper beside it drives `render --mapper` (an
// orbit from dataset scenes and from two photos) and `eval --mapper --jitter`; a mapper of another model and a
// dataset too short for the asked frame distances are refused with what to do.
#include <gtest/gtest.h>

#include <fstream>

#include <nlohmann/json.hpp>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/io/image.h"

namespace fs = std::filesystem;
using namespace uplvsm;

namespace {

std::string fit_args(const std::string& checkpoint, const fs::path& out, const std::string& extra = "") {
  return "fit-mapper --checkpoint " + checkpoint + " --data " + test::micro_dataset() + " --out " + out.string() +
         " --targets 2 --min-frame-dist 2 --max-frame-dist 6 --batch 2 --views 16 " + extra;
}

}  // namespace

TEST(FitMapperCli, TheAuthorsCheckpointGetsAMapperBesideItThatRendersAnOrbitAndScores) {
  UPLVSM_NEEDS_FIXTURES();
  const auto dir = test::temp_dir("cli_fit_mapper");
  const auto checkpoint = test::fixture("official_uplvsm/checkpoint.pt");
  const auto bytes_before = fs::file_size(checkpoint);
  const auto mapper = dir / "mapper.safetensors";
  std::string out;
  ASSERT_EQ(test::run_cli(fit_args(checkpoint, mapper, "--steps 20 --hidden 8"), &out), 0) << out;
  EXPECT_NE(out.find("fitted a mlp pose mapper to "), std::string::npos) << out;
  EXPECT_NE(out.find(" views of 6 scenes"), std::string::npos) << out;
  EXPECT_TRUE(fs::exists(mapper));
  EXPECT_EQ(fs::file_size(checkpoint), bytes_before);  // the model file is not touched

  const auto render = "render --checkpoint " + checkpoint + " --mapper " + mapper.string() + " --data " +
                      test::micro_dataset() + " --scenes 1 --frames 3 --trajectory orbit --out " + (dir / "v").string();
  ASSERT_EQ(test::run_cli(render, &out), 0) << out;
  auto listing = nlohmann::json::parse(std::ifstream(dir / "v" / "videos.json"));
  ASSERT_EQ(listing.size(), 1u);

  // Two photos without cameras: an orbit around the first (render does not place the second; serve does).
  data::ChunkDataset rooms(test::micro_dataset(), "test");
  auto views = rooms.load_views(0, {0, 5}, test::micro_prep());
  std::vector<std::string> photos;
  for (int i = 0; i < 2; ++i) {
    photos.push_back((dir / ("photo_" + std::to_string(i) + ".png")).string());
    io::write_png(photos.back(), (views.images[i].permute({1, 2, 0}) * 255).round().to(torch::kUInt8).contiguous());
  }
  ASSERT_EQ(
      test::run_cli("render --checkpoint " + checkpoint + " --mapper " + mapper.string() + " --images " + photos[0] +
                        " " + photos[1] + " --frames 3 --trajectory orbit --out " + (dir / "photos").string(),
                    &out),
      0)
      << out;
  EXPECT_TRUE(fs::exists(dir / "photos" / "video.mp4")) << out;

  const auto eval = "eval --checkpoint " + checkpoint + " --mapper " + mapper.string() + " --data " +
                    test::micro_dataset() + " --jitter --visualise 0 --out " + (dir / "e").string();
  ASSERT_EQ(test::run_cli(eval, &out), 0) << out;
  auto metrics = nlohmann::json::parse(std::ifstream(dir / "e" / "metrics.json"));
  EXPECT_EQ(metrics["target_poses"], "mapper") << metrics.dump();
  auto jitter = nlohmann::json::parse(std::ifstream(dir / "e" / "jitter.json"));
  EXPECT_EQ(jitter["scenes"], 2);
  EXPECT_GT(jitter["jitter"].get<double>(), 0.0);
  EXPECT_GT(jitter["renders"].get<int64_t>(), 2 * 5);  // two paths of at least two frames cut into four steps
}

TEST(FitMapperCli, AMapperOfAnotherModelAndTooShortScenesAreRefused) {
  UPLVSM_NEEDS_FIXTURES();
  const auto dir = test::temp_dir("cli_fit_mapper_errors");
  const auto mapper = dir / "mapper.safetensors";
  std::string out;
  ASSERT_EQ(test::run_cli(fit_args(test::fixture("official_uplvsm/checkpoint.pt"), mapper, "--kind linear"), &out), 0)
      << out;
  const auto demo = std::string(UPLVSM_SOURCE_DIR) + "/models/demo.safetensors";
  EXPECT_NE(test::run_cli("eval --checkpoint " + demo + " --mapper " + mapper.string() + " --data " +
                              test::micro_dataset() + " --out " + (dir / "e").string(),
                          &out),
            0);
  EXPECT_NE(out.find("fitted to another model"), std::string::npos) << out;
  EXPECT_NE(out.find("uplvsm fit-mapper"), std::string::npos) << out;
  // The paper's frame distances (25 to 192 frames apart) need longer scenes than these 12 frames.
  EXPECT_NE(test::run_cli("fit-mapper --checkpoint " + test::fixture("official_uplvsm/checkpoint.pt") + " --data " +
                              test::micro_dataset() + " --out " + (dir / "m2.safetensors").string(),
                          &out),
            0);
  EXPECT_NE(out.find("--min-frame-dist"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir / "m2.safetensors"));
}
