// Tests of eval/report: a report from a fake metrics.json, training log and scene grid contains index.html that
// links exactly the assets that exist, the training curve and the paper-style table.
#include "uplvsm/eval/report.h"
#include "uplvsm/eval/comparison_report.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "test_util.h"
#include "uplvsm/io/image.h"

namespace uplvsm::eval {
namespace {

namespace fs = std::filesystem;

void write(const fs::path& path, const std::string& text) {
  std::ofstream f(path);
  f << text;
}

std::string read(const fs::path& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

nlohmann::json fake_metrics() {
  nlohmann::json row = {{"model", {{"psnr", 25.5}, {"ssim", 0.8}, {"grad_ratio", 0.25}}},
                        {"copy_nearest", {{"psnr", 14.25}, {"ssim", 0.4}, {"grad_ratio", 1.1}}},
                        {"mean_colour", {{"psnr", 12.0}, {"ssim", 0.05}, {"grad_ratio", 0.0}}}};
  return {{"scenes", 3},
          {"table", row},
          {"buckets", {{"large", row}, {"small", row}}},
          {"bucket_scenes", {{"large", 2}, {"small", 1}}},
          {"seconds", 12.5}};
}

TEST(Report, WritesIndexWithExistingAssets) {
  const auto src = test::temp_dir("report_src");
  const auto out = test::temp_dir("report_out");
  write(src / "metrics.json", fake_metrics().dump());
  write(src / "per_scene.csv", "key,psnr\na,1\n");
  std::string log;
  for (int step = 10; step <= 50; step += 10)
    log += fmt::format("{{\"step\":{},\"loss\":{},\"psnr\":{},\"lr\":0.001}}\n", step, 1.0 / step, 10 + step / 10.0);
  log += "{\"step\": 60, \"loss\"";  // a line cut off by a crash
  write(src / "train.jsonl", log);
  io::write_png((src / "tiny.png").string(), torch::full({4, 6, 3}, 128, torch::kUInt8));

  ReportInputs in;
  in.title = "Test <run>";
  in.config = {{"name", "tiny"}, {"model", {{"d", 32}}}};
  in.metrics_json = (src / "metrics.json").string();
  in.train_log_jsonl = (src / "train.jsonl").string();
  in.scene_grids = {(src / "tiny.png").string(), (src / "absent.png").string()};
  in.videos = {{"interpolation", "", (src / "absent.gif").string()}};
  in.runtime_info = "torch 1.13.1";
  in.train_seconds = 3725;
  const auto index = write_report(out.string(), in);

  EXPECT_EQ(fs::path(index), out / "index.html");
  for (const char* file : {"index.html", "training_curve.png", "metrics.json", "per_scene.csv", "scenes/tiny.png",
                           "config.json", "train_log.jsonl"})
    EXPECT_TRUE(fs::is_regular_file(out / file)) << file;
  EXPECT_FALSE(fs::exists(out / "video_0.gif"));
  const auto html = read(index);
  EXPECT_NE(html.find("src=\"training_curve.png\""), std::string::npos);
  EXPECT_NE(html.find("src=\"scenes/tiny.png\""), std::string::npos);
  EXPECT_EQ(html.find("src=\"scenes/absent.png\""), std::string::npos);
  EXPECT_EQ(html.find("video_0.gif"), std::string::npos);
  EXPECT_EQ(html.find("<video"), std::string::npos);
  EXPECT_NE(html.find("Test &lt;run&gt;"), std::string::npos);
  EXPECT_NE(html.find("UP-LVSM (ours)"), std::string::npos);
  EXPECT_NE(html.find("Large overlap (2 scenes)"), std::string::npos);
  EXPECT_NE(html.find("Medium overlap (0 scenes)"), std::string::npos);
  EXPECT_NE(html.find("Full (3 scenes)"), std::string::npos);
  EXPECT_NE(html.find("<b>25.50</b>"), std::string::npos);
  EXPECT_NE(html.find("<b>1.10</b>"), std::string::npos);  // edges: the nearest to 1 is best, not the highest
  EXPECT_EQ(html.find("<b>0.25</b>"), std::string::npos);
  EXPECT_NE(html.find("14.25"), std::string::npos);
  EXPECT_NE(html.find("1:02:05"), std::string::npos);     // training time
  EXPECT_NE(html.find("absent.png"), std::string::npos);  // listed as missing
  auto curve = io::read_image((out / "training_curve.png").string());
  EXPECT_EQ(curve.size(1), 800);
  EXPECT_EQ(read_train_log(in.train_log_jsonl).size(), 5u);
  if (std::getenv("UPLVSM_KEEP_TEST_OUTPUT")) return;
  test::remove_tree(src);
  test::remove_tree(out);
}

TEST(Report, VideoAndPlainTable) {
  const auto src = test::temp_dir("report_src2");
  const auto out = test::temp_dir("report_out2");
  auto m = fake_metrics();
  m.erase("buckets");
  write(src / "metrics.json", m.dump());
  write(src / "v.mp4", "not really a video");
  ReportInputs in;
  in.metrics_json = (src / "metrics.json").string();
  in.videos = {{"latent interpolation", (src / "v.mp4").string(), ""}, {"orbit", (src / "v.mp4").string(), ""}};
  const auto html = read(write_report(out.string(), in));
  EXPECT_TRUE(fs::is_regular_file(out / "video_0.mp4"));
  EXPECT_TRUE(fs::is_regular_file(out / "video_1.mp4"));
  EXPECT_NE(html.find("<video src=\"video_0.mp4\" controls loop autoplay muted"), std::string::npos);
  EXPECT_NE(html.find("<figcaption>orbit</figcaption>"), std::string::npos);
  EXPECT_EQ(html.find("Large"), std::string::npos);
  EXPECT_NE(html.find("Test set (3 scenes)"), std::string::npos);
  EXPECT_FALSE(fs::exists(out / "training_curve.png"));
  test::remove_tree(src);
  test::remove_tree(out);
}

TEST(Report, LpipsColumnOnlyWhenAvailable) {
  auto m = fake_metrics();
  EXPECT_EQ(results_table_html(m).find("LPIPS&darr;"), std::string::npos);
  EXPECT_NE(results_table_html(m).find("LPIPS unavailable"), std::string::npos);
  m["lpips"] = {{"available", true}, {"net", "vgg"}};
  m["table"]["model"]["lpips"] = 0.25;
  m["table"]["copy_nearest"]["lpips"] = 0.125;  // lower is better: this one is bold
  m["table"]["mean_colour"]["lpips"] = 0.5;
  const auto html = results_table_html(m);
  EXPECT_NE(html.find("LPIPS&darr;"), std::string::npos);
  EXPECT_NE(html.find("<b>0.125</b>"), std::string::npos) << html;
  EXPECT_NE(html.find("<td>0.500</td>"), std::string::npos);
  EXPECT_NE(html.find("colspan=\"4\""), std::string::npos);  // PSNR, SSIM, LPIPS, edges
  EXPECT_EQ(html.find("LPIPS unavailable"), std::string::npos);
  EXPECT_EQ(html.find("Extrapolation"), std::string::npos);
  m["spans"] = {{"interpolation", m["table"]}, {"extrapolation", m["table"]}};
  m["span_scenes"] = {{"interpolation", 3}, {"extrapolation", 2}};
  EXPECT_NE(results_table_html(m).find("Extrapolation (2 scenes)"), std::string::npos);
}

TEST(Report, ModelRowIsNamedByTheEvaluatedVariant) {
  auto m = fake_metrics();
  EXPECT_NE(results_table_html(m).find("<td>UP-LVSM (ours)</td>"), std::string::npos);  // older files: no variant
  m["variant"] = "lvsm";
  const auto posed = results_table_html(m);
  EXPECT_NE(posed.find("<td>LVSM, cameras known</td>"), std::string::npos);
  EXPECT_EQ(posed.find("UP-LVSM"), std::string::npos);
  m["variant"] = "ptlvsm";
  EXPECT_NE(results_table_html(m).find("<td>PT-LVSM, target camera known</td>"), std::string::npos);
  m["variant"] = "uplvsm";
  EXPECT_NE(results_table_html(m).find("<td>UP-LVSM (ours)</td>"), std::string::npos);
}

TEST(Report, RejectsMalformedMetrics) {
  const auto src = test::temp_dir("report_bad");
  write(src / "metrics.json", "{\"scenes\": 1");
  ReportInputs in;
  in.metrics_json = (src / "metrics.json").string();
  EXPECT_THROW(write_report((src / "out").string(), in), std::runtime_error);
  write(src / "metrics.json", "{\"scenes\": 1}");
  EXPECT_THROW(write_report((src / "out").string(), in), std::runtime_error);
  test::remove_tree(src);
}

TEST(Report, HtmlEscape) { EXPECT_EQ(html_escape("a<b & \"c\"'"), "a&lt;b &amp; &quot;c&quot;&#39;"); }

TEST(Report, ComparisonPageShowsModelsSideBySide) {
  const auto src = test::temp_dir("report_cmp_src");
  const auto out = test::temp_dir("report_cmp_out");
  write(src / "metrics.json", fake_metrics().dump());
  write(src / "v.mp4", "not really a video");
  io::write_png((src / "grid.png").string(), torch::full({10, 150, 3}, 128, torch::kUInt8));
  ReportInputs a;
  a.metrics_json = (src / "metrics.json").string();
  a.scene_grids = {(src / "grid.png").string()};
  a.videos = {{"orbit", (src / "v.mp4").string(), "", 96}};
  ReportInputs b;
  b.metrics_json = a.metrics_json;
  const auto html =
      read(write_comparison_report(out.string(), "Demo <both>", {{"Shipped", "at 96x96", a}, {"tiny", "", b}}));
  for (const char* file : {"index.html", "model_0/index.html", "model_0/video_0.mp4", "model_0/scenes/grid.png",
                           "model_1/index.html", "model_1/metrics.json"})
    EXPECT_TRUE(fs::is_regular_file(out / file)) << file;
  EXPECT_NE(html.find("Demo &lt;both&gt;"), std::string::npos);
  EXPECT_LT(html.find("<h2>Shipped</h2>"), html.find("<h2>tiny</h2>"));
  EXPECT_NE(html.find("at 96x96"), std::string::npos);
  // Small renders are upscaled by integer factors (96 px video -> 6x = 576 px; 150 px grid -> 4x = 600 px).
  EXPECT_NE(html.find("src=\"model_0/video_0.mp4\" width=\"576\""), std::string::npos) << html;
  EXPECT_NE(html.find("src=\"model_0/scenes/grid.png\" width=\"600\""), std::string::npos) << html;
  EXPECT_NE(html.find("image-rendering:pixelated"), std::string::npos);
  // Narrow columns show the whole test set only, not the overlap buckets.
  EXPECT_EQ(html.find("Large overlap"), std::string::npos);
  EXPECT_NE(html.find("Test set (3 scenes)"), std::string::npos);
  test::remove_tree(src);
  test::remove_tree(out);
}

TEST(Report, PixelWidthIsAnIntegerMultipleOfTheNativeWidth) {
  EXPECT_EQ(pixel_width_attr(96, 600), " width=\"576\"");
  EXPECT_EQ(pixel_width_attr(700, 600), " width=\"700\"");  // never shrunk below its own size
  EXPECT_EQ(pixel_width_attr(0, 600), "");
}

}  // namespace
}  // namespace uplvsm::eval
