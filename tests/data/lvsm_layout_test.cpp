// Tests of data/lvsm_layout (chunks <-> LVSM layout on the RealEstate10K fixture) and data/dataset_stats.
#include "uplvsm/data/lvsm_layout.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/dataset_stats.h"
#include "uplvsm/data/loader.h"
#include "uplvsm/io/image.h"

using namespace uplvsm;
using namespace uplvsm::data;
namespace fs = std::filesystem;

TEST(LvsmLayout, ChunksToLvsmAndBackKeepPixelsAndCameras) {
  UPLVSM_NEEDS_FIXTURES();
  const auto dir = test::temp_dir("lvsm_layout");
  const auto chunks = test::fixture("re10k_chunks/root/test");
  const auto lvsm = (dir / "lvsm/test").string(), back = (dir / "back/test").string();
  auto there = chunks_to_lvsm(chunks, lvsm);
  ASSERT_GT(there.scenes, 0);
  auto list = read_full_list((fs::path(lvsm) / "full_list.txt").string());
  ASSERT_EQ(static_cast<int64_t>(list.size()), there.scenes);
  EXPECT_TRUE(std::is_sorted(list.begin(), list.end()));
  EXPECT_TRUE(fs::path(list[0]).is_absolute());

  // The official metadata: intrinsics in pixels of the stored image, w2c 4x4.
  ChunkDataset original(test::fixture("re10k_chunks/root"), "test");
  const auto key = original.key(0);
  std::ifstream in(fs::path(lvsm) / "metadata" / (key + ".json"));
  auto meta = nlohmann::json::parse(in);
  EXPECT_EQ(meta.at("scene_name"), key);
  const auto& f0 = meta.at("frames").at(0);
  auto cam = original.scene(0).cameras[0];
  auto png = io::read_image(f0.at("image_path").get<std::string>());
  EXPECT_NEAR(f0.at("fxfycxcy")[0].get<double>(), cam[0].item<double>() * png.size(1), 1e-3);
  EXPECT_NEAR(f0.at("fxfycxcy")[3].get<double>(), cam[3].item<double>() * png.size(0), 1e-3);
  EXPECT_EQ(f0.at("w2c").size(), 4u);
  EXPECT_EQ(f0.at("w2c")[3], nlohmann::json({0.0, 0.0, 0.0, 1.0}));

  auto again = lvsm_to_chunks(lvsm, back, 2);
  EXPECT_EQ(again.scenes, there.scenes);
  EXPECT_EQ(again.frames, there.frames);
  ChunkDataset converted((dir / "back").string(), "test");
  ASSERT_EQ(converted.size(), original.size());
  PreprocessOptions prep{224, 14, true};
  for (int64_t i = 0; i < original.size(); ++i) {
    const int64_t j = converted.find(original.key(i));
    ASSERT_GE(j, 0);
    auto a = original.load_views(i, {0, 1}, prep), b = converted.load_views(j, {0, 1}, prep);
    EXPECT_TRUE(torch::equal(a.images, b.images)) << original.key(i);  // PNG keeps the decoded JPEG pixels
    EXPECT_TRUE(torch::allclose(a.fxfycxcy, b.fxfycxcy, 1e-5, 1e-4));
    EXPECT_TRUE(torch::allclose(a.c2w, b.c2w, 1e-5, 1e-5));
  }
}

TEST(LvsmLayout, BadMetadataNamesTheFileAndField) {
  UPLVSM_NEEDS_FIXTURES();
  const auto dir = test::temp_dir("lvsm_bad");
  auto scene = read_chunk(test::fixture("re10k_chunks/root/test/000000.torch")).at(0);
  scene.images.resize(2);
  scene.cameras = scene.cameras.slice(0, 0, 2);
  scene.timestamps = scene.timestamps.slice(0, 0, 2);
  const auto meta_path = write_lvsm_scene((dir / "split").string(), scene);
  std::ifstream in(meta_path);
  const auto good = nlohmann::json::parse(in);
  auto write = [&](const nlohmann::json& j) { std::ofstream(meta_path) << j.dump(); };

  auto nan = good;
  nan["frames"][1]["w2c"][0][3] = nullptr;  // not a number
  write(nan);
  auto msg = test::error_of([&] { read_lvsm_scene(meta_path); });
  EXPECT_NE(msg.find(meta_path), std::string::npos) << msg;
  EXPECT_NE(msg.find("frames[1].w2c"), std::string::npos) << msg;

  auto missing = good;
  missing["frames"][0].erase("fxfycxcy");
  write(missing);
  msg = test::error_of([&] { read_lvsm_scene(meta_path); });
  EXPECT_NE(msg.find("missing field 'fxfycxcy'"), std::string::npos) << msg;

  auto no_image = good;
  no_image["frames"][0]["image_path"] = (dir / "nowhere.png").string();
  write(no_image);
  msg = test::error_of([&] { read_lvsm_scene(meta_path); });
  EXPECT_NE(msg.find("nowhere.png"), std::string::npos) << msg;

  // Deeper than rows of numbers: described, not printed (printing recursed per level; found by fuzzing).
  auto deep = good;
  deep["frames"][0]["w2c"][0] = "DEEP";
  auto deep_text = deep.dump();
  deep_text.replace(deep_text.find("\"DEEP\""), 6, std::string(100000, '[') + "1" + std::string(100000, ']'));
  std::ofstream(meta_path) << deep_text;
  msg = test::error_of([&] { read_lvsm_scene(meta_path); });
  EXPECT_NE(msg.find("expected numbers, got an array of 1"), std::string::npos) << msg;

  write(good);
  EXPECT_EQ(read_lvsm_scene(meta_path).images.size(), 2u);
  std::ofstream(meta_path) << "{\"frames\": [";
  msg = test::error_of([&] { read_lvsm_scene(meta_path); });
  EXPECT_NE(msg.find("not valid JSON"), std::string::npos) << msg;
}

