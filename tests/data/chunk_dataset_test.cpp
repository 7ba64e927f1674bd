// Tests of data/chunk_dataset: the re10k fixture (keys, frames, cameras against truth.safetensors, views), chunk
// write/read round trips, error messages for bad files, skipped frames, the no-index fallback and thread safety.
#include "uplvsm/data/chunk_dataset.h"

#include <gtest/gtest.h>
#include <torch/csrc/jit/serialization/pickle.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <thread>

#include <fmt/format.h>

#include "test_util.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"
#include "uplvsm/io/safetensors.h"

namespace uplvsm::data {
namespace {
using test::error_of;

namespace fs = std::filesystem;
using test::fixture;

const std::string kRoot = "re10k_chunks/root";

const io::TensorMap& truth() {
  static io::TensorMap t = io::read_safetensors(fixture("re10k_chunks/truth.safetensors")).tensors;
  return t;
}

// A small valid scene: n frames of h x w smooth JPEGs, identity-ish cameras.
RawScene make_scene(const std::string& key, int n, int h = 24, int w = 32) {
  RawScene s;
  s.key = key;
  s.url = "test://" + key;
  s.timestamps = torch::arange(n, torch::kInt64) * 100000;
  s.cameras = torch::zeros({n, 18});
  for (int i = 0; i < n; ++i) {
    auto row = s.cameras[i];
    row[0] = 0.8, row[1] = 1.4, row[2] = 0.5, row[3] = 0.5;
    row[6] = 1, row[11] = 1, row[16] = 1;  // rotation identity (r00, r11, r22)
    row[17] = -0.1 * i;                    // t_z
  }
  for (int i = 0; i < n; ++i) {
    auto img = torch::full({h, w, 3}, 40 + 10 * i, torch::kUInt8);
    auto bytes = io::encode_jpeg(img, 90);
    s.images.push_back(torch::from_blob(bytes.data(), {static_cast<int64_t>(bytes.size())}, torch::kUInt8).clone());
  }
  return s;
}

void write_split(const fs::path& root, const std::string& split, const std::vector<RawScene>& scenes) {
  fs::create_directories(root / split);
  write_chunk((root / split / "000000.torch").string(), scenes);
  std::map<std::string, std::string> index;
  for (const auto& s : scenes) index[s.key] = "000000.torch";
  write_chunk_index((root / split).string(), index);
}

TEST(ChunkDataset, FixtureKeysAndFrames) {
  UPLVSM_NEEDS_FIXTURES();
  ChunkDataset train(fixture(kRoot), "train");
  ChunkDataset test_split(fixture(kRoot), "test");
  ASSERT_EQ(train.size(), 3);
  ASSERT_EQ(test_split.size(), 2);
  std::set<std::string> train_keys, test_keys;
  for (int64_t i = 0; i < train.size(); ++i) train_keys.insert(train.key(i));
  for (int64_t i = 0; i < test_split.size(); ++i) test_keys.insert(test_split.key(i));
  EXPECT_EQ(train_keys, (std::set<std::string>{"38ea44e76f05d39c", "3a4870d3d6531daa", "3d8ecadc15567bc8"}));
  EXPECT_EQ(test_keys, (std::set<std::string>{"20e408dd375292a1", "09d9882a954acbf1"}));
  for (int64_t i = 0; i < train.size(); ++i) EXPECT_EQ(train.num_frames(i), 16);
  EXPECT_EQ(test_split.key(test_split.find("20e408dd375292a1")), "20e408dd375292a1");
  EXPECT_EQ(test_split.find("0000000000000000"), -1);
  auto scene = test_split.scene(test_split.find("20e408dd375292a1"));
  EXPECT_EQ(scene.images.size(), 16u);
  EXPECT_EQ(scene.timestamps.scalar_type(), torch::kInt64);
  EXPECT_EQ(scene.url.rfind("synthetic://", 0), 0u) << scene.url;
  EXPECT_THROW(train.key(3), std::out_of_range);
}

TEST(ChunkDataset, FixtureCamerasMatchTruth) {
  UPLVSM_NEEDS_FIXTURES();
  for (const char* split : {"train", "test"}) {
    ChunkDataset ds(fixture(kRoot), split);
    for (int64_t i = 0; i < ds.size(); ++i) {
      auto s = ds.scene(i);
      auto c2w = cameras_to_c2w(s.cameras, s.key);
      EXPECT_LT(test::max_abs_diff(c2w, truth().at(s.key + ".c2w")), 1e-6) << s.key;
      auto k = cameras_to_fxfycxcy(s.cameras, 640, 360);
      EXPECT_LT(test::max_abs_diff(k, truth().at(s.key + ".intrinsics_px")), 1e-3) << s.key;
    }
  }
}

TEST(ChunkDataset, FixtureLoadViewsOfficial224) {
  UPLVSM_NEEDS_FIXTURES();
  ChunkDataset ds(fixture(kRoot), "test");
  int64_t i = ds.find("20e408dd375292a1");
  std::vector<int64_t> frames = {1, 13, 4, 8, 11};
  SceneViews v = ds.load_views(i, frames, PreprocessOptions{});
  EXPECT_EQ(v.images.sizes(), (std::vector<int64_t>{5, 3, 224, 224}));
  EXPECT_EQ(v.frames, frames);
  EXPECT_GE(v.images.min().item<float>(), 0.0f);
  EXPECT_LE(v.images.max().item<float>(), 1.0f);
  auto idx = torch::tensor(frames, torch::kInt64);
  auto k = truth().at("20e408dd375292a1.intrinsics_px").index_select(0, idx).to(torch::kFloat64);
  // Official formulas: 640x360 -> resize 392x224, crop x from 84.
  auto expected = torch::stack({k.select(1, 0) * 392.0 / 640.0, k.select(1, 1) * 224.0 / 360.0,
                                k.select(1, 2) * 392.0 / 640.0 - 84.0, k.select(1, 3) * 224.0 / 360.0},
                               1);
  EXPECT_LT(test::max_abs_diff(v.fxfycxcy, expected), 1e-3);
  EXPECT_LT(test::max_abs_diff(v.c2w, truth().at("20e408dd375292a1.c2w").index_select(0, idx)), 1e-6);
  EXPECT_NE(error_of([&] { ds.load_views(i, {16}, PreprocessOptions{}); }).find("frame 16"), std::string::npos);
}

TEST(ChunkDataset, WriteReadRoundTrip) {
  auto dir = test::temp_dir("chunk_roundtrip");
  std::vector<RawScene> scenes = {make_scene("aaaa000000000001", 3), make_scene("aaaa000000000002", 5)};
  auto path = (dir / "000000.torch").string();
  write_chunk(path, scenes);
  auto back = read_chunk(path);
  ASSERT_EQ(back.size(), 2u);
  for (size_t j = 0; j < 2; ++j) {
    EXPECT_EQ(back[j].key, scenes[j].key);
    EXPECT_EQ(back[j].url, scenes[j].url);
    EXPECT_TRUE(torch::equal(back[j].timestamps, scenes[j].timestamps));
    EXPECT_TRUE(torch::equal(back[j].cameras, scenes[j].cameras));
    ASSERT_EQ(back[j].images.size(), scenes[j].images.size());
    for (size_t f = 0; f < scenes[j].images.size(); ++f)
      EXPECT_TRUE(torch::equal(back[j].images[f], scenes[j].images[f]));
  }
  // Only what Python's torch.save writes: no TorchScript type tags (torch.load(weights_only=True) refuses them).
  auto raw = io::read_file(path);
  std::string text(raw.begin(), raw.end());
  EXPECT_EQ(text.find("torch.jit"), std::string::npos);
  EXPECT_NE(text.find("_rebuild_tensor_v2"), std::string::npos);
  // Same content, same bytes (no timestamps in the zip).
  write_chunk((dir / "again.torch").string(), scenes);
  EXPECT_EQ(io::read_file(path), io::read_file((dir / "again.torch").string()));
  test::remove_tree(dir);
}

TEST(ChunkDataset, BadFilesThrowNamingFileAndField) {
  UPLVSM_NEEDS_FIXTURES();
  auto dir = test::temp_dir("chunk_bad");
  // Truncated file.
  auto full = io::read_file(fixture(kRoot + "/test/000000.torch"));
  auto truncated = (dir / "truncated.torch").string();
  std::ofstream(truncated, std::ios::binary).write(reinterpret_cast<const char*>(full.data()), full.size() / 2);
  auto msg = error_of([&] { read_chunk(truncated); });
  EXPECT_NE(msg.find("truncated.torch"), std::string::npos) << msg;
  // Cameras of the wrong shape, written around write_chunk's validation.
  auto write_raw = [&](const std::string& name, const std::function<void(c10::impl::GenericDict&)>& edit) {
    RawScene s = make_scene("bbbb000000000001", 2);
    c10::impl::GenericDict d(c10::StringType::get(), c10::AnyType::get());
    d.insert("url", s.url);
    d.insert("timestamps", s.timestamps);
    d.insert("cameras", s.cameras);
    c10::impl::GenericList images(c10::AnyType::get());
    for (auto& im : s.images) images.push_back(im);
    d.insert("images", images);
    d.insert("key", s.key);
    edit(d);
    c10::impl::GenericList list(c10::AnyType::get());
    list.push_back(d);
    auto bytes = torch::pickle_save(list);
    std::ofstream((dir / name).string(), std::ios::binary).write(bytes.data(), bytes.size());
    return (dir / name).string();
  };
  auto p = write_raw("shape.torch", [](auto& d) { d.insert_or_assign("cameras", torch::zeros({2, 17})); });
  msg = error_of([&] { read_chunk(p); });
  EXPECT_NE(msg.find("shape.torch"), std::string::npos) << msg;
  EXPECT_NE(msg.find("cameras"), std::string::npos) << msg;
  EXPECT_NE(msg.find("bbbb000000000001"), std::string::npos) << msg;
  p = write_raw("missing.torch", [](auto& d) { (void)d.erase("images"); });
  msg = error_of([&] { read_chunk(p); });
  EXPECT_NE(msg.find("missing field 'images'"), std::string::npos) << msg;
  p = write_raw("count.torch", [](auto& d) {
    c10::impl::GenericList one(c10::AnyType::get());
    one.push_back(torch::ones({10}, torch::kUInt8));
    d.insert_or_assign("images", one);
  });
  msg = error_of([&] { read_chunk(p); });
  EXPECT_NE(msg.find("images"), std::string::npos) << msg;
  p = write_raw("dtype.torch", [](auto& d) { d.insert_or_assign("cameras", torch::zeros({2, 18}, torch::kInt64)); });
  msg = error_of([&] { read_chunk(p); });
  EXPECT_NE(msg.find("float32"), std::string::npos) << msg;
  // write_chunk validates too.
  RawScene s = make_scene("cccc000000000001", 2);
  s.cameras = torch::zeros({2, 12});
  msg = error_of([&] { write_chunk((dir / "w.torch").string(), {s}); });
  EXPECT_NE(msg.find("cameras"), std::string::npos) << msg;
  EXPECT_FALSE(fs::exists(dir / "w.torch"));
  test::remove_tree(dir);
}

TEST(ChunkDataset, NanCameraAndGarbageJpegNameSceneAndFrame) {
  auto dir = test::temp_dir("chunk_nan");
  RawScene s = make_scene("dddd000000000001", 4);
  s.cameras[2][9] = std::numeric_limits<float>::quiet_NaN();
  s.images[3] = torch::full({50}, 7, torch::kUInt8);
  write_split(dir, "test", {s});
  ChunkDataset ds(dir.string(), "test");
  EXPECT_NO_THROW(ds.load_views(0, {0, 1}, PreprocessOptions{}));
  auto msg = error_of([&] { ds.load_views(0, {0, 2}, PreprocessOptions{}); });
  EXPECT_NE(msg.find("dddd000000000001"), std::string::npos) << msg;
  EXPECT_NE(msg.find("frame 2"), std::string::npos) << msg;
  EXPECT_NE(msg.find("cameras"), std::string::npos) << msg;
  msg = error_of([&] { ds.load_views(0, {3}, PreprocessOptions{}); });
  EXPECT_NE(msg.find("dddd000000000001 frame 3"), std::string::npos) << msg;
  EXPECT_NE(msg.find("JPEG"), std::string::npos) << msg;
  test::remove_tree(dir);
}

TEST(ChunkDataset, WrongSizeFrameThrowsBadFrameError) {
  auto dir = test::temp_dir("chunk_badframe");
  RawScene s = make_scene("eeee000000000001", 3, 24, 32);
  RawScene other = make_scene("x", 1, 20, 32);
  s.images[1] = other.images[0];
  write_split(dir, "train", {s});
  ChunkDataset ds(dir.string(), "train");
  try {
    ds.load_views(0, {0, 1}, PreprocessOptions{});
    FAIL() << "expected BadFrameError";
  } catch (const BadFrameError& e) {
    EXPECT_EQ(e.scene_key, "eeee000000000001");
    EXPECT_EQ(e.frame, 1);
    EXPECT_EQ(e.expected_height, 24);
    EXPECT_EQ(e.height, 20);
    EXPECT_NE(std::string(e.what()).find("frame 1"), std::string::npos);
  }
  EXPECT_EQ(ds.load_views(0, {2, 0}, PreprocessOptions{}).images.size(0), 2);
  test::remove_tree(dir);
}

// Under FrameSizePolicy::Resize a frame of another size is preprocessed from its own size, as every frame is (the
// official dataset): the views stack and the frame is counted. Without a square crop a frame whose resized width
// differs cannot stack: still a BadFrameError. Under Skip (the default) any other size is pixelSplat's skip.
TEST(ChunkDataset, FramesOfAnotherSizeAreResizedWhenAsked) {
  auto dir = test::temp_dir("chunk_resized");
  RawScene s = make_scene("eeee000000000002", 4, 24, 32);
  s.images[1] = make_scene("x", 1, 48, 64).images[0];  // the same aspect, twice the size
  s.images[2] = make_scene("y", 1, 30, 32).images[0];  // another aspect
  write_split(dir, "train", {s});
  ChunkDataset ds(dir.string(), "train");
  const PreprocessOptions square{32, 8, true}, wide{32, 8, false};
  constexpr auto resize = FrameSizePolicy::Resize;
  auto v = ds.load_views(0, {0, 1, 2, 3}, square, resize);
  EXPECT_EQ(v.resized_frames, 2);
  EXPECT_EQ(v.images.sizes(), (std::vector<int64_t>{4, 3, 32, 32}));
  // Frame 1 comes out as frame 0 would from its own size (a flat image: the same pixels; the same intrinsics).
  EXPECT_LE((v.images[1] - v.images[0]).abs().max().item<double>(), 2.5 / 255.0);
  EXPECT_TRUE(torch::allclose(v.fxfycxcy[1], v.fxfycxcy[0]));
  auto wide_views = ds.load_views(0, {0, 1}, wide, resize);
  EXPECT_EQ(wide_views.images.size(3), 40);
  EXPECT_EQ(wide_views.resized_frames, 1);
  EXPECT_THROW(ds.load_views(0, {0, 2}, wide, resize), BadFrameError);
  EXPECT_THROW(ds.load_views(0, {2, 3}, wide, resize), BadFrameError);
  EXPECT_EQ(ds.load_views(0, {0, 3}, square, resize).resized_frames, 0);
  EXPECT_THROW(ds.load_views(0, {0, 1}, square), BadFrameError);  // the default: pixelSplat's rule
  EXPECT_THROW(ds.load_views(0, {0, 1}, square, FrameSizePolicy::Skip), BadFrameError);
  test::remove_tree(dir);
}

TEST(ChunkDataset, ScansChunksWithoutIndex) {
  auto dir = test::temp_dir("chunk_noindex");
  fs::create_directories(dir / "train");
  write_chunk((dir / "train" / "000001.torch").string(), {make_scene("ffff000000000002", 2)});
  write_chunk((dir / "train" / "000000.torch").string(), {make_scene("ffff000000000009", 3)});
  ChunkDataset ds(dir.string(), "train");
  ASSERT_EQ(ds.size(), 2);
  EXPECT_EQ(ds.key(0), "ffff000000000009");  // ordered by chunk file, then key
  EXPECT_EQ(ds.num_frames(0), 3);
  EXPECT_EQ(ds.num_frames(1), 2);
  EXPECT_THROW(ChunkDataset(dir.string(), "test"), std::runtime_error);
  test::remove_tree(dir);
}

TEST(ChunkDataset, IndexEntriesThatPointNowhereNameTheKeyAndFile) {
  auto dir = test::temp_dir("chunk_badindex");
  fs::create_directories(dir / "train");
  write_chunk((dir / "train" / "000000.torch").string(), {make_scene("ffff000000000001", 2)});
  write_chunk_index((dir / "train").string(),
                    {{"ffff000000000001", "000000.torch"}, {"ffff000000000002", "000007.torch"}});
  auto msg = test::error_of([&] { ChunkDataset(dir.string(), "train"); });
  EXPECT_NE(msg.find("ffff000000000002"), std::string::npos) << msg;
  EXPECT_NE(msg.find("missing file 000007.torch"), std::string::npos) << msg;

  // The file exists but does not hold the key: found when the scene is read, not at open.
  write_chunk_index((dir / "train").string(),
                    {{"ffff000000000001", "000000.torch"}, {"ffff000000000002", "000000.torch"}});
  ChunkDataset ds(dir.string(), "train");
  ASSERT_EQ(ds.size(), 2);
  EXPECT_EQ(ds.scene(0).key, "ffff000000000001");
  msg = test::error_of([&] { ds.scene(1); });
  EXPECT_NE(msg.find("says scene ffff000000000002 is in 000000.torch"), std::string::npos) << msg;
  test::remove_tree(dir);
}

TEST(ChunkDataset, ChunkStartsMarkEachChunksContiguousRange) {
  auto dir = test::temp_dir("chunk_starts");
  fs::create_directories(dir / "train");
  write_chunk((dir / "train" / "000001.torch").string(), {make_scene("bb00000000000001", 2)});
  write_chunk((dir / "train" / "000000.torch").string(),
              {make_scene("aa00000000000002", 2), make_scene("aa00000000000001", 2)});
  ChunkDataset ds(dir.string(), "train");
  ASSERT_EQ(ds.size(), 3);
  EXPECT_EQ(ds.chunk_starts(), (std::vector<int64_t>{0, 2}));
  for (int64_t i = 0; i < ds.size(); ++i) EXPECT_EQ(ds.chunk_name(i), i < 2 ? "000000.torch" : "000001.torch");
  ds.keep_only({"aa00000000000002", "bb00000000000001"});  // the starts follow the subset
  EXPECT_EQ(ds.chunk_starts(), (std::vector<int64_t>{0, 1}));
  test::remove_tree(dir);
}

TEST(ChunkDataset, ConcurrentLoadsMatchSerial) {
  auto dir = test::temp_dir("chunk_threads");
  fs::create_directories(dir / "train");
  std::map<std::string, std::string> index;
  for (int c = 0; c < 3; ++c) {
    std::vector<RawScene> scenes;
    for (int j = 0; j < 2; ++j) scenes.push_back(make_scene(fmt::format("{:016x}", c * 10 + j), 4));
    auto file = fmt::format("{:06d}.torch", c);
    write_chunk((dir / "train" / file).string(), scenes);
    for (const auto& s : scenes) index[s.key] = file;
  }
  write_chunk_index((dir / "train").string(), index);
  ChunkDataset ds(dir.string(), "train", /*cache_chunks=*/1, /*cache_bytes=*/0);  // evictions under concurrency
  PreprocessOptions opt;
  opt.image_size = 28;
  std::vector<torch::Tensor> serial;
  for (int64_t i = 0; i < ds.size(); ++i) serial.push_back(ds.load_views(i, {0, 3}, opt).images);
  std::vector<std::thread> threads;
  std::atomic<int> mismatches{0};
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      for (int rep = 0; rep < 10; ++rep) {
        int64_t i = (t + rep) % ds.size();
        if (!torch::equal(ds.load_views(i, {0, 3}, opt).images, serial[i])) ++mismatches;
      }
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(mismatches.load(), 0);
  test::remove_tree(dir);
}

}  // namespace
}  // namespace uplvsm::data

// The first input the chunk fuzzer (fuzz/) crashed on: torch::pickle_load read freed memory in LibTorch's zip reader.
// read_chunk now goes through io::TorchFile and must reject it cleanly, naming the file.
TEST(ChunkDataset, FuzzRegressionMalformedZipIsACleanError) {
  const std::string path = std::string(UPLVSM_SOURCE_DIR) + "/fuzz/corpus/chunk/regression_libtorch_zip_uaf.torch";
  ASSERT_TRUE(std::filesystem::exists(path));
  auto msg = uplvsm::test::error_of([&] { uplvsm::data::read_chunk(path); });
  EXPECT_NE(msg.find("regression_libtorch_zip_uaf.torch"), std::string::npos) << msg;
  EXPECT_NE(msg.find("not a readable torch.save file"), std::string::npos) << msg;
}
