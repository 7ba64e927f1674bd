// Tests of data/view_sampler: bounds, gap rule, the official skip boundary, distinct interior frames, determinism
// and the fallbacks.
#include "uplvsm/data/view_sampler.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <string>

#include "test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/loader.h"
#include "uplvsm/data/synthetic/room_scenes.h"

namespace uplvsm::data {
namespace {

TEST(ViewSampler, RespectsGapAndBounds) {
  std::mt19937_64 rng(123);
  std::set<int64_t> gaps;
  for (int rep = 0; rep < 2000; ++rep) {
    auto v = sample_training_views(300, 5, 25, 192, rng);
    ASSERT_EQ(v.size(), 5u);
    int64_t start = v[0], gap = v[1] - v[0];
    gaps.insert(gap);
    EXPECT_GE(gap, 25);
    EXPECT_LE(gap, 192);
    EXPECT_GE(start, 0);
    EXPECT_LE(v[1], 299);
    std::set<int64_t> interior(v.begin() + 2, v.end());
    EXPECT_EQ(interior.size(), 3u);  // distinct
    for (int64_t f : interior) {
      EXPECT_GT(f, start);
      EXPECT_LT(f, start + gap);
    }
  }
  EXPECT_EQ(*gaps.begin(), 25);  // both ends of [25, 192] reachable
  EXPECT_EQ(*gaps.rbegin(), 192);
}

TEST(ViewSampler, CurriculumGrowsTheLargestGapLinearly) {
  EXPECT_EQ(max_gap_at_step(4, 16, 0, 0), 16);  // off: the full range from the start
  EXPECT_EQ(max_gap_at_step(4, 16, 1200, 0), 4);
  EXPECT_EQ(max_gap_at_step(4, 16, 1200, 100), 5);  // 4 + 12 * 100 / 1200
  EXPECT_EQ(max_gap_at_step(4, 16, 1200, 599), 9);  // 4 + floor(5.99)
  EXPECT_EQ(max_gap_at_step(4, 16, 1200, 1199), 15);
  EXPECT_EQ(max_gap_at_step(4, 16, 1200, 1200), 16);
  EXPECT_EQ(max_gap_at_step(4, 16, 1200, 50000), 16);
  EXPECT_EQ(max_gap_at_step(7, 7, 1200, 3), 7);
  int previous = 0;
  for (int64_t step = 0; step <= 1300; ++step) {
    const int gap = max_gap_at_step(4, 16, 1200, step);
    EXPECT_GE(gap, previous);
    previous = gap;
  }
}

TEST(ViewSampler, GapCappedByScene) {
  std::mt19937_64 rng(5);
  for (int rep = 0; rep < 200; ++rep) {
    auto v = sample_training_views(40, 4, 25, 192, rng);  // upper bound min(39, 192)
    EXPECT_LE(v[1] - v[0], 39);
    EXPECT_GE(v[1] - v[0], 25);
    auto w = sample_training_views(10, 4, 25, 192, rng);  // min_gap above the bound: gap = 9
    EXPECT_EQ(w[0], 0);
    EXPECT_EQ(w[1], 9);
  }
}

TEST(ViewSampler, DeterministicForSeed) {
  std::mt19937_64 a(42), b(42), c(43);
  std::vector<std::vector<int64_t>> ra, rb, rc;
  for (int i = 0; i < 20; ++i) {
    ra.push_back(sample_training_views(100, 6, 10, 50, a));
    rb.push_back(sample_training_views(100, 6, 10, 50, b));
    rc.push_back(sample_training_views(100, 6, 10, 50, c));
  }
  EXPECT_EQ(ra, rb);
  EXPECT_NE(ra, rc);
}

TEST(ViewSampler, SmallScenesAndErrors) {
  std::mt19937_64 rng(1);
  EXPECT_THROW(sample_training_views(3, 4, 1, 10, rng), std::invalid_argument);
  // Gap 1 leaves no interior frame: the extra views repeat frames of the span.
  auto v = sample_training_views(2, 2, 25, 192, rng);
  EXPECT_EQ(v, (std::vector<int64_t>{0, 1}));
  auto w = sample_training_views(3, 3, 1, 1, rng);
  EXPECT_EQ(w[1] - w[0], 1);
  EXPECT_TRUE(w[2] == w[0] || w[2] == w[1]);
  EXPECT_EQ(sample_training_views(5, 1, 1, 1, rng).size(), 1u);
  EXPECT_FALSE(can_sample(3, 4, 1));
  for (int i = 0; i < 1000; ++i) {
    int64_t x = uniform_int(rng, -3, 3);
    EXPECT_GE(x, -3);
    EXPECT_LE(x, 3);
  }
}

// The official view_selector skips a scene when min(frames - 1, max_frame_dist) <= min_frame_dist: one of exactly
// min_frame_dist + 1 frames is skipped, one more frame makes it usable.
TEST(ViewSampler, ASceneOfMinFrameDistPlusOneFramesIsSkippedAsTheOfficial) {
  EXPECT_FALSE(can_sample(25, 4, 25));
  EXPECT_FALSE(can_sample(26, 4, 25));  // min_frame_dist + 1
  EXPECT_TRUE(can_sample(27, 4, 25));   // min_frame_dist + 2
  EXPECT_FALSE(can_sample(5, 4, 4));
  EXPECT_TRUE(can_sample(6, 4, 4));
  EXPECT_FALSE(can_sample(5, 6, 1));  // fewer frames than views
}

// The loader goes by that rule: at min_frame_dist 4 a scene of 5 frames is replaced by another (counted and logged)
// and never served, one of 6 frames is served.
TEST(ViewSampler, TheLoaderReplacesAndCountsAMinFrameDistPlusOneFrameScene) {
  const auto dir = test::temp_dir("view_sampler_boundary");
  std::filesystem::create_directories(dir / "train");
  RoomSceneOptions scene;
  scene.height = 24, scene.width = 32, scene.frames = 5;
  auto boundary = render_room_scene(1, scene);
  scene.frames = 6;
  auto usable = render_room_scene(2, scene);
  write_chunk((dir / "train/000000.torch").string(), {boundary, usable});
  ChunkDataset dataset(dir.string(), "train");
  LoaderOptions opt;
  opt.batch_size = 2, opt.num_views = 4, opt.num_input_views = 2, opt.num_target_views = 2;
  opt.min_frame_dist = 4, opt.max_frame_dist = 16;
  opt.preprocess = {32, 8, true};
  int64_t replaced = 0;
  std::set<std::string> served;
  for (int64_t step = 0; step < 4; ++step) {
    auto batch = make_training_batch(dataset, opt, step);
    replaced += batch.replaced_scenes;
    served.insert(batch.keys.begin(), batch.keys.end());
    for (const auto& frames : batch.frames) {  // 6 frames: the gap is 4 or 5
      EXPECT_GE(frames[1] - frames[0], 4);
      EXPECT_LE(frames[1] - frames[0], 5);
    }
  }
  EXPECT_EQ(served, std::set<std::string>{usable.key});
  EXPECT_GT(replaced, 0);
}

// Unordered views: distinct frames anywhere in the scene, every frame reachable in every slot, no gap rule.
TEST(ViewSampler, UnorderedViewsAreDistinctAndCoverEveryFrame) {
  std::mt19937_64 rng(7);
  std::vector<std::set<int64_t>> seen(5);
  for (int rep = 0; rep < 3000; ++rep) {
    auto v = sample_unordered_views(24, 5, rng);
    ASSERT_EQ(v.size(), 5u);
    EXPECT_EQ(std::set<int64_t>(v.begin(), v.end()).size(), 5u);
    for (size_t k = 0; k < v.size(); ++k) {
      EXPECT_GE(v[k], 0);
      EXPECT_LT(v[k], 24);
      seen[k].insert(v[k]);
    }
  }
  for (const auto& s : seen) EXPECT_EQ(s.size(), 24u);
  EXPECT_EQ(sample_unordered_views(5, 5, rng).size(), 5u);  // a scene of exactly num_views frames
  EXPECT_THROW(sample_unordered_views(4, 5, rng), std::invalid_argument);
}

TEST(ViewSampler, ViewSamplerSettingFollowsTheDataset) {
  DatasetInfo ordered, unordered;
  unordered.ordered_views = false;
  EXPECT_TRUE(uses_ordered_views("auto", ordered));
  EXPECT_FALSE(uses_ordered_views("auto", unordered));
  EXPECT_TRUE(uses_ordered_views("ordered", unordered));
  EXPECT_FALSE(uses_ordered_views("unordered", ordered));
  EXPECT_THROW(uses_ordered_views("random", ordered), std::invalid_argument);
}

}  // namespace
}  // namespace uplvsm::data
