#include <gtest/gtest.h>

#include <set>

#include "train/train_test_util.h"
#include "uplvsm/data/loader.h"
#include "uplvsm/data/synthetic/room_scenes.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/io/image.h"

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
  auto a = data::make_training_batch(dataset, micro_options(), 5),
       b = data::make_training_batch(dataset, micro_options(), 5);
  EXPECT_EQ(a.keys, b.keys);
  EXPECT_EQ(a.frames, b.frames);
  EXPECT_TRUE(torch::equal(a.images, b.images));
  EXPECT_TRUE(torch::equal(a.c2w, b.c2w));
}

// An epoch visits every scene once, two chunks at a time: samples 4k..4k+3 of this split (2 scenes per chunk) come
// from one pair of chunks, and the pairs are disjoint, so the chunk cache serves the whole epoch with no re-reads.
TEST(Loader, EpochGoesThroughTheChunksTwoAtATime) {
  const auto root = test::temp_dir("loader_chunk_order");
  data::RoomSceneOptions scene;
  scene.height = 24, scene.width = 32, scene.frames = 8;
  data::write_builtin_dataset(root.string(), 12, 0, 3, scene, /*scenes_per_chunk=*/2);
  data::ChunkDataset dataset(root.string(), "train");
  ASSERT_EQ(dataset.size(), 12);
  auto opt = micro_options();
  opt.batch_size = 1;
  std::set<std::string> scenes, used_chunks;
  for (int64_t group = 0; group < 3; ++group) {
    std::set<std::string> chunks;
    for (int64_t step = 4 * group; step < 4 * group + 4; ++step) {
      const auto key = data::make_training_batch(dataset, opt, step).keys.at(0);
      scenes.insert(key);
      chunks.insert(dataset.chunk_name(dataset.find(key)));
    }
    EXPECT_EQ(chunks.size(), 2u) << "group " << group;
    for (const auto& c : chunks) EXPECT_TRUE(used_chunks.insert(c).second) << c << " read again in group " << group;
  }
  EXPECT_EQ(scenes.size(), 12u);
  EXPECT_EQ(dataset.chunk_reads(), 6);  // each chunk parsed once in the epoch
  // Another epoch, another order.
  std::vector<std::string> first, second;
  for (int64_t step = 0; step < 12; ++step) {
    first.push_back(data::make_training_batch(dataset, opt, step).keys.at(0));
    second.push_back(data::make_training_batch(dataset, opt, step + 12).keys.at(0));
  }
  EXPECT_NE(first, second);
}

