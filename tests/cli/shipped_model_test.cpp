// The shipped demo models (models/demo*.safetensors) still score what their card (models/demo.json) and docs/demo.md
// say on a fixed slice of the built-in test split: a regression anywhere in data generation, preprocessing, the model
// or the metrics moves the PSNR by more than the 0.05 dB allowed here.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "test_util.h"

using namespace uplvsm;
namespace fs = std::filesystem;

namespace {
nlohmann::json read_json(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path.string());
  return nlohmann::json::parse(in);
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}
}  // namespace

TEST(ShippedModel, ReproducesItsPsnrOnTheFixedTestSlice) {
  const fs::path source(UPLVSM_SOURCE_DIR);
  const auto card = read_json(source / "models/demo.json");
  const auto demo_page = read_text(source / "docs/demo.md");
  const auto dir = test::temp_dir("shipped_model");
  const auto& models = card.at("models");
  ASSERT_FALSE(models.empty());
  const int scenes = models.at(0).at("test_slice").at("scenes").get<int>();
  std::string out;
  // Only the test split is needed: a scene depends on (seed, split, index) alone, not on how many scenes there are.
  ASSERT_EQ(test::run_cli(
                fmt::format("make-dataset --config {} --train-scenes 1 --test-scenes {} --out {}",
                            (source / card.at("config").get<std::string>()).string(), scenes, (dir / "data").string()),
                &out),
            0)
      << out;
  for (const auto& model : models) {
    const auto& slice = model.at("test_slice");
    const auto weights = model.at("weights").get<std::string>();
    SCOPED_TRACE(weights);
    ASSERT_EQ(slice.at("scenes").get<int>(), scenes);
    const auto eval_dir = dir / fs::path(weights).stem();
    ASSERT_EQ(test::run_cli(fmt::format("eval --checkpoint {} --data {} --split test --target-poses {} --visualise 0 "
                                        "--out {}",
                                        (source / weights).string(), (dir / "data").string(),
                                        model.at("target_poses").get<std::string>(), eval_dir.string()),
                            &out),
              0)
        << out;
    const auto table = read_json(eval_dir / "metrics.json").at("table");
    const double psnr = table.at("model").at("psnr"), ssim = table.at("model").at("ssim");
    EXPECT_NEAR(psnr, slice.at("psnr").get<double>(), 0.05);
    EXPECT_NEAR(ssim, slice.at("ssim").get<double>(), 0.002);
    EXPECT_NEAR(table.at("model").at("grad_ratio").get<double>(), slice.at("grad_ratio").get<double>(), 0.003);
    EXPECT_NEAR(table.at("copy_nearest").at("psnr").get<double>(), slice.at("copy_nearest_psnr").get<double>(), 0.05);
    // docs/demo.md quotes the card's figures (the slice, and the full test split).
    EXPECT_NE(
        demo_page.find(fmt::format("{:.2f} dB on the first {} test scenes", slice.at("psnr").get<double>(), scenes)),
        std::string::npos)
        << "docs/demo.md does not quote the model card's slice PSNR of " << weights;
    EXPECT_NE(demo_page.find(fmt::format("{:.2f}", model.at("test").at("psnr").get<double>())), std::string::npos)
        << "docs/demo.md does not quote the model card's test PSNR of " << weights;
  }
  if (!std::getenv("UPLVSM_KEEP_TEST_OUTPUT")) test::remove_tree(dir);
}
