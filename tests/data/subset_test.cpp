// Tests of data/subset (little/medium/large/full manifests), ChunkDataset::keep_only and unposed.json.
#include "uplvsm/data/subset.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/data/lvsm_layout.h"

using namespace uplvsm;
using namespace uplvsm::data;
namespace fs = std::filesystem;

namespace {

// The micro built-in train split re-chunked at 2 scenes per file: 6 scenes in 3 chunks.
std::string three_chunk_root() {
  static std::string root;
  if (root.empty()) {
    const auto dir = test::temp_dir("subset_root");
    chunks_to_lvsm(test::micro_dataset() + "/train", (dir / "lvsm/train").string());
    lvsm_to_chunks((dir / "lvsm/train").string(), (dir / "chunks/train").string(), 2);
    root = (dir / "chunks").string();
  }
  return root;
}

}  // namespace

TEST(Subset, OfficialSizesAreTheReadmeFigures) {
  ASSERT_EQ(official_subsets().size(), 4u);
  EXPECT_EQ(find_official_subset("little")->chunks, 76);
  EXPECT_EQ(find_official_subset("little")->scenes, 1202);
  EXPECT_EQ(find_official_subset("medium")->chunks, 304);
  EXPECT_EQ(find_official_subset("medium")->scenes, 4121);
  EXPECT_EQ(find_official_subset("large")->chunks, 1216);
  EXPECT_EQ(find_official_subset("large")->scenes, 16449);
  EXPECT_EQ(find_official_subset("full")->chunks, 4866);
  EXPECT_EQ(find_official_subset("full")->scenes, 66033);
  EXPECT_FALSE(find_official_subset("tiny"));
}

TEST(Subset, FirstChunksInNameOrderAndManifestRoundTrip) {
  ChunkDataset ds(three_chunk_root(), "train");
  ASSERT_EQ(ds.size(), 6);
  auto m = select_subset(ds, {"", 2, 0});
  EXPECT_EQ(m.chunks, (std::vector<std::string>{"000000.torch", "000001.torch"}));
  ASSERT_EQ(m.scenes.size(), 4u);
  for (size_t i = 0; i < 4; ++i) EXPECT_EQ(m.scenes[i], ds.key(static_cast<int64_t>(i)));
  // The same request gives the same manifest (deterministic); a bigger one nests the smaller.
  EXPECT_EQ(select_subset(ds, {"", 2, 0}).scenes, m.scenes);
  auto bigger = select_subset(ds, {"", 3, 0});
  EXPECT_TRUE(std::equal(m.scenes.begin(), m.scenes.end(), bigger.scenes.begin()));

  const auto path = (test::temp_dir("subset_manifest") / "two.json").string();
  write_subset_manifest(path, m);
  auto back = read_subset_manifest(path);
  EXPECT_EQ(back.scenes, m.scenes);
  EXPECT_EQ(back.chunks, m.chunks);
  EXPECT_EQ(back.split, "train");

  ChunkDataset restricted(three_chunk_root(), "train");
  restricted.keep_only(back.scenes);
  ASSERT_EQ(restricted.size(), 4);
  for (int64_t i = 0; i < 4; ++i) {
    EXPECT_EQ(restricted.key(i), m.scenes[i]);
    EXPECT_EQ(restricted.find(m.scenes[i]), i);
  }
  EXPECT_EQ(restricted.find(ds.key(5)), -1);
  EXPECT_EQ(restricted.load_views(3, {0, 1}, {32, 8, true}).images.size(0), 2);
}