// Data-parallel sharding: in one epoch two ranks see disjoint scenes that together cover the split.
TEST(Loader, RanksReadDisjointShardsCoveringTheEpoch) {
  data::ChunkDataset dataset(test::micro_dataset(), "train");
  const int64_t n = dataset.size();
  ASSERT_EQ(n % 2, 0);
  auto opt = micro_options();
  opt.batch_size = 1;
  opt.world_size = 2;
  std::multiset<std::string> seen;
  std::set<std::string> rank_keys[2];
  for (int rank = 0; rank < 2; ++rank) {
    opt.rank = rank;
    for (int64_t step = 0; step < n / 2; ++step) {
      const auto key = data::make_training_batch(dataset, opt, step).keys.at(0);
      seen.insert(key);
      rank_keys[rank].insert(key);
    }
  }
  EXPECT_EQ(seen.size(), static_cast<size_t>(n));
  EXPECT_EQ(std::set<std::string>(seen.begin(), seen.end()).size(), static_cast<size_t>(n));  // each exactly once
  EXPECT_EQ(rank_keys[0].size() + rank_keys[1].size(), static_cast<size_t>(n));
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

// The curriculum narrows the context gap early on (min_frame_dist only at step 0) and leaves later batches as
// they are without it.
TEST(Loader, FrameDistanceCurriculumStartsWithTheSmallestGap) {
  data::ChunkDataset dataset(test::micro_dataset(), "train");
  auto opt = micro_options();
  opt.frame_dist_curriculum_steps = 100;
  for (int64_t step = 0; step < 3; ++step)
    for (const auto& frames : data::make_training_batch(dataset, opt, step).frames)
      EXPECT_EQ(frames[1] - frames[0], opt.min_frame_dist);
  std::set<int64_t> gaps;
  for (int64_t step = 100; step < 120; ++step) {
    auto with = data::make_training_batch(dataset, opt, step);
    EXPECT_EQ(with.frames, data::make_training_batch(dataset, micro_options(), step).frames);
    for (const auto& frames : with.frames) gaps.insert(frames[1] - frames[0]);
  }
  EXPECT_GT(*gaps.rbegin(), opt.min_frame_dist);
}

// chunks_per_shuffle 0 shuffles the whole split as the official does: an epoch still visits every scene once, but
// its first four samples are not confined to two chunks (as they are with pairs, above).
TEST(Loader, WholeSplitShuffleVisitsEveryScenePerEpoch) {
  const auto root = test::temp_dir("loader_whole_shuffle");
  data::RoomSceneOptions scene;
  scene.height = 24, scene.width = 32, scene.frames = 8;
  data::write_builtin_dataset(root.string(), 12, 0, 3, scene, /*scenes_per_chunk=*/2);
  data::ChunkDataset dataset(root.string(), "train");
  auto opt = micro_options();
  opt.batch_size = 1;
  opt.chunks_per_shuffle = 0;
  int spread_groups = 0;
  for (int64_t epoch = 0; epoch < 4; ++epoch) {
    std::set<std::string> scenes, first_chunks;
    for (int64_t step = 12 * epoch; step < 12 * epoch + 12; ++step) {
      const auto key = data::make_training_batch(dataset, opt, step).keys.at(0);
      scenes.insert(key);
      if (step < 12 * epoch + 4) first_chunks.insert(dataset.chunk_name(dataset.find(key)));
    }
    EXPECT_EQ(scenes.size(), 12u) << "epoch " << epoch;
    spread_groups += first_chunks.size() > 2;
  }
  EXPECT_GT(spread_groups, 0);
  // A split that fits in the chunk cache is parsed once, however its scenes are shuffled.
  EXPECT_EQ(dataset.chunk_reads(), 6);
}

// The official dataset's preprocess_poses over each sample's views: centred on their mean camera, the largest
// translation coordinate 1 / 1.35.
TEST(Loader, CamerasAreInTheFrameOfTheSampledViews) {
  data::ChunkDataset dataset(test::micro_dataset(), "train");
  auto batch = data::make_training_batch(dataset, micro_options(), 3);
  using torch::indexing::Slice;
  auto t = batch.c2w.index({Slice(), Slice(), Slice(0, 3), 3});
  EXPECT_LT(t.mean(1).abs().max().item<double>(), 1e-5);
  EXPECT_NEAR(t.abs().amax({1, 2}).min().item<double>(), 1 / 1.35, 1e-5);
  EXPECT_NEAR(t.abs().amax({1, 2}).max().item<double>(), 1 / 1.35, 1e-5);
  EXPECT_TRUE(torch::equal(batch.input_c2w(2), batch.c2w.narrow(1, 0, 2)));
}

TEST(Loader, PoseNoisePerturbsOnlyTheCameras) {
  data::ChunkDataset dataset(test::micro_dataset(), "train");
  auto clean = data::make_training_batch(dataset, micro_options(), 3);
  auto opt = micro_options();
  opt.pose_noise_std = 0.1;
  auto noisy = data::make_training_batch(dataset, opt, 3);
  // Same scenes, views, pixels and scene frame: the noise has its own random stream and comes after the split.
  EXPECT_EQ(noisy.keys, clean.keys);
  EXPECT_EQ(noisy.frames, clean.frames);
  EXPECT_TRUE(torch::equal(noisy.images, clean.images));
  EXPECT_TRUE(torch::equal(noisy.target_index, clean.target_index));
  EXPECT_TRUE(torch::equal(noisy.c2w, clean.c2w));
  EXPECT_TRUE(torch::equal(noisy.target_c2w(), data::make_training_batch(dataset, opt, 3).target_c2w()));  // resume
  EXPECT_FALSE(torch::equal(noisy.input_c2w(2), data::make_training_batch(dataset, opt, 4).input_c2w(2)));
  using torch::indexing::Slice;
  auto R = noisy.target_c2w().index({Slice(), Slice(), Slice(0, 3), Slice(0, 3)}).to(torch::kFloat64);
  EXPECT_TRUE(torch::allclose(R.matmul(R.transpose(-1, -2)), torch::eye(3, torch::kFloat64).expand_as(R), 1e-5, 1e-5));
}

// The official noise_scale is a standard deviation on the (t, q) encoding in the scene frame: translations move by
// N(0, sd^2) exactly, and a target that repeats an input has a draw of its own.
TEST(Loader, PoseNoiseHasTheOfficialScaleAndIsDrawnApartForTargets) {
  data::ChunkDataset dataset(test::micro_dataset(), "train");
  auto opt = micro_options();
  opt.pose_noise_std = 0.1;
  std::vector<torch::Tensor> moves;
  int repeats = 0;
  using torch::indexing::Slice;
  for (int64_t step = 0; step < 12; ++step) {
    auto clean = data::make_training_batch(dataset, micro_options(), step);
    auto noisy = data::make_training_batch(dataset, opt, step);
    moves.push_back((noisy.input_c2w(2) - clean.input_c2w(2)).index({Slice(), Slice(), Slice(0, 3), 3}).flatten());
    moves.push_back((noisy.target_c2w() - clean.target_c2w()).index({Slice(), Slice(), Slice(0, 3), 3}).flatten());
    for (int64_t b = 0; b < 2; ++b)
      for (int64_t k = 0; k < 2; ++k) {
        const int64_t view = noisy.target_index[b][k].item<int64_t>();
        if (view >= 2) continue;
        ++repeats;
        EXPECT_TRUE(torch::equal(clean.target_c2w()[b][k], clean.input_c2w(2)[b][view]));
        EXPECT_FALSE(torch::allclose(noisy.target_c2w()[b][k], noisy.input_c2w(2)[b][view]));
      }
  }
  EXPECT_GT(repeats, 0);
  const double sd = torch::cat(moves).std().item<double>();  // 360 draws: within ~8 % of 0.1
  EXPECT_GT(sd, 0.08);
  EXPECT_LT(sd, 0.12);
}

// The quaternion half of the official noise: each told rotation's (x, y, z, w) moves by noise of the same scale (less
// its radial part, which renormalising removes: sd 0.1 x sqrt(3/4) ~ 0.087 per component).
TEST(Loader, PoseNoiseMovesTheRotationsQuaternions) {
  data::ChunkDataset dataset(test::micro_dataset(), "train");
  auto opt = micro_options();
  opt.pose_noise_std = 0.1;
  std::vector<torch::Tensor> moves;
  for (int64_t step = 0; step < 12; ++step) {
    auto clean = data::make_training_batch(dataset, micro_options(), step);
    auto noisy = data::make_training_batch(dataset, opt, step);
    for (auto [c, n] : {std::pair{clean.input_c2w(2), noisy.input_c2w(2)}, {clean.target_c2w(), noisy.target_c2w()}}) {
      auto qc = geometry::c2w_to_pose_encoding(c.to(torch::kFloat64)).narrow(-1, 3, 4).reshape({-1, 4});
      auto qn = geometry::c2w_to_pose_encoding(n.to(torch::kFloat64)).narrow(-1, 3, 4).reshape({-1, 4});
      auto sign = (qc * qn).sum(-1, true).sign();  // q and -q are one rotation
      moves.push_back((qn * sign - qc).flatten());
    }
  }
  const double sd = torch::cat(moves).std().item<double>();  // 384 components
  EXPECT_GT(sd, 0.065);
  EXPECT_LT(sd, 0.11);
}

namespace {
// A scene of n frames of h x w JPEGs whose cameras are valid.
data::RawScene jpeg_scene(const std::string& key, int n, int h = 24, int w = 32) {
  data::RawScene s;
  s.key = key;
  s.url = "test://" + key;
  s.timestamps = torch::arange(n, torch::kInt64);
  s.cameras = torch::zeros({n, 18});
  for (int i = 0; i < n; ++i) {
    s.cameras[i][0] = 0.8, s.cameras[i][1] = 1.4, s.cameras[i][2] = 0.5, s.cameras[i][3] = 0.5;
    s.cameras[i][6] = 1, s.cameras[i][11] = 1, s.cameras[i][16] = 1, s.cameras[i][17] = -0.1 * i;
    auto bytes = io::encode_jpeg(torch::full({h, w, 3}, 30 + 5 * i, torch::kUInt8), 90);
    s.images.push_back(torch::from_blob(bytes.data(), {static_cast<int64_t>(bytes.size())}, torch::kUInt8).clone());
  }
  return s;
}
}  // namespace

TEST(Loader, BadScenesAreReplacedCountedAndNeverServed) {
  const auto dir = test::temp_dir("loader_bad");
  std::filesystem::create_directories(dir / "train");
  std::vector<data::RawScene> scenes;
  scenes.push_back(jpeg_scene("good0", 12));
  scenes.push_back(jpeg_scene("good1", 12));
  scenes.push_back(jpeg_scene("empty", 0));
  scenes.push_back(jpeg_scene("short", 3));  // fewer frames than 4 views 2+ apart
  auto nan = jpeg_scene("nan", 12);
  nan.cameras.index_put_({torch::indexing::Slice(), 9}, std::numeric_limits<float>::quiet_NaN());
  scenes.push_back(nan);
  // Only frame 0 is 24x32: the others are resized from their own size, as the official dataset does (served).
  auto resized = jpeg_scene("resized", 12);
  for (int i = 1; i < 12; ++i) resized.images[i] = jpeg_scene("x", 1, 20, 32).images[0];
  scenes.push_back(resized);
  auto corrupt = jpeg_scene("corrupt", 12);
  for (int i = 0; i < 12; ++i) corrupt.images[i] = corrupt.images[i].slice(0, 0, 40).clone();  // truncated JPEGs
  scenes.push_back(corrupt);
  data::write_chunk((dir / "train/000000.torch").string(), scenes);
  data::ChunkDataset dataset(dir.string(), "train");
  ASSERT_EQ(dataset.size(), 7);
  auto opt = micro_options();
  int64_t replaced = 0, resized_frames = 0;
  std::set<std::string> served;
  for (int64_t step = 0; step < 10; ++step) {
    auto batch = data::make_training_batch(dataset, opt, step);
    EXPECT_EQ(batch.images.size(0), opt.batch_size);
    EXPECT_TRUE(torch::isfinite(batch.c2w).all().item<bool>());
    replaced += batch.replaced_scenes;
    resized_frames += batch.resized_frames;
    served.insert(batch.keys.begin(), batch.keys.end());
  }
  EXPECT_EQ(served, (std::set<std::string>{"good0", "good1", "resized"}));
  EXPECT_GT(replaced, 0);
  EXPECT_GT(resized_frames, 0);
  // Asked for directly, each bad scene gives an error naming it (the empty one too, without reading past its end).
  for (const char* key : {"empty", "nan", "corrupt"}) {
    auto msg = test::error_of([&] { dataset.load_views(dataset.find(key), {0, 1}, opt.preprocess); });
    EXPECT_NE(msg.find(key), std::string::npos) << msg;
  }
}
