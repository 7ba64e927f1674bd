// The parsed chunks a ChunkDataset keeps in memory: least recently used out first, at least `min_entries` kept and
// more while they fit in `budget_bytes`. A small split then stays whole in memory, so a shuffle over the whole split
// parses each chunk once instead of once per sample; a large one keeps a few ~100 MB chunks, as before.
#pragma once

#include <cstdint>
#include <functional>
#include <future>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

namespace uplvsm::data {

// `tiny`'s 400 rooms (35 MB) fit whole; about five ~100 MB RealEstate10K chunks.
inline constexpr int64_t kChunkCacheBytes = int64_t{512} << 20;

template <class T>
class ChunkCache {
 public:
  using Ptr = std::shared_ptr<const T>;
  // What a read returns: the value and the bytes it holds (what the budget counts).
  using Read = std::function<std::pair<Ptr, int64_t>()>;

  ChunkCache(int min_entries, int64_t budget_bytes) : min_entries_(min_entries), budget_bytes_(budget_bytes) {}

  // The value cached under `name`, read by `read` outside the lock on a miss; callers asking for the same name
  // meanwhile wait for that one read. A read that throws is not cached (a later call retries) and rethrows to all.
  Ptr get(const std::string& name, const Read& read) {
    std::promise<Ptr> promise;
    std::shared_future<Ptr> future;
    uint64_t read_id = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      auto it = slots_.find(name);
      if (it != slots_.end()) {
        future = it->second.value;
        lru_.remove(name);
      } else {
        future = promise.get_future().share();
        read_id = ++reads_;
        slots_[name] = {future, 0, read_id};
      }
      lru_.push_front(name);
      evict_locked();
    }
    if (read_id) fill(name, read_id, read, promise);
    return future.get();
  }

  // Bytes of the values now cached (reads in flight count 0).
  int64_t bytes() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return bytes_;
  }

 private:
  struct Slot {
    std::shared_future<Ptr> value;
    int64_t bytes = 0;  // 0 while the read runs
    uint64_t read_id = 0;
  };

  void fill(const std::string& name, uint64_t read_id, const Read& read, std::promise<Ptr>& promise) {
    try {
      auto [value, size] = read();
      promise.set_value(std::move(value));
      std::lock_guard<std::mutex> lock(mutex_);
      auto it = slots_.find(name);
      if (it == slots_.end() || it->second.read_id != read_id) return;  // evicted while it was read
      it->second.bytes = size;
      bytes_ += size;
      evict_locked();
    } catch (...) {
      promise.set_exception(std::current_exception());
      std::lock_guard<std::mutex> lock(mutex_);
      auto it = slots_.find(name);
      if (it == slots_.end() || it->second.read_id != read_id) return;
      slots_.erase(it);
      lru_.remove(name);
    }
  }

  // Holders of an evicted value keep their shared_ptr alive.
  void evict_locked() {
    while (static_cast<int64_t>(lru_.size()) > min_entries_ && bytes_ > budget_bytes_) {
      auto it = slots_.find(lru_.back());
      bytes_ -= it->second.bytes;
      slots_.erase(it);
      lru_.pop_back();
    }
  }

  const int64_t min_entries_;
  const int64_t budget_bytes_;
  mutable std::mutex mutex_;  // guards slots_, lru_, bytes_ and reads_
  std::map<std::string, Slot> slots_;
  std::list<std::string> lru_;  // most recently used first
  int64_t bytes_ = 0;
  uint64_t reads_ = 0;
};

}  // namespace uplvsm::data
