#include "uplvsm/data/chunk_cache.h"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

namespace uplvsm::data {
namespace {

// A cache of ints, each "read" holding `bytes` bytes and counted in *reads.
struct Counted {
  ChunkCache<int> cache;
  std::atomic<int> reads{0};
  int64_t bytes;
  Counted(int min_entries, int64_t budget, int64_t bytes_each) : cache(min_entries, budget), bytes(bytes_each) {}
  int get(int i) {
    return *cache.get(std::to_string(i), [&] {
      ++reads;
      return std::make_pair(std::make_shared<const int>(i), bytes);
    });
  }
};

TEST(ChunkCache, ASplitWithinTheBudgetIsReadOnceWhateverTheOrder) {
  Counted c(/*min_entries=*/2, /*budget=*/1000, /*bytes_each=*/100);
  for (int rep = 0; rep < 3; ++rep)
    for (int i : {7, 2, 9, 0, 4, 1, 8, 3, 6, 5}) EXPECT_EQ(c.get(i), i);
  EXPECT_EQ(c.reads.load(), 10);
  EXPECT_EQ(c.cache.bytes(), 1000);
}

TEST(ChunkCache, BeyondTheBudgetTheLeastRecentlyUsedLeaveButTheMinimumStays) {
  Counted c(/*min_entries=*/2, /*budget=*/250, /*bytes_each=*/100);
  for (int i = 0; i < 3; ++i) c.get(i);  // 300 bytes: 0 leaves
  EXPECT_EQ(c.cache.bytes(), 200);
  c.get(1);  // cached: most recently used now
  c.get(0);  // read again; 2 leaves (least recently used)
  EXPECT_EQ(c.reads.load(), 4);
  c.get(1);
  EXPECT_EQ(c.reads.load(), 4);
  c.get(2);
  EXPECT_EQ(c.reads.load(), 5);

  Counted big(/*min_entries=*/2, /*budget=*/0, /*bytes_each=*/100);  // over budget: the minimum still stays
  for (int i : {0, 1, 0, 1}) big.get(i);
  EXPECT_EQ(big.reads.load(), 2);
  EXPECT_EQ(big.cache.bytes(), 200);
}

TEST(ChunkCache, AFailedReadIsNotCachedAndALaterCallRetries) {
  ChunkCache<int> cache(1, 1000);
  int calls = 0;
  auto read = [&] {
    if (++calls == 1) throw std::runtime_error("damaged chunk");
    return std::make_pair(std::make_shared<const int>(5), int64_t{10});
  };
  EXPECT_THROW(cache.get("a", read), std::runtime_error);
  EXPECT_EQ(cache.bytes(), 0);
  EXPECT_EQ(*cache.get("a", read), 5);
  EXPECT_EQ(*cache.get("a", read), 5);
  EXPECT_EQ(calls, 2);
}

TEST(ChunkCache, ThreadsAskingForTheSameChunkShareOneRead) {
  Counted c(/*min_entries=*/1, /*budget=*/1 << 20, /*bytes_each=*/10);
  std::vector<std::thread> threads;
  std::atomic<int> wrong{0};
  for (int t = 0; t < 8; ++t)
    threads.emplace_back([&] {
      for (int i = 0; i < 50; ++i) wrong += c.get(i % 5) != i % 5;
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(wrong.load(), 0);
  EXPECT_EQ(c.reads.load(), 5);
}

}  // namespace
}  // namespace uplvsm::data
