// A bounded load test of the viewer server on loopback: N clients for M seconds (env UPLVSM_LOAD_CLIENTS,
// UPLVSM_LOAD_SECONDS; default 6 x 20 s) dragging through their scenes as fast as frames come back, beside clients
// that open, use and close sessions. Passes when no request fails and resident memory stays flat after warm-up.
// Prints the figures (frames/s, latency percentiles, memory).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <mutex>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "serve_test_util.h"

namespace uplvsm::test {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

int env_int(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v ? std::max(1, std::atoi(v)) : fallback;
}

TEST(ViewerLoad, ClientsForSecondsWithoutErrorsAndFlatMemory) {
  const int clients = env_int("UPLVSM_LOAD_CLIENTS", 6), seconds = env_int("UPLVSM_LOAD_SECONDS", 20);
  const int churners = 2, warmup_s = std::max(2, seconds / 5);
  serve::ServerOptions options;
  options.sessions.max_sessions = static_cast<size_t>(clients + churners + 2);
  TestServer server(tiny_viewer_model(true), tiny_dataset("serve_load", 4), options);

  std::atomic<bool> stop{false};
  std::atomic<int64_t> frames{0}, superseded{0}, sessions{0}, errors{0};
  std::mutex mutex;
  std::vector<double> latencies_ms;
  std::vector<std::string> failures;
  auto fail = [&](const std::string& what) {
    ++errors;
    std::lock_guard<std::mutex> lock(mutex);
    if (failures.size() < 5) failures.push_back(what);
  };
  auto post = [&](httplib::Client& c, const std::string& path, const json& body) {
    return c.Post(path.c_str(), body.dump(), "application/json");
  };
  // A dragging client: two requests in flight per session, as the page sends them, so that the server's
  // newest-wins dropping is exercised too.
  auto dragger = [&](int id) {
    auto c = server.client();
    auto open = post(c, "/api/sessions", {{"scene", std::to_string(id % 4)}});
    if (!open || open->status != 200) return fail("open session");
    const std::string sid = json::parse(open->body)["session"];
    std::atomic<uint64_t> seq{0};
    auto drag = [&] {
      auto cc = server.client();
      for (int step = 0; !stop; ++step) {
        const double a = 0.02 * (step % 100);
        std::vector<double> pose{0.3 * std::sin(a), 0.1 * std::cos(a), 0.05 * a, 0, std::sin(a / 4), 0,
                                 std::cos(a / 4)};
        const auto t0 = Clock::now();
        auto r = post(cc, "/api/sessions/" + sid + "/frame", {{"pose", pose}, {"space", "real"}, {"seq", ++seq}});
        const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
        if (!r) return fail("frame: no response");
        if (r->status == 204) {
          ++superseded;
          continue;
        }
        if (r->status != 200 || r->body.size() < 100) return fail(fmt::format("frame: {} {}", r->status, r->body));
        ++frames;
        std::lock_guard<std::mutex> lock(mutex);
        latencies_ms.push_back(ms);
      }
    };
    std::thread second(drag);
    drag();
    second.join();
  };
  // A client that keeps opening a scene, rendering a few frames and closing the session again.
  auto churner = [&](int id) {
    auto c = server.client();
    for (int n = 0; !stop; ++n) {
      auto open = post(c, "/api/sessions", {{"scene", std::to_string((id + n) % 4)}});
      if (!open || open->status != 200) return fail("churn: open session");
      auto s = json::parse(open->body);
      const std::string sid = s["session"];
      for (int i = 0; i < 3; ++i) {
        auto r = post(c, "/api/sessions/" + sid + "/frame", {{"pose", s["key_real"][1]}, {"seq", i + 1}});
        if (!r || r->status != 200) return fail("churn: frame");
      }
      if (!c.Get("/api/scenes") || !c.Delete(("/api/sessions/" + sid).c_str())) return fail("churn: close");
      ++sessions;
    }
  };

  std::vector<std::thread> threads;
  for (int i = 0; i < clients; ++i) threads.emplace_back(dragger, i);
  for (int i = 0; i < churners; ++i) threads.emplace_back(churner, i);
  std::this_thread::sleep_for(std::chrono::seconds(warmup_s));
  const int64_t rss_warm = serve::resident_bytes(), frames_warm = frames;
  int64_t rss_max = rss_warm;
  const auto t_warm = Clock::now();
  for (int s = warmup_s; s < seconds; ++s) {
    std::this_thread::sleep_for(std::chrono::seconds(1));
    rss_max = std::max(rss_max, serve::resident_bytes());
  }
  stop = true;
  for (auto& t : threads) t.join();
  const double measured_s = std::chrono::duration<double>(Clock::now() - t_warm).count();
  const int64_t rss_end = serve::resident_bytes();

  std::sort(latencies_ms.begin(), latencies_ms.end());
  auto pct = [&](double p) {
    return latencies_ms.empty() ? 0.0 : latencies_ms[static_cast<size_t>(p * (latencies_ms.size() - 1))];
  };
  std::cout << fmt::format(
      "load: {} dragging clients (2 requests in flight each) + {} session churners, {} s ({} s warm-up)\n"
      "      {} frames ({:.1f} frames/s after warm-up), {} superseded, {} sessions opened and closed, {} errors\n"
      "      frame latency p50 {:.1f} ms, p95 {:.1f} ms, max {:.1f} ms\n"
      "      resident memory after warm-up {:.1f} MiB, max {:.1f} MiB, end {:.1f} MiB\n",
      clients, churners, seconds, warmup_s, frames.load(), (frames - frames_warm) / measured_s, superseded.load(),
      sessions.load(), errors.load(), pct(0.5), pct(0.95), pct(1.0), rss_warm / 1048576.0, rss_max / 1048576.0,
      rss_end / 1048576.0);
  for (const auto& f : failures) ADD_FAILURE() << f;
  EXPECT_EQ(errors.load(), 0);
  EXPECT_GT(frames.load(), 0);
  EXPECT_GT(sessions.load(), 0);
  EXPECT_LT(rss_max - rss_warm, int64_t{48} << 20) << "resident memory grew under a steady load";
  auto stats = server.server->sessions().stats();
  EXPECT_EQ(stats.sessions, static_cast<size_t>(clients));  // the churners closed theirs
}

}  // namespace
}  // namespace uplvsm::test
