#include <gtest/gtest.h>

#include <set>

#include "train/train_test_util.h"
#include "uplvsm/data/loader.h"

using namespace uplvsm;

namespace {
data::LoaderOptions micro_options() {
  data::LoaderOptions o;
  o.batch_size = 2;
  o.num_views = 4;
  o.num_input_views = 2;
  o.num_target_views = 2;
  o.min_frame_dist = 2;
  o.max_frame_dist = 6;
  o.preprocess = {32, 8, true};
  return o;
}
}  // namespace

TEST(Loader, BatchIsAPureFunctionOfTheStep) {
  data::ChunkDataset dataset(test::micro_dataset(), "train");
  auto a = data::make_training_batch(dataset, micro_options(), 5), b = data::make_training_batch(dataset, micro_options(), 5);
  EXPECT_EQ(a.keys, b.keys);
  EXPECT_EQ(a.frames, b.frames);
  EXPECT_TRUE(torch::equal(a.images, b.images));
  EXPECT_TRUE(torch::equal(a.c2w, b.c2w));
}

TEST(Loader, MaxScenesTrainsOnTheFirstScenesOnly) {
  data::ChunkDataset dataset(test::micro_dataset(), "train");
  ASSERT_GT(dataset.size(), 2);
  auto opt = micro_options();
  opt.max_scenes = 2;
  std::set<std::string> seen;
  for (int64_t step = 0; step < 12; ++step)
    for (const auto& k : data::make_training_batch(dataset, opt, step).keys) seen.insert(k);
  EXPECT_EQ(seen, (std::set<std::string>{dataset.key(0), dataset.key(1)}));
}

TEST(Loader, PoseNoisePerturbsOnlyTheCameras) {
  data::ChunkDataset dataset(test::micro_dataset(), "train");
  auto clean = data::make_training_batch(dataset, micro_options(), 3);
  auto opt = micro_options();
  opt.pose_noise_variance = 0.01;
  auto noisy = data::make_training_batch(dataset, opt, 3);
  // Same scenes, views and pixels: the noise has its own random stream.
  EXPECT_EQ(noisy.keys, clean.keys);
  EXPECT_EQ(noisy.frames, clean.frames);
  EXPECT_TRUE(torch::equal(noisy.images, clean.images));
  EXPECT_TRUE(torch::equal(noisy.target_index, clean.target_index));
  EXPECT_TRUE(torch::equal(noisy.c2w, data::make_training_batch(dataset, opt, 3).c2w));  // reproducible (resume)
  EXPECT_FALSE(torch::equal(noisy.c2w, data::make_training_batch(dataset, opt, 4).c2w.narrow(0, 0, 2)));
  // Translations move by about sigma = 0.1 per coordinate; rotations stay rotations.
  using torch::indexing::Slice;
  auto dt = (noisy.c2w - clean.c2w).index({Slice(), Slice(), Slice(0, 3), 3});
  const double spread = dt.std().item<double>();
  EXPECT_GT(spread, 0.04);
  EXPECT_LT(spread, 0.25);
  auto R = noisy.c2w.index({Slice(), Slice(), Slice(0, 3), Slice(0, 3)}).to(torch::kFloat64);
  EXPECT_TRUE(torch::allclose(R.matmul(R.transpose(-1, -2)), torch::eye(3, torch::kFloat64).expand_as(R), 1e-5, 1e-5));
  EXPECT_TRUE(torch::allclose(noisy.c2w.index({Slice(), Slice(), 3}), clean.c2w.index({Slice(), Slice(), 3}), 0, 1e-6));
}
