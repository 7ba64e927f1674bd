// Tests of eval/result_files: metrics.json's content (NaN as null, views and spans counted, `extra` merged) and the
// per-scene / per-view CSVs (quoted keys, unavailable LPIPS as empty fields, six decimals).
#include "uplvsm/eval/result_files.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "fake_scene.h"
#include "test_util.h"

namespace uplvsm::eval {
namespace {

namespace fs = std::filesystem;

using test::fake_scene;

std::vector<std::string> lines_of(const fs::path& path) {
  std::ifstream f(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(f, line);) lines.push_back(line);
  return lines;
}

TEST(ResultFiles, SummaryJsonCountsViewsAndWritesNaNAsNull) {
  auto s = summarise(
      {fake_scene("a", 0.7, {20}), fake_scene("b", 0.2, {30, 30, 30}), fake_scene("c", std::nullopt, {10, 20})});
  EXPECT_EQ(summary_to_json(s)["views"], 6);
  // Without scenes the table is NaN, which JSON carries as null.
  EXPECT_TRUE(nlohmann::json::parse(summary_to_json(summarise({})).dump())["table"]["model"]["psnr"].is_null());
}

// The typed summary writes the tables metrics.json has always had, byte for byte: predictor -> score (names sorted),
// a bucket's or span's table alike, NaN as null, doubles in nlohmann's shortest form.
TEST(ResultFiles, SummaryTablesKeepTheirJsonBytes) {
  const auto j = summary_to_json(summarise({fake_scene("a", 0.7, {20}), fake_scene("b", 0.2, {30})}));
  const auto table = [](const std::string& model, const std::string& copy) {
    return "{\"copy_nearest\":{\"grad_ratio\":0.0,\"lpips\":null,\"psnr\":" + copy +
           ",\"ssim\":0.25},\"mean_colour\":{\"grad_ratio\":0.0,\"lpips\":null,\"psnr\":10.0,\"ssim\":0.01},"
           "\"model\":{\"grad_ratio\":0.0,\"lpips\":null,\"psnr\":" +
           model + ",\"ssim\":0.5}}";
  };
  EXPECT_EQ(j["table"].dump(), table("25.0", "20.0"));
  EXPECT_EQ(j["buckets"].dump(), "{\"large\":" + table("20.0", "15.0") + ",\"small\":" + table("30.0", "25.0") + "}");
  EXPECT_EQ(j["bucket_scenes"].dump(), "{\"large\":1,\"small\":1}");
  EXPECT_EQ(j["spans"].dump(), "{\"interpolation\":" + table("25.0", "20.0") + "}");
  EXPECT_EQ(summary_to_json(summarise({}))["buckets"].dump(), "{}");
}

TEST(ResultFiles, SummaryJsonHasSpans) {
  auto a = fake_scene("a", std::nullopt, {20, 10});
  a.views[1].extrapolated = true;
  finalise_scene(a);
  auto j = summary_to_json(summarise({a, fake_scene("b", std::nullopt, {30, 40})}));
  EXPECT_EQ(j["span_scenes"]["extrapolation"], 1);
  EXPECT_EQ(j["span_scenes"]["interpolation"], 2);
}

TEST(ResultFiles, WritesMetricsJsonAndBothCsvs) {
  const auto out = test::temp_dir("result_files") / "nested";  // created by write_results
  auto a = fake_scene("a,b", 0.7, {20});
  a.views[0].extrapolated = true;
  write_results(out.string(), summarise({a, fake_scene("c", std::nullopt, {10, 30})}),
                {{"checkpoint", "model.safetensors"}});
  std::ifstream f(out / "metrics.json");
  const auto j = nlohmann::json::parse(f);
  EXPECT_EQ(j["scenes"], 2);
  EXPECT_EQ(j["checkpoint"], "model.safetensors");
  const auto scenes = lines_of(out / "per_scene.csv");
  ASSERT_EQ(scenes.size(), 3u);
  EXPECT_EQ(scenes[0],
            "key,bucket,overlap,num_targets,psnr,ssim,lpips,grad_ratio,psnr_copy,ssim_copy,lpips_copy,"
            "grad_ratio_copy,psnr_mean,ssim_mean,lpips_mean,grad_ratio_mean");
  EXPECT_EQ(scenes[1],
            "\"a,b\",large,0.7,1,20.000000,0.500000,,0.000000,15.000000,0.250000,,0.000000,10.000000,"
            "0.010000,,0.000000");
  EXPECT_EQ(scenes[2].substr(0, 22), "c,none,,2,20.000000,0.");
  const auto views = lines_of(out / "per_view.csv");
  ASSERT_EQ(views.size(), 4u);
  EXPECT_EQ(views[0].substr(0, 28), "key,frame,extrapolated,psnr,");
  EXPECT_EQ(views[1].substr(0, 20), "\"a,b\",0,1,20.000000,");
  EXPECT_EQ(views[3].substr(0, 16), "c,1,0,30.000000,");
  if (!std::getenv("UPLVSM_KEEP_TEST_OUTPUT")) test::remove_tree(out.parent_path());
}

}  // namespace
}  // namespace uplvsm::eval
