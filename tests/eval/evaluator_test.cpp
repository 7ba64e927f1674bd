// Tests of eval/evaluator: a tiny random model evaluated on the fixture dataset (counts, skipped entries, written
// files, baseline numbers recomputed independently, training mode restored) and the aggregation rules.
#include "uplvsm/eval/evaluator.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "fake_scene.h"
#include "test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/eval/baselines.h"
#include "uplvsm/eval/metrics.h"
#include "uplvsm/io/image.h"
#include "uplvsm/model/model_factory.h"

namespace uplvsm::eval {
namespace {

namespace fs = std::filesystem;
const char* kKey = "20e408dd375292a1";

ModelConfig tiny_config() {
  ModelConfig c;
  c.image_size = 32;
  c.patch_size = 8;
  c.transformer.d = 32;
  c.transformer.d_head = 16;
  c.transformer.encoder_n_layer = 1;
  c.transformer.estimator_n_layer = 1;
  c.transformer.decoder_n_layer = 1;
  c.transformer.n_latent_vectors = 8;
  c.dinov2.embed_dim = 32;
  c.dinov2.depth = 1;
  c.dinov2.num_heads = 2;
  c.dinov2.pos_grid = 4;
  return c;
}

data::PreprocessOptions tiny_prep() {
  data::PreprocessOptions p;
  p.image_size = 32;
  p.patch_size = 8;
  return p;
}

std::string root() { return test::fixture("re10k_chunks/root"); }

size_t count_lines(const fs::path& path) {
  std::ifstream f(path);
  size_t n = 0;
  for (std::string line; std::getline(f, line);) ++n;
  return n;
}

// The baselines of `r`, recomputed from the views directly (targets 4, 8, 11 copy context frames 1, 13, 13).
void expect_baselines_recomputed(const data::ChunkDataset& dataset, const EvalSummary& s, const SceneResult& r) {
  auto views = dataset.load_views(dataset.find(kKey), {1, 13, 4, 8, 11}, tiny_prep());
  auto gt = views.images.narrow(0, 2, 3);
  auto copy = views.images.index_select(0, torch::tensor({0, 1, 1}, torch::kInt64));
  auto psnr_copy = psnr(copy, gt), ssim_mean = ssim(mean_colour(gt), gt);
  auto edges_copy = gradient_energy_ratio(copy, gt);
  for (int t = 0; t < 3; ++t) {
    EXPECT_NEAR(r.views[t].copy_nearest.psnr, psnr_copy[t].item<double>(), 1e-9);
    EXPECT_NEAR(r.views[t].mean_colour.ssim, ssim_mean[t].item<double>(), 1e-9);
    EXPECT_NEAR(r.views[t].copy_nearest.grad_ratio, edges_copy[t].item<double>(), 1e-12);
    EXPECT_EQ(r.views[t].mean_colour.grad_ratio, 0.0);  // a constant colour has no edges
    EXPECT_TRUE(r.views[t].model.grad_ratio > 0 && std::isfinite(r.views[t].model.grad_ratio))
        << r.views[t].model.grad_ratio;
  }
  EXPECT_DOUBLE_EQ(s.scores.copy_nearest.grad_ratio, r.copy_nearest.grad_ratio);
}

// metrics.json, the CSVs and the grid the evaluation wrote.
void expect_result_files(const fs::path& out, const EvalSummary& s, const SceneResult& r) {
  EXPECT_TRUE(fs::is_regular_file(out / "metrics.json"));
  EXPECT_EQ(count_lines(out / "per_scene.csv"), 2u);
  EXPECT_EQ(count_lines(out / "per_view.csv"), 4u);
  EXPECT_TRUE(fs::is_regular_file(out / "scenes" / (std::string(kKey) + ".png")));
  ASSERT_EQ(s.scene_grids.size(), 1u);
  std::ifstream f(out / "metrics.json");
  auto j = nlohmann::json::parse(f);
  EXPECT_EQ(j["scenes"], 1);
  EXPECT_EQ(j["views"], 3);
  EXPECT_EQ(j["skipped"]["null_entries"], 1);
  EXPECT_NEAR(j["table"]["model"]["psnr"].get<double>(), r.model.psnr, 1e-12);
  EXPECT_NEAR(j["table"]["model"]["grad_ratio"].get<double>(), r.model.grad_ratio, 1e-12);
  EXPECT_TRUE(j["buckets"].contains("large"));
}

TEST(Evaluator, TinyModelOnFixtureDataset) {
  UPLVSM_NEEDS_FIXTURES();
  torch::manual_seed(0);
  auto net = model::make_model(tiny_config());
  net->train();
  data::ChunkDataset dataset(root(), "test");
  const auto out = test::temp_dir("eval_tiny");
  EvalOptions opt;
  opt.out_dir = out.string();
  auto s = evaluate(net, dataset, tiny_prep(), opt);
  EXPECT_TRUE(net->is_training());  // mode restored

  EXPECT_EQ(s.scenes, 1);
  EXPECT_EQ(s.skipped_null, 1);
  EXPECT_EQ(s.skipped_missing, 0);
  EXPECT_EQ(s.skipped_bad_frames, 0);
  ASSERT_EQ(s.per_scene.size(), 1u);
  const auto& r = s.per_scene[0];
  EXPECT_EQ(r.key, kKey);
  EXPECT_EQ(r.context, (std::vector<int64_t>{1, 13}));
  EXPECT_EQ(r.bucket, "large");
  ASSERT_EQ(r.views.size(), 3u);
  EXPECT_EQ(r.views[1].frame, 8);
  for (const auto& v : r.views) {
    EXPECT_TRUE(std::isfinite(v.model.psnr) && v.model.psnr > 0 && v.model.psnr < 60) << v.model.psnr;
    EXPECT_TRUE(v.model.ssim > -1 && v.model.ssim <= 1);
  }
  EXPECT_NEAR(r.model.psnr, (r.views[0].model.psnr + r.views[1].model.psnr + r.views[2].model.psnr) / 3, 1e-12);
  EXPECT_DOUBLE_EQ(s.scores.model.psnr, r.model.psnr);
  EXPECT_DOUBLE_EQ(s.buckets.at("large").copy_nearest.ssim, r.copy_nearest.ssim);
  EXPECT_EQ(s.bucket_scenes.at("large"), 1);
  EXPECT_EQ(s.buckets.count("small"), 0u);
  for (const auto& v : r.views) EXPECT_FALSE(v.extrapolated);  // targets 4, 8, 11 lie between frames 1 and 13
  EXPECT_EQ(s.span_scenes.at("interpolation"), 1);
  EXPECT_EQ(s.spans.count("extrapolation"), 0u);

  expect_baselines_recomputed(dataset, s, r);
  expect_result_files(out, s, r);
  if (!std::getenv("UPLVSM_KEEP_TEST_OUTPUT")) test::remove_tree(out);
}

// A JPEG of a horizontal ramp (so a resize shows), h x w, brightness `level`.
torch::Tensor ramp_jpeg(int h, int w, int level) {
  auto img = (torch::arange(w, torch::kFloat32) * (200.0 / w) + level).clamp(0, 255).to(torch::kUInt8);
  auto bytes = io::encode_jpeg(img.view({1, w, 1}).expand({h, w, 3}).contiguous(), 95);
  return torch::from_blob(bytes.data(), {static_cast<int64_t>(bytes.size())}, torch::kUInt8).clone();
}

// A scene whose target frame 4 is 30x32 while the others are 24x32 (frame 0's size): the official dataset resizes
// every frame from its own size and crops it square, so the scene is scored, not dropped, and the frame counted.
TEST(Evaluator, ScoresAFrameOfAnotherSizeResizedAsTheOfficial) {
  const auto dir = test::temp_dir("eval_resized_frame");
  data::RawScene s;
  s.key = "abcd000000000001";
  s.url = "test://resized";
  s.timestamps = torch::arange(6, torch::kInt64);
  s.cameras = torch::zeros({6, 18});
  for (int i = 0; i < 6; ++i) {
    s.cameras[i].slice(0, 0, 4) = torch::tensor({0.8, 1.1, 0.5, 0.5});
    s.cameras[i][6] = s.cameras[i][11] = s.cameras[i][16] = 1;
    s.cameras[i][17] = -0.1 * i;
    s.images.push_back(ramp_jpeg(i == 4 ? 30 : 24, 32, 10 * i));
  }
  fs::create_directories(dir / "test");
  data::write_chunk((dir / "test" / "000000.torch").string(), {s});
  data::write_chunk_index((dir / "test").string(), {{s.key, "000000.torch"}});
  data::write_eval_index((dir / "index.json").string(), {{s.key, {0, 5}, {2, 3, 4}, std::nullopt}});
  torch::manual_seed(0);
  auto net = model::make_model(tiny_config());
  data::ChunkDataset dataset(dir.string(), "test");
  EvalOptions opt;
  opt.index_path = (dir / "index.json").string();
  opt.out_dir = (dir / "out").string();
  opt.num_visualised = 0;
  const auto summary = evaluate(net, dataset, tiny_prep(), opt);
  ASSERT_EQ(summary.scenes, 1);
  EXPECT_EQ(summary.skipped_bad_frames, 0);
  EXPECT_EQ(summary.resized_frames, 1);
  std::ifstream f(dir / "out" / "metrics.json");
  EXPECT_EQ(nlohmann::json::parse(f)["resized_frames"], 1);
  // The target as the official preprocesses it (LANCZOS to 32 rows from its own 30x32, then the square crop),
  // scored against its copy-nearest baseline (context frame 5).
  const auto& bytes = s.images[4];
  auto own = data::preprocess({io::decode_image(bytes.data_ptr<uint8_t>(), bytes.numel(), "frame 4")},
                              s.cameras.slice(0, 4, 5), tiny_prep());
  auto nearest = dataset.load_views(0, {5}, tiny_prep()).images;
  EXPECT_NEAR(summary.per_scene[0].views[2].copy_nearest.psnr, psnr(nearest, own.images)[0].item<double>(), 1e-9);
  test::remove_tree(dir);
}

TEST(Evaluator, LpipsOnlyWithItsWeights) {
  UPLVSM_NEEDS_FIXTURES();
  torch::manual_seed(0);
  auto net = model::make_model(tiny_config());
  data::ChunkDataset dataset(root(), "test");
  const auto out = test::temp_dir("eval_lpips");
  EvalOptions opt;
  opt.out_dir = out.string();
  opt.num_visualised = 0;
  auto without = evaluate(net, dataset, tiny_prep(), opt);
  ASSERT_EQ(without.scenes, 1);
  EXPECT_TRUE(std::isnan(without.per_scene[0].views[0].model.lpips));
  EXPECT_TRUE(std::isnan(without.scores.model.lpips));
  {
    std::ifstream f(out / "metrics.json");
    auto j = nlohmann::json::parse(f);
    EXPECT_FALSE(j["lpips"]["available"].get<bool>());
    EXPECT_TRUE(j["table"]["model"]["lpips"].is_null());  // never a number without the network
    std::ifstream csv(out / "per_view.csv");
    std::string header, row;
    std::getline(csv, header);
    std::getline(csv, row);
    EXPECT_NE(header.find(",lpips,"), std::string::npos);
    EXPECT_NE(row.find(",,"), std::string::npos) << row;  // empty LPIPS fields
  }

  opt.lpips =
      load_lpips(LpipsNet::Alex, test::fixture("lpips/alexnet_features.safetensors"), test::fixture("lpips/alex.pth"));
  opt.lpips_chunk = 2;  // 3 targets: chunks of 2 and 1 must join up in order
  auto with = evaluate(net, dataset, tiny_prep(), opt);
  const auto& r = with.per_scene[0];
  // Recompute LPIPS of the baselines directly (targets 4, 8, 11 copy context frames 1, 13, 13).
  auto views = dataset.load_views(dataset.find(kKey), {1, 13, 4, 8, 11}, tiny_prep());
  auto gt = views.images.narrow(0, 2, 3);
  auto copy = views.images.index_select(0, torch::tensor({0, 1, 1}, torch::kInt64));
  torch::NoGradGuard no_grad;
  auto lp_copy = opt.lpips->forward(copy, gt), lp_mean = opt.lpips->forward(mean_colour(gt), gt);
  double sum = 0;
  for (int t = 0; t < 3; ++t) {
    EXPECT_NEAR(r.views[t].copy_nearest.lpips, lp_copy[t].item<double>(), 1e-6);
    EXPECT_NEAR(r.views[t].mean_colour.lpips, lp_mean[t].item<double>(), 1e-6);
    EXPECT_TRUE(r.views[t].model.lpips >= 0 && std::isfinite(r.views[t].model.lpips));
    sum += r.views[t].model.lpips;
  }
  EXPECT_NEAR(with.scores.model.lpips, sum / 3, 1e-12);
  EXPECT_DOUBLE_EQ(with.scores.model.psnr, without.scores.model.psnr);
  std::ifstream f(out / "metrics.json");
  auto j = nlohmann::json::parse(f);
  EXPECT_TRUE(j["lpips"]["available"].get<bool>());
  EXPECT_EQ(j["lpips"]["net"], "alex");
  EXPECT_NEAR(j["buckets"]["large"]["copy_nearest"]["lpips"].get<double>(), lp_copy.mean().item<double>(), 1e-6);
  if (!std::getenv("UPLVSM_KEEP_TEST_OUTPUT")) test::remove_tree(out);
}

TEST(Evaluator, Bf16ForwardCloseToFp32) {
  UPLVSM_NEEDS_FIXTURES();
  torch::manual_seed(0);
  auto net = model::make_model(tiny_config());
  data::ChunkDataset dataset(root(), "test");
  EvalOptions opt;
  auto fp32 = evaluate(net, dataset, tiny_prep(), opt);
  opt.bf16 = true;
  auto bf16 = evaluate(net, dataset, tiny_prep(), opt);
  ASSERT_EQ(bf16.scenes, 1);
  EXPECT_NEAR(bf16.scores.model.psnr, fp32.scores.model.psnr, 0.2);
  EXPECT_NEAR(bf16.scores.model.ssim, fp32.scores.model.ssim, 0.01);
  // The baselines never pass through the model: identical.
  EXPECT_DOUBLE_EQ(bf16.scores.copy_nearest.ssim, fp32.scores.copy_nearest.ssim);
}

TEST(Evaluator, CountsMissingKeysAndCapsScenes) {
  UPLVSM_NEEDS_FIXTURES();
  const auto dir = test::temp_dir("eval_index");
  std::vector<data::EvalEntry> entries = {{kKey, {1, 13}, {4, 8, 11}, std::nullopt},
                                          {"ffffffffffffffff", {0, 2}, {1, 1, 1}, 0.2}};
  data::write_eval_index((dir / "index.json").string(), entries);
  torch::manual_seed(0);
  auto net = model::make_model(tiny_config());
  data::ChunkDataset dataset(root(), "test");
  EvalOptions opt;
  opt.index_path = (dir / "index.json").string();
  opt.batch_size = 1;
  auto s = evaluate(net, dataset, tiny_prep(), opt);  // no out_dir: nothing written
  EXPECT_EQ(s.scenes, 1);
  EXPECT_EQ(s.skipped_null, 0);
  EXPECT_EQ(s.skipped_missing, 1);
  EXPECT_EQ(s.per_scene[0].bucket, "none");
  EXPECT_TRUE(s.buckets.empty());
  EXPECT_TRUE(s.scene_grids.empty());
  EXPECT_TRUE(net->is_training());  // modules start in training mode; evaluate() restores it
  opt.max_scenes = 1;
  opt.index_path.clear();
  EXPECT_EQ(evaluate(net, dataset, tiny_prep(), opt).scenes, 1);
  test::remove_tree(dir);
}

TEST(Evaluator, RunsOnCuda) {
  UPLVSM_NEEDS_FIXTURES();
  if (!torch::cuda::is_available()) GTEST_SKIP() << "no CUDA device";
  torch::manual_seed(0);
  auto net = model::make_model(tiny_config());
  data::ChunkDataset dataset(root(), "test");
  EvalOptions opt;
  auto cpu = evaluate(net, dataset, tiny_prep(), opt);
  net->to(torch::kCUDA);
  opt.device = torch::kCUDA;
  auto gpu = evaluate(net, dataset, tiny_prep(), opt);
  ASSERT_EQ(gpu.scenes, 1);
  EXPECT_NEAR(gpu.scores.model.psnr, cpu.scores.model.psnr, 1e-3);
  EXPECT_NEAR(gpu.scores.copy_nearest.ssim, cpu.scores.copy_nearest.ssim, 1e-9);
}

using test::fake_scene;

TEST(Evaluator, AveragesPerSceneThenOverScenes) {
  // A scene with 1 target counts as much as a scene with 3 (community convention).
  auto s = summarise(
      {fake_scene("a", 0.7, {20}), fake_scene("b", 0.2, {30, 30, 30}), fake_scene("c", std::nullopt, {10, 20})});
  EXPECT_EQ(s.scenes, 3);
  EXPECT_DOUBLE_EQ(s.scores.model.psnr, (20.0 + 30.0 + 15.0) / 3);
  EXPECT_DOUBLE_EQ(s.scores.copy_nearest.psnr, (15.0 + 25.0 + 10.0) / 3);
  EXPECT_DOUBLE_EQ(s.scores.mean_colour.ssim, 0.01);
  EXPECT_DOUBLE_EQ(s.buckets.at("large").model.psnr, 20.0);
  EXPECT_DOUBLE_EQ(s.buckets.at("small").model.psnr, 30.0);
  EXPECT_EQ(s.buckets.count("none"), 0u);
  EXPECT_EQ(s.bucket_scenes.at("small"), 1);
  auto empty = summarise({});
  EXPECT_EQ(empty.scenes, 0);
  EXPECT_TRUE(std::isnan(empty.scores.model.psnr));
}

TEST(Evaluator, SceneResultsRoundTripThroughJsonForShardMerging) {
  auto r = fake_scene("k", 0.4, {21.5, 18.25});
  r.context = {0, 9};
  r.target = {3, 12};
  r.views[1].extrapolated = true;
  r.views[0].model.lpips = 0.125;  // the other LPIPS values stay NaN (unavailable) and must come back as NaN
  r.views[0].model.grad_ratio = 0.375, r.views[1].copy_nearest.grad_ratio = 0.875;
  auto back = scene_from_json(nlohmann::json::parse(scene_to_json(r).dump()));
  EXPECT_EQ(back.key, "k");
  EXPECT_EQ(back.context, r.context);
  EXPECT_EQ(back.target, r.target);
  EXPECT_EQ(back.bucket, r.bucket);
  ASSERT_TRUE(back.overlap);
  EXPECT_DOUBLE_EQ(*back.overlap, 0.4);
  ASSERT_EQ(back.views.size(), 2u);
  EXPECT_TRUE(back.views[1].extrapolated);
  EXPECT_DOUBLE_EQ(back.views[0].model.lpips, 0.125);
  EXPECT_TRUE(std::isnan(back.views[1].model.lpips));
  EXPECT_DOUBLE_EQ(back.model.psnr, r.model.psnr);
  EXPECT_DOUBLE_EQ(back.copy_nearest.ssim, r.copy_nearest.ssim);
  EXPECT_DOUBLE_EQ(back.views[0].model.grad_ratio, 0.375);
  EXPECT_DOUBLE_EQ(back.views[1].copy_nearest.grad_ratio, 0.875);
}

TEST(Evaluator, InterpolationAndExtrapolationSpans) {
  auto a = fake_scene("a", std::nullopt, {20, 10});  // frame 1 interpolated, frame 0 extrapolated
  a.views[1].extrapolated = true;
  auto b = fake_scene("b", std::nullopt, {30, 40});
  finalise_scene(a);
  auto s = summarise({a, b});
  EXPECT_EQ(s.span_scenes.at("interpolation"), 2);
  EXPECT_EQ(s.span_scenes.at("extrapolation"), 1);
  EXPECT_DOUBLE_EQ(s.spans.at("interpolation").model.psnr, (20.0 + 35.0) / 2);
  EXPECT_DOUBLE_EQ(s.spans.at("extrapolation").model.psnr, 10.0);
  EXPECT_DOUBLE_EQ(s.scores.model.psnr, (15.0 + 35.0) / 2);  // the full table is unchanged
}

TEST(Evaluator, ErrorHeatmapAndGrid) {
  auto gt = torch::zeros({2, 3, 16, 16});
  auto pred = gt.clone();
  pred[1].fill_(1.0);
  auto heat = error_heatmap(pred, gt);
  ASSERT_EQ(heat.sizes(), gt.sizes());
  EXPECT_LE(heat[0].max().item<float>(), 4.0f / 255 + 1e-6);         // no error: black end of the ramp
  EXPECT_NEAR(heat[1][0].mean().item<float>(), 252.0f / 255, 1e-5);  // saturated: pale yellow
  auto scene = fake_scene("k", std::nullopt, {20, 21});
  scene.context = {0, 5};
  auto grid = scene_grid(scene, torch::rand({2, 3, 16, 16}), pred, gt, gt);
  EXPECT_EQ(grid.scalar_type(), torch::kUInt8);
  EXPECT_EQ(grid.dim(), 3);
  EXPECT_GT(grid.size(1), 6 * 16);
}

}  // namespace
}  // namespace uplvsm::eval