TEST(DatasetStats, CountsScenesFramesSizesAndSkips) {
  auto st = dataset_stats(test::micro_dataset(), "train", 13);
  EXPECT_EQ(st.scenes, 6);
  EXPECT_EQ(st.frames, 72);
  EXPECT_EQ(st.min_frames, 12);
  EXPECT_EQ(st.max_frames, 12);
  EXPECT_EQ(st.image_sizes, (std::map<std::string, int64_t>{{"36x64", 72}}));
  EXPECT_EQ(st.off_size_frames, 0);
  EXPECT_EQ(st.nonfinite_cameras, 0);
  EXPECT_EQ(st.scenes_shorter_than, 6);  // 12 frames < 13 needed
  EXPECT_EQ(to_json(st).at("chunks"), st.chunks);
}

TEST(LvsmLayout, DatasetReadsTheLayoutInPlaceLikeTheChunks) {
  UPLVSM_NEEDS_FIXTURES();
  const auto dir = test::temp_dir("lvsm_direct");
  chunks_to_lvsm(test::fixture("re10k_chunks/root/test"), (dir / "lvsm/test").string());
  ChunkDataset chunks(test::fixture("re10k_chunks/root"), "test");
  ChunkDataset lvsm((dir / "lvsm").string(), "test");
  EXPECT_EQ(chunks.layout(), ChunkDataset::Layout::Chunks);
  ASSERT_EQ(lvsm.layout(), ChunkDataset::Layout::Lvsm);
  ASSERT_EQ(lvsm.size(), chunks.size());
  PreprocessOptions prep{224, 14, true};
  for (int64_t i = 0; i < chunks.size(); ++i) {
    const int64_t j = lvsm.find(chunks.key(i));
    ASSERT_GE(j, 0) << chunks.key(i);
    const int64_t n = chunks.num_frames(i);
    ASSERT_EQ(lvsm.num_frames(j), n);
    const std::vector<int64_t> frames{n - 1, 0, n / 2};
    auto a = chunks.load_views(i, frames, prep), b = lvsm.load_views(j, frames, prep);
    EXPECT_TRUE(torch::equal(a.images, b.images)) << chunks.key(i);
    EXPECT_TRUE(torch::allclose(a.fxfycxcy, b.fxfycxcy, 1e-5, 1e-4));
    EXPECT_TRUE(torch::allclose(a.c2w, b.c2w, 1e-5, 1e-5));
    EXPECT_EQ(b.frames, frames);
  }
  // The training loader and the statistics work on it unchanged.
  LoaderOptions lo;
  lo.batch_size = 1;
  lo.num_views = 4;
  lo.num_target_views = 2;
  lo.min_frame_dist = 2;
  lo.max_frame_dist = 10;
  lo.preprocess = {32, 8, true};
  auto batch = make_training_batch(lvsm, lo, 0);
  EXPECT_EQ(batch.images.sizes(), (std::vector<int64_t>{1, 4, 3, 32, 32}));
  auto st = dataset_stats((dir / "lvsm").string(), "test", 8);
  EXPECT_EQ(st.layout, "lvsm");
  EXPECT_EQ(st.scenes, chunks.size());
}

TEST(LvsmLayout, MovedDatasetAndMissingFramesAreHandled) {
  UPLVSM_NEEDS_FIXTURES();
  const auto dir = test::temp_dir("lvsm_moved");
  chunks_to_lvsm(test::fixture("re10k_chunks/root/test"), (dir / "a/test").string());
  // full_list.txt and the metadata hold absolute paths into a/: after a move they are stale.
  fs::rename(dir / "a", dir / "b");
  ChunkDataset moved((dir / "b").string(), "test");
  ASSERT_GT(moved.size(), 0);
  EXPECT_EQ(moved.load_views(0, {0, 1}, {32, 8, true}).images.size(0), 2);
  // A frame file that is gone: the error names it; other frames still load.
  const auto gone = dir / "b/test/images" / moved.key(0) / "00001.png";
  fs::remove(gone);
  auto msg = test::error_of([&] { moved.load_views(0, {0, 1}, {32, 8, true}); });
  EXPECT_NE(msg.find("00001.png"), std::string::npos) << msg;
  EXPECT_EQ(moved.load_views(0, {0, 2}, {32, 8, true}).images.size(0), 2);
}
