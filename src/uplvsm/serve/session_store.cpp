#include "uplvsm/serve/session_store.h"

#include <chrono>
#include <random>
#include <stdexcept>

#include <fmt/format.h>

namespace uplvsm::serve {

int64_t Session::bytes() const {
  int64_t n = scene.bytes() + static_cast<int64_t>(sizeof(Session) + id.size() + name.size());
  for (const auto& j : input_jpegs) n += static_cast<int64_t>(j.size());
  return n;
}

void Session::note_request(uint64_t seq) {
  uint64_t cur = latest_seq_.load();
  while (seq > cur && !latest_seq_.compare_exchange_weak(cur, seq)) {
  }
}

std::string random_id() {
  thread_local std::random_device device;
  std::string id;
  for (int i = 0; i < 4; ++i) id += fmt::format("{:08x}", static_cast<uint32_t>(device()));
  return id;
}

SessionStore::SessionStore(SessionLimits limits, Clock clock) : limits_(limits), clock_(std::move(clock)) {
  if (!clock_)
    clock_ = [] { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); };
}

void SessionStore::erase_locked(const std::string& id) {
  auto it = slots_.find(id);
  if (it == slots_.end()) return;
  bytes_ -= it->second.bytes;
  lru_.erase(it->second.lru);
  slots_.erase(it);
}

void SessionStore::expire_locked(double now) {
  while (!lru_.empty()) {
    const auto& oldest = slots_.at(lru_.back());
    if (now - oldest.last_used <= limits_.idle_seconds) break;
    erase_locked(lru_.back());
    ++expired_;
  }
}

std::string SessionStore::add(std::shared_ptr<Session> session) {
  const int64_t size = session->bytes();
  if (size > limits_.max_bytes)
    throw std::length_error(fmt::format("a session needs {:.1f} MiB, more than the session cache's {:.1f} MiB",
                                        size / 1048576.0, limits_.max_bytes / 1048576.0));
  std::lock_guard<std::mutex> lock(mutex_);
  const double now = clock_();
  expire_locked(now);
  while (!lru_.empty() && (slots_.size() >= limits_.max_sessions || bytes_ + size > limits_.max_bytes)) {
    erase_locked(lru_.back());
    ++evicted_;
  }
  std::string id = random_id();
  while (slots_.count(id)) id = random_id();
  session->id = id;
  session->created = now;
  lru_.push_front(id);
  slots_[id] = Slot{std::move(session), size, now, lru_.begin()};
  bytes_ += size;
  return id;
}

std::shared_ptr<Session> SessionStore::get(const std::string& id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const double now = clock_();
  expire_locked(now);
  auto it = slots_.find(id);
  if (it == slots_.end()) return nullptr;
  it->second.last_used = now;
  lru_.splice(lru_.begin(), lru_, it->second.lru);
  return it->second.session;
}

bool SessionStore::remove(const std::string& id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const bool found = slots_.count(id) > 0;
  erase_locked(id);
  return found;
}

SessionStore::Stats SessionStore::stats() {
  std::lock_guard<std::mutex> lock(mutex_);
  expire_locked(clock_());
  return {slots_.size(), bytes_, evicted_, expired_};
}

}  // namespace uplvsm::serve
