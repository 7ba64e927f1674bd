// Tests of data/synthetic/object_scenes: determinism, cameras on a sphere looking at the object, depth/camera
// consistency (every surface point lies inside the unit sphere the object is scaled into), the gray backdrop, and
// the dataset writer: unordered views in dataset.json, evaluation entries of distinct random views.
#include "uplvsm/data/synthetic/object_scenes.h"
#include "uplvsm/data/synthetic/room_scenes.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <set>

#include "test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/dataset_info.h"
#include "uplvsm/data/eval_index.h"

namespace uplvsm::data {
namespace {

namespace fs = std::filesystem;

ObjectSceneOptions small_object_options() {
  ObjectSceneOptions opt;
  opt.height = 40;
  opt.width = 48;
  opt.views = 8;
  return opt;
}

TEST(ObjectScenes, DeterministicPerSeed) {
  auto opt = small_object_options();
  auto a = render_object(5, opt), b = render_object(5, opt), c = render_object(6, opt);
  EXPECT_EQ(a.scene.key, b.scene.key);
  EXPECT_TRUE(torch::equal(a.images, b.images));
  EXPECT_TRUE(torch::equal(a.scene.cameras, b.scene.cameras));
  EXPECT_NE(a.scene.key, c.scene.key);
  EXPECT_FALSE(torch::equal(a.c2w, c.c2w));
  EXPECT_EQ(a.scene.url, "builtin://object/5");
  EXPECT_EQ(static_cast<int>(a.scene.images.size()), 8);
}

TEST(ObjectScenes, CamerasCircleTheObjectAndSeeItInTheMiddle) {
  auto opt = small_object_options();
  auto r = render_object(17, opt);
  for (int64_t i = 0; i < 8; ++i) {
    auto c2w = r.c2w[i].to(torch::kFloat64);
    const double distance = c2w.index({torch::indexing::Slice(0, 3), 3}).norm().item<double>();
    EXPECT_GT(distance, 2.1);
    EXPECT_LT(distance, 2.7);
    // The origin in camera coordinates: in front, and projecting near the image centre (look-at jitter 0.1).
    auto w2c = torch::linalg_inv(c2w);
    auto o = w2c.index({torch::indexing::Slice(0, 3), 3});
    const double z = o[2].item<double>(), fx = r.fxfycxcy[i][0].item<double>();
    ASSERT_GT(z, 0);
    EXPECT_LT(std::abs(o[0].item<double>() / z * fx), 0.12 * fx);
    EXPECT_LT(std::abs(o[1].item<double>() / z * fx), 0.12 * fx);
  }
}

// Back-projecting every pixel that sees a surface lands inside the unit sphere; background pixels are the gray
// backdrop with infinite depth; the object covers a good part of the frame.
TEST(ObjectScenes, DepthAndCamerasAgreeWithTheObjectsBounds) {
  auto opt = small_object_options();
  auto r = render_object(23, opt);
  const int64_t h = opt.height, w = opt.width;
  auto vs = torch::arange(h, torch::kFloat64).add(0.5).view({h, 1}).expand({h, w});
  auto us = torch::arange(w, torch::kFloat64).add(0.5).view({1, w}).expand({h, w});
  for (int64_t i = 0; i < 8; ++i) {
    auto z = r.depth[i].to(torch::kFloat64);
    auto surface = torch::isfinite(z);
    const double covered = surface.to(torch::kFloat64).mean().item<double>();
    EXPECT_GT(covered, 0.1) << "view " << i;
    EXPECT_LT(covered, 0.95) << "view " << i;
    auto k = r.fxfycxcy[i].to(torch::kFloat64);
    auto zs = torch::where(surface, z, torch::zeros_like(z));
    auto cam = torch::stack({(us - k[2]) / k[0] * zs, (vs - k[3]) / k[1] * zs, zs}, -1).view({-1, 3});
    auto c2w = r.c2w[i].to(torch::kFloat64);
    auto world = cam.matmul(c2w.index({torch::indexing::Slice(0, 3), torch::indexing::Slice(0, 3)}).t()) +
                 c2w.index({torch::indexing::Slice(0, 3), 3});
    auto radius = world.norm(2, 1).masked_select(surface.view({-1}));
    EXPECT_LT(radius.max().item<double>(), 1.0 + 1e-3) << "view " << i;
    auto background = r.images[i].view({-1, 3}).index({(~surface).view({-1})});
    ASSERT_GT(background.size(0), 0);
    EXPECT_TRUE(torch::all((background.to(torch::kInt32) - 128).abs() <= 1).item<bool>());
  }
}

TEST(ObjectScenes, DatasetIsUnorderedWithRandomEvaluationViews) {
  const auto dir = test::temp_dir("object_dataset");
  auto opt = small_object_options();
  write_generated_dataset(dir.string(), 3, 4, 9, object_generator(opt), 2);
  const auto info = read_dataset_info(dir.string());
  EXPECT_EQ(info.generator, "objects");
  EXPECT_FALSE(info.ordered_views);
  ChunkDataset test_split(dir.string(), "test");
  EXPECT_FALSE(test_split.info().ordered_views);
  ASSERT_EQ(test_split.size(), 4);
  const auto entries = read_eval_index((dir / "evaluation_index.json").string());
  ASSERT_EQ(entries.size(), 4u);
  std::set<std::vector<int64_t>> contexts;
  for (const auto& e : entries) {
    ASSERT_EQ(e.context.size(), 2u);
    ASSERT_EQ(e.target.size(), 3u);
    std::set<int64_t> all(e.context.begin(), e.context.end());
    all.insert(e.target.begin(), e.target.end());
    EXPECT_EQ(all.size(), 5u);  // five distinct views
    EXPECT_LT(*all.rbegin(), 8);
    EXPECT_TRUE(std::is_sorted(e.target.begin(), e.target.end()));
    ASSERT_TRUE(e.overlap.has_value());
    EXPECT_GT(*e.overlap, 0.0);
    contexts.insert(e.context);
  }
  EXPECT_GT(contexts.size(), 1u);  // not one fixed pair of views
  // Rooms and objects of one dataset seed never share keys.
  RoomSceneOptions room;
  room.height = 24, room.width = 32, room.frames = 8;
  write_builtin_dataset((dir / "rooms").string(), 0, 4, 9, room, 2);
  ChunkDataset rooms((dir / "rooms").string(), "test");
  for (int64_t i = 0; i < 4; ++i) EXPECT_LT(test_split.find(rooms.key(i)), 0);
  EXPECT_TRUE(rooms.info().ordered_views);
  test::remove_tree(dir);
}

TEST(ObjectScenes, BadOptionsNameThemselves) {
  auto opt = small_object_options();
  opt.fov_degrees = 0;
  try {
    render_object(1, opt);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("fov 0"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace uplvsm::data
