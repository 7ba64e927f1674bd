// Tests of data/eval_index: the overlap bucket rule, reading the shared split files and the fixture index, null
// entries, round trip and malformed files.
#include "uplvsm/data/eval_index.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "test_util.h"

namespace uplvsm::data {
namespace {

using test::fixture;

TEST(EvalIndex, OverlapBuckets) {
  EXPECT_EQ(overlap_bucket(0.05), "small");
  EXPECT_EQ(overlap_bucket(0.2), "small");
  EXPECT_EQ(overlap_bucket(0.3), "small");
  EXPECT_EQ(overlap_bucket(0.04), "medium");  // below 0.05 falls through to medium
  EXPECT_EQ(overlap_bucket(0.0), "medium");
  EXPECT_EQ(overlap_bucket(0.31), "medium");
  EXPECT_EQ(overlap_bucket(0.55), "medium");
  EXPECT_EQ(overlap_bucket(0.56), "large");
  EXPECT_EQ(overlap_bucket(0.8), "large");
  EXPECT_EQ(overlap_bucket(0.81), "ignore");
  EXPECT_EQ(overlap_bucket(1.0), "ignore");
}

TEST(EvalIndex, ReadsFixtureIndex) {
  UPLVSM_NEEDS_FIXTURES();
  int64_t nulls = -1;
  auto entries = read_eval_index(fixture("re10k_chunks/root/evaluation_index.json"), &nulls);
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_EQ(nulls, 1);
  EXPECT_EQ(entries[0].key, "20e408dd375292a1");
  EXPECT_EQ(entries[0].context, (std::vector<int64_t>{1, 13}));
  EXPECT_EQ(entries[0].target, (std::vector<int64_t>{4, 8, 11}));
  ASSERT_TRUE(entries[0].overlap.has_value());
  EXPECT_DOUBLE_EQ(*entries[0].overlap, 0.708);
  EXPECT_EQ(overlap_bucket(*entries[0].overlap), "large");
}

TEST(EvalIndex, ReadsSharedSplitFiles) {
  UPLVSM_NEEDS_FIXTURES();
  struct Expect {
    const char* file;
    size_t non_null;
    bool overlap;
  };
  // Counts from fixtures/eval_splits/README.md.
  for (const auto& e :
       {Expect{"official_evaluation_index_re10k.json", 6474, false}, Expect{"official_extrapolation.json", 6424, false},
        Expect{"official_overlap_large.json", 1630, true}, Expect{"official_overlap_medium.json", 2568, true},
        Expect{"official_overlap_small.json", 1403, true}, Expect{"noposplat_evaluation_index_re10k.json", 5601, true},
        Expect{"noposplat_evaluation_index_acid.json", 1341, true}}) {
    int64_t nulls = 0;
    auto entries = read_eval_index(fixture(std::string("eval_splits/") + e.file), &nulls);
    EXPECT_EQ(entries.size(), e.non_null) << e.file;
    EXPECT_TRUE(std::is_sorted(entries.begin(), entries.end(),
                               [](const EvalEntry& a, const EvalEntry& b) { return a.key < b.key; }));
    for (const auto& x : entries) {
      EXPECT_EQ(x.context.size(), 2u) << e.file << " " << x.key;
      EXPECT_EQ(x.overlap.has_value(), e.overlap) << e.file << " " << x.key;
    }
  }
  // The official bucket files agree with NoPoSplat's rule.
  for (const auto& [file, bucket] : std::vector<std::pair<std::string, std::string>>{
           {"official_overlap_small.json", "small"},
           {"official_overlap_medium.json", "medium"},  // includes overlaps below 0.05
           {"official_overlap_large.json", "large"}}) {
    for (const auto& x : read_eval_index(fixture("eval_splits/" + file)))
      EXPECT_EQ(overlap_bucket(*x.overlap), bucket) << x.key;
  }
  EXPECT_EQ(read_eval_index(fixture("eval_splits/official_evaluation_index_re10k.json")).size() +
                read_eval_index(fixture("eval_splits/official_extrapolation.json")).size(),
            6474u + 6424u);
}

TEST(EvalIndex, RoundTripAndErrors) {
  auto dir = test::temp_dir("eval_index");
  std::vector<EvalEntry> entries = {{"b", {0, 10}, {2, 5, 7}, 0.42}, {"a", {3, 9}, {4, 5, 6}, std::nullopt}};
  auto path = (dir / "index.json").string();
  write_eval_index(path, entries);
  auto back = read_eval_index(path);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].key, "a");
  EXPECT_FALSE(back[0].overlap.has_value());
  EXPECT_EQ(back[1].target, (std::vector<int64_t>{2, 5, 7}));
  EXPECT_DOUBLE_EQ(*back[1].overlap, 0.42);
  std::ofstream((dir / "bad.json").string()) << R"({"k": {"context": [1], "target": []}})";
  try {
    read_eval_index((dir / "bad.json").string());
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.json"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("key k"), std::string::npos) << e.what();
  }
  std::ofstream((dir / "neg.json").string()) << R"({"k": {"context": [1, -2], "target": [1]}})";
  EXPECT_THROW(read_eval_index((dir / "neg.json").string()), std::runtime_error);
  std::ofstream((dir / "trunc.json").string()) << R"({"k": {"context": [1, 2], "tar)";
  EXPECT_THROW(read_eval_index((dir / "trunc.json").string()), std::runtime_error);
  EXPECT_THROW(read_eval_index((dir / "missing.json").string()), std::runtime_error);
  // A frame value nested 100000 deep is described, not printed (printing recursed once per level and overflowed
  // the stack, found by fuzzing).
  std::ofstream((dir / "deep.json").string())
      << R"({"k": {"context": [)" << std::string(100000, '[') << std::string(100000, ']') << R"(, 1], "target": [1]}})";
  const auto msg = test::error_of([&] { read_eval_index((dir / "deep.json").string()); });
  EXPECT_NE(msg.find("non-frame value an array of 1"), std::string::npos) << msg;
  test::remove_tree(dir);
}

}  // namespace
}  // namespace uplvsm::data
