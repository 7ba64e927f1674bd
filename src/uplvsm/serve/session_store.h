// Viewer sessions: one encoded scene each (its scene latents cached so that only the decoder runs per frame), kept
// in a bounded LRU store — a cap on the number of sessions and on the memory they hold, and an idle expiry. Also
// the per-session frame ordering that lets the newest drag request win (stale ones are dropped, not rendered).
#pragma once
#include <atomic>
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include <nlohmann/json.hpp>

#include "uplvsm/serve/viewer_model.h"

namespace uplvsm::serve {

struct Session {
  std::string id;
  std::string name;  // the scene's name or "upload"
  SceneEncoding scene;
  std::vector<std::vector<uint8_t>> input_jpegs;  // the two preprocessed inputs, as shown on the page
  nlohmann::json photos;                          // uploads: each photo's orientation and field of view (to_json)
  double created = 0;

  int64_t bytes() const;
  // Frame requests carry a client sequence number. note_request records it; stale() tells, once a request's turn
  // on the model comes, whether a newer one has arrived meanwhile (then it is dropped).
  void note_request(uint64_t seq);
  bool stale(uint64_t seq) const { return seq < latest_seq_.load(); }

 private:
  std::atomic<uint64_t> latest_seq_{0};
};

struct SessionLimits {
  size_t max_sessions = 8;
  int64_t max_bytes = int64_t{512} << 20;
  double idle_seconds = 1800;
};

class SessionStore {
 public:
  using Clock = std::function<double()>;  // seconds; injectable so tests can expire sessions
  explicit SessionStore(SessionLimits limits, Clock clock = {});

  // Stores the session under a fresh random id (returned), evicting expired sessions, then least recently used
  // ones, until it fits. A session larger than max_bytes on its own is refused (std::length_error).
  std::string add(std::shared_ptr<Session> session);
  // The session, marked as just used; nullptr when unknown or expired.
  std::shared_ptr<Session> get(const std::string& id);
  bool remove(const std::string& id);

  struct Stats {
    size_t sessions = 0;
    int64_t bytes = 0;
    int64_t evicted = 0, expired = 0;
  };
  Stats stats();
  const SessionLimits& limits() const { return limits_; }

 private:
  struct Slot {
    std::shared_ptr<Session> session;
    int64_t bytes = 0;  // as counted when added
    double last_used = 0;
    std::list<std::string>::iterator lru;
  };
  void expire_locked(double now);
  void erase_locked(const std::string& id);

  SessionLimits limits_;
  Clock clock_;
  std::mutex mutex_;
  std::unordered_map<std::string, Slot> slots_;
  std::list<std::string> lru_;  // most recently used first
  int64_t bytes_ = 0, evicted_ = 0, expired_ = 0;
};

// 128 random bits as 32 hex characters (session ids are capabilities: not guessable, not sequential).
std::string random_id();

}  // namespace uplvsm::serve