TEST(Subset, ScenesCountsFullAndErrors) {
  ChunkDataset ds(three_chunk_root(), "train");
  auto m = select_subset(ds, {"", 0, 3});
  EXPECT_TRUE(m.chunks.empty());
  EXPECT_EQ(m.scenes.size(), 3u);
  auto full = select_subset(ds, {"full", 0, 0});
  EXPECT_EQ(full.scenes.size(), 6u);
  EXPECT_EQ(full.chunks.size(), 3u);
  EXPECT_EQ(full.official_scenes, 66033);

  auto msg = test::error_of([&] { select_subset(ds, {"little", 0, 0}); });
  EXPECT_NE(msg.find("needs 76 chunks"), std::string::npos) << msg;
  EXPECT_NE(msg.find("has 3"), std::string::npos) << msg;
  msg = test::error_of([&] { select_subset(ds, {"", 0, 7}); });
  EXPECT_NE(msg.find("needs 7 scenes"), std::string::npos) << msg;
  msg = test::error_of([&] { select_subset(ds, {"little", 2, 0}); });
  EXPECT_NE(msg.find("exactly one"), std::string::npos) << msg;
  msg = test::error_of([&] { select_subset(ds, {"huge", 0, 0}); });
  EXPECT_NE(msg.find("unknown subset 'huge'"), std::string::npos) << msg;
  msg = test::error_of([&] { ds.keep_only({ds.key(0), "not-a-scene"}); });
  EXPECT_NE(msg.find("not-a-scene"), std::string::npos) << msg;

  // An LVSM-layout split has no chunks: official names count scenes, chunk counts are refused.
  ChunkDataset lvsm(fs::path(three_chunk_root()).parent_path().string() + "/lvsm", "train");
  msg = test::error_of([&] { select_subset(lvsm, {"", 2, 0}); });
  EXPECT_NE(msg.find("no chunks"), std::string::npos) << msg;
  msg = test::error_of([&] { select_subset(lvsm, {"little", 0, 0}); });
  EXPECT_NE(msg.find("needs 1202 scenes"), std::string::npos) << msg;
}

TEST(Subset, BadManifestsNameTheFileAndField) {
  const auto dir = test::temp_dir("subset_bad");
  const auto path = (dir / "m.json").string();
  std::ofstream(path) << R"({"name": "x", "scenes": ["a", 3]})";
  auto msg = test::error_of([&] { read_subset_manifest(path); });
  EXPECT_NE(msg.find(path), std::string::npos) << msg;
  EXPECT_NE(msg.find("'scenes'"), std::string::npos) << msg;
  std::ofstream(path) << R"({"name": "x", "scenes": ["a", "a"]})";
  msg = test::error_of([&] { read_subset_manifest(path); });
  EXPECT_NE(msg.find("twice"), std::string::npos) << msg;
  std::ofstream(path) << R"({"name": "x")";
  msg = test::error_of([&] { read_subset_manifest(path); });
  EXPECT_NE(msg.find("not valid JSON"), std::string::npos) << msg;
  // Found by fuzzing: a huge count was a float-to-int cast (undefined behaviour), a deep entry recursed in the message.
  std::ofstream(path) << R"({"name": "x", "official_scenes": 4e24, "scenes": ["a"]})";
  msg = test::error_of([&] { read_subset_manifest(path); });
  EXPECT_NE(msg.find("official_scenes: expected an integer, got 4e+24"), std::string::npos) << msg;
  std::ofstream(path) << R"({"name": "x", "scenes": [)" << std::string(100000, '[') << std::string(100000, ']') << "]}";
  msg = test::error_of([&] { read_subset_manifest(path); });
  EXPECT_NE(msg.find("holds an array of 1, expected strings"), std::string::npos) << msg;
}

TEST(Unposed, ListedScenesHaveNoKnownPoses) {
  const auto dir = test::temp_dir("unposed");
  fs::copy(three_chunk_root() + "/train", dir / "train");
  ChunkDataset before(dir.string(), "train");
  for (int64_t i = 0; i < before.size(); ++i) EXPECT_TRUE(before.poses_known(i));
  std::ofstream(dir / "train/unposed.json") << "[\"" << before.key(1) << "\"]";
  ChunkDataset after(dir.string(), "train");
  EXPECT_TRUE(after.poses_known(0));
  EXPECT_FALSE(after.poses_known(1));
  std::ofstream(dir / "train/unposed.json") << "{\"a\": 1}";
  auto msg = test::error_of([&] { ChunkDataset bad(dir.string(), "train"); });
  EXPECT_NE(msg.find("unposed.json"), std::string::npos)
      << msg;  // An entry nested 100000 deep is described, not printed (printing it recursed per level; found by
               // fuzzing).
  std::ofstream(dir / "train/unposed.json") << "[" << std::string(100000, '[') << std::string(100000, ']') << "]";
  msg = test::error_of([&] { ChunkDataset bad(dir.string(), "train"); });
  EXPECT_NE(msg.find("entry an array of 1 is not a scene key"), std::string::npos) << msg;
}
