// Tests of data/synthetic/room_scenes: determinism, camera conventions, geometric consistency of images, depth and
// cameras (reprojection), and the dataset writer read back through ChunkDataset and the evaluation index.
#include "uplvsm/data/synthetic/room_scenes.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <regex>
#include <set>

#include "test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/io/atomic_file.h"

namespace uplvsm::data {
namespace {

namespace fs = std::filesystem;

RoomSceneOptions small_options() {
  RoomSceneOptions opt;
  opt.height = 36;
  opt.width = 64;
  opt.frames = 8;
  return opt;
}

double mean_abs(const torch::Tensor& a, const torch::Tensor& b) {
  return (a.to(torch::kFloat64) - b.to(torch::kFloat64)).abs().mean().item<double>();
}

TEST(RoomScenes, DeterministicPerSeed) {
  auto opt = small_options();
  RawScene a = render_room_scene(11, opt), b = render_room_scene(11, opt), c = render_room_scene(12, opt);
  EXPECT_EQ(a.key, b.key);
  EXPECT_TRUE(torch::equal(a.cameras, b.cameras));
  for (size_t i = 0; i < a.images.size(); ++i) EXPECT_TRUE(torch::equal(a.images[i], b.images[i]));
  EXPECT_NE(a.key, c.key);
  EXPECT_FALSE(torch::equal(a.cameras, c.cameras));
  EXPECT_TRUE(std::regex_match(a.key, std::regex("[0-9a-f]{16}")));
  EXPECT_EQ(a.url, "builtin://room/11");
  EXPECT_TRUE(torch::equal(a.timestamps, torch::arange(8, torch::kInt64) * 100000));
}

// texture_scale changes only the surface patterns: same cameras and geometry, larger (smoother) patterns.
TEST(RoomScenes, TextureScaleKeepsGeometryAndEnlargesPatterns) {
  auto opt = small_options();
  RoomRender base = render_room(21, opt);
  opt.texture_scale = 3.0;
  RoomRender coarse = render_room(21, opt);
  EXPECT_TRUE(torch::equal(base.scene.cameras, coarse.scene.cameras));
  EXPECT_TRUE(torch::equal(base.depth, coarse.depth));
  EXPECT_FALSE(torch::equal(base.images, coarse.images));
  // Mean absolute difference of horizontal neighbours: detail of the texture patterns.
  auto detail = [](const torch::Tensor& img) {
    auto f = img.to(torch::kFloat64);
    return (f.slice(2, 1) - f.slice(2, 0, -1)).abs().mean().item<double>();
  };
  EXPECT_LT(detail(coarse.images), detail(base.images));
  opt.texture_scale = 0;
  EXPECT_THROW(render_room(21, opt), std::runtime_error);
}

TEST(RoomScenes, CameraConventions) {
  RoomSceneOptions opt;  // 72x128, 32 frames
  for (uint64_t seed : {1, 2, 3}) {
    RoomRender r = render_room(seed, opt);
    ASSERT_EQ(r.scene.cameras.sizes(), (std::vector<int64_t>{32, 18}));
    auto k = cameras_to_fxfycxcy(r.scene.cameras, 128, 72);
    EXPECT_LT(test::max_abs_diff(k.select(1, 2), torch::full({32}, 64.0)), 1e-4);
    EXPECT_LT(test::max_abs_diff(k.select(1, 3), torch::full({32}, 36.0)), 1e-4);
    EXPECT_LT(test::max_abs_diff(k.select(1, 0), k.select(1, 1)), 1e-3);
    double fov = 2 * std::atan(64.0 / k[0][0].item<double>()) * 180 / M_PI;
    EXPECT_GE(fov, 55.0 - 1e-6);
    EXPECT_LE(fov, 75.0 + 1e-6);
    // Stored w2c inverts to the rendering c2w; rotations are orthonormal.
    auto c2w = cameras_to_c2w(r.scene.cameras, r.scene.key);
    EXPECT_LT(test::max_abs_diff(c2w, r.c2w), 1e-5);
    auto rot = c2w.slice(1, 0, 3).slice(2, 0, 3);
    EXPECT_LT(test::max_abs_diff(rot.matmul(rot.transpose(1, 2)), torch::eye(3).expand({32, 3, 3})), 1e-5);
    // Walkthrough: the camera moves mostly along its viewing direction, and the image's "down" points to the floor.
    for (int i = 0; i + 1 < 32; ++i) {
      auto step = c2w[i + 1].slice(0, 0, 3).select(1, 3) - c2w[i].slice(0, 0, 3).select(1, 3);
      auto forward = c2w[i].slice(0, 0, 3).select(1, 2);
      double len = step.norm().item<double>();
      EXPECT_GT(len, 0.01);
      EXPECT_GT(step.dot(forward).item<double>(), 0.7 * len) << "seed " << seed << " frame " << i;
    }
    EXPECT_GT(c2w[0][1][1].item<float>(), 0.9f);  // camera y (down) is close to world +y (down)
  }
}

// Warping frame a into frame b with a's depth lands on the same colours (visible, unoccluded pixels).
TEST(RoomScenes, DepthReprojectionIsConsistent) {
  RoomSceneOptions opt;
  opt.frames = 8;
  for (uint64_t seed : {5, 6}) {
    RoomRender r = render_room(seed, opt);
    const int a = 0, b = 4, h = opt.height, w = opt.width;
    auto k = r.fxfycxcy.to(torch::kFloat64);
    auto vs = torch::arange(h, torch::kFloat64).add(0.5).view({h, 1}).expand({h, w});
    auto us = torch::arange(w, torch::kFloat64).add(0.5).view({1, w}).expand({h, w});
    auto z = r.depth[a].to(torch::kFloat64);
    auto pts = torch::stack({(us - k[a][2]) / k[a][0] * z, (vs - k[a][3]) / k[a][1] * z, z, torch::ones_like(z)}, -1);
    auto a2b = torch::linalg_inv(r.c2w[b].to(torch::kFloat64)).matmul(r.c2w[a].to(torch::kFloat64));
    auto q = pts.view({-1, 4}).matmul(a2b.t());
    auto qz = q.select(1, 2);
    auto pu = (q.select(1, 0) / qz * k[b][0] + k[b][2]).floor().to(torch::kLong);
    auto pv = (q.select(1, 1) / qz * k[b][1] + k[b][3]).floor().to(torch::kLong);
    auto inside = (qz > 0) & (pu >= 0) & (pu < w) & (pv >= 0) & (pv < h);
    auto idx = inside.nonzero().squeeze(1);
    ASSERT_GT(idx.numel(), h * w / 4);
    // Visible in b: b's depth at the landing pixel agrees with the warped depth.
    auto flat = (pv.index_select(0, idx) * w + pu.index_select(0, idx));
    auto depth_b = r.depth[b].reshape({-1}).index_select(0, flat).to(torch::kFloat64);
    auto visible = ((depth_b - qz.index_select(0, idx)).abs() < 0.05 * depth_b);
    auto src = idx.index_select(0, visible.nonzero().squeeze(1));
    auto dst = flat.index_select(0, visible.nonzero().squeeze(1));
    ASSERT_GT(src.numel(), h * w / 5);
    auto col_a = r.images[a].reshape({-1, 3}).index_select(0, src);
    auto col_b = r.images[b].reshape({-1, 3}).index_select(0, dst);
    double warped = mean_abs(col_a, col_b);
    double unwarped = mean_abs(r.images[a], r.images[b]);
    EXPECT_LT(warped, 6.0) << "seed " << seed;
    EXPECT_LT(warped, 0.5 * unwarped) << "seed " << seed;
  }
}

TEST(RoomScenes, ConsecutiveFramesSimilarDistantDiffer) {
  RoomSceneOptions opt;
  RoomRender r = render_room(9, opt);
  double near = mean_abs(r.images[10], r.images[11]);
  double far = mean_abs(r.images[0], r.images[31]);
  EXPECT_LT(near, far);
  EXPECT_GT(far, 10.0);
  // Images are not flat: a learnable but non-trivial texture.
  EXPECT_GT(r.images[0].to(torch::kFloat32).std().item<float>(), 10.0f);
  EXPECT_NEAR(context_overlap(r, 3, 3), 1.0, 1e-9);
  double o = context_overlap(r, 0, 16);
  EXPECT_GT(o, 0.0);
  EXPECT_LT(o, 1.0);
}

TEST(RoomScenes, WriteBuiltinDatasetReadsBack) {
  auto dir = test::temp_dir("room_dataset");
  auto opt = small_options();
  write_builtin_dataset((dir / "a").string(), 3, 2, 77, opt, /*scenes_per_chunk=*/2);
  write_builtin_dataset((dir / "b").string(), 3, 2, 77, opt, 2);
  // Same seed, identical bytes.
  for (const char* f : {"train/000000.torch", "train/000001.torch", "train/index.json", "test/000000.torch",
                        "test/index.json", "evaluation_index.json"}) {
    ASSERT_TRUE(fs::exists(dir / "a" / f)) << f;
    EXPECT_EQ(io::read_file((dir / "a" / f).string()), io::read_file((dir / "b" / f).string())) << f;
  }
  ChunkDataset train((dir / "a").string(), "train"), test_split((dir / "a").string(), "test");
  ASSERT_EQ(train.size(), 3);
  ASSERT_EQ(test_split.size(), 2);
  std::set<std::string> keys;
  for (int64_t i = 0; i < 3; ++i) keys.insert(train.key(i));
  for (int64_t i = 0; i < 2; ++i) {
    EXPECT_EQ(keys.count(test_split.key(i)), 0u);  // train and test disjoint
    EXPECT_EQ(test_split.num_frames(i), 8);
  }
  PreprocessOptions pre;
  pre.image_size = 28;
  SceneViews v = train.load_views(0, {0, 7, 3}, pre);
  EXPECT_EQ(v.images.sizes(), (std::vector<int64_t>{3, 3, 28, 28}));
  int64_t nulls = 0;
  auto eval = read_eval_index((dir / "a" / "evaluation_index.json").string(), &nulls);
  ASSERT_EQ(eval.size(), 2u);
  for (const auto& e : eval) {
    EXPECT_GE(test_split.find(e.key), 0);
    EXPECT_EQ(e.context[1] - e.context[0], 4);
    ASSERT_EQ(e.target.size(), 3u);
    EXPECT_TRUE(std::is_sorted(e.target.begin(), e.target.end()));
    for (int64_t t : e.target) {
      EXPECT_GT(t, e.context[0]);
      EXPECT_LT(t, e.context[1]);
    }
    ASSERT_TRUE(e.overlap.has_value());
    EXPECT_GT(*e.overlap, 0.0);
    EXPECT_LE(*e.overlap, 1.0);
  }
  // A different dataset seed gives different scenes.
  write_builtin_dataset((dir / "c").string(), 1, 0, 78, opt, 2);
  ChunkDataset other((dir / "c").string(), "train");
  EXPECT_EQ(keys.count(other.key(0)), 0u);
  test::remove_tree(dir);
}

// Developer benchmark: the default built-in dataset (400 train + 100 test scenes, 72x128, 32 frames) written to
// $UPLVSM_ROOM_BENCH_DIR, with the wall time printed. Skipped unless that variable is set.
TEST(RoomScenesBench, WriteDefaultDataset) {
  const char* out = std::getenv("UPLVSM_ROOM_BENCH_DIR");
  if (!out) GTEST_SKIP() << "set UPLVSM_ROOM_BENCH_DIR to time write_builtin_dataset(400 train, 100 test)";
  auto t0 = std::chrono::steady_clock::now();
  write_builtin_dataset(out, 400, 100, 2024, RoomSceneOptions{});
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("write_builtin_dataset(400 train + 100 test, 72x128 x 32 frames): %.2f s with %d threads\n", seconds,
              at::get_num_threads());
  EXPECT_EQ(ChunkDataset(out, "train").size(), 400);
  EXPECT_EQ(ChunkDataset(out, "test").size(), 100);
}

TEST(RoomScenes, TheRoomRendersAtAnyCameraAsAtItsOwnFrames) {
  auto opt = small_options();
  auto scene = render_room(21, opt);
  // Its own cameras give its own pixels, bit for bit; a camera half way between two frames, a picture near both.
  auto again = render_room_at(21, opt, scene.c2w.to(torch::kFloat64));
  EXPECT_TRUE(torch::equal(again.images, scene.images));
  auto between = scene.c2w.narrow(0, 2, 1).to(torch::kFloat64).clone();
  between.select(0, 0).narrow(0, 0, 3).select(1, 3).copy_((scene.c2w[2] + scene.c2w[3]).narrow(0, 0, 3).select(1, 3) /
                                                          2);
  auto mid = render_room_at(21, opt, between).images[0];
  EXPECT_LT(mean_abs(mid, scene.images[2]), mean_abs(scene.images[5], scene.images[2]));
  EXPECT_GT(mean_abs(mid, scene.images[2]), 0.0);
  // Another room's seed is another room.
  EXPECT_GT(mean_abs(render_room_at(22, opt, scene.c2w).images, scene.images), 5.0);
  EXPECT_EQ(room_seed_from_url(scene.scene.url), std::optional<uint64_t>(21));
  EXPECT_FALSE(room_seed_from_url("builtin://object/21").has_value());
  EXPECT_FALSE(room_seed_from_url("builtin://room/2x").has_value());
}

}  // namespace
}  // namespace uplvsm::data
