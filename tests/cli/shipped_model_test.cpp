// The shipped demo model (models/demo.safetensors) still scores what its model card (models/demo.json) and the
// README say on a fixed slice of the built-in test split: a regression anywhere in data generation, preprocessing,
// the model or the metrics moves the PSNR by more than the 0.05 dB allowed here.
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
  const auto& slice = card.at("test_slice");
  const auto dir = test::temp_dir("shipped_model");
  std::string out;
  // Only the test split is needed; its scenes do not depend on how many train scenes there are.
  ASSERT_EQ(test::run_cli(fmt::format("make-dataset --config {} --train-scenes 1 --test-scenes {} --out {}",
                                      (source / card.at("config").get<std::string>()).string(),
                                      slice.at("scenes").get<int>(), (dir / "data").string()),
                          &out),
            0);
  ASSERT_EQ(test::run_cli(fmt::format("eval --checkpoint {} --data {} --split test --visualise 0 --out {}",
                                      (source / card.at("weights").get<std::string>()).string(),
                                      (dir / "data").string(), (dir / "eval").string()),
                          &out),
            0);
  const auto table = read_json(dir / "eval/metrics.json").at("table");
  const double psnr = table.at("model").at("psnr"), ssim = table.at("model").at("ssim");
  EXPECT_NEAR(psnr, slice.at("psnr").get<double>(), 0.05);
  EXPECT_NEAR(ssim, slice.at("ssim").get<double>(), 0.002);
  EXPECT_NEAR(table.at("copy_nearest").at("psnr").get<double>(), slice.at("copy_nearest_psnr").get<double>(), 0.05);
  // The README quotes the card's figure.
  const auto readme = read_text(source / "README.md");
  EXPECT_NE(readme.find(fmt::format("{:.2f} dB on the first {} test scenes", slice.at("psnr").get<double>(),
                                    slice.at("scenes").get<int>())),
            std::string::npos)
      << "README.md does not quote the model card's slice PSNR";
  if (!std::getenv("UPLVSM_KEEP_TEST_OUTPUT")) fs::remove_all(dir);
}
