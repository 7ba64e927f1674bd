// The session store's bounds (count, memory, idle expiry, LRU order) and the frame ordering of a session.
#include <gtest/gtest.h>

#include <regex>
#include <set>

#include "test_util.h"
#include "uplvsm/serve/session_store.h"

namespace uplvsm::serve {
namespace {

std::shared_ptr<Session> session_of_bytes(int64_t latent_floats) {
  auto s = std::make_shared<Session>();
  s->scene.latents = torch::zeros({1, latent_floats});
  return s;
}

TEST(SessionStore, EvictsTheLeastRecentlyUsedBeyondTheCount) {
  SessionStore store({2, int64_t{1} << 30, 1e9});
  auto a = store.add(session_of_bytes(10)), b = store.add(session_of_bytes(10));
  ASSERT_TRUE(store.get(a));  // a is now more recent than b
  auto c = store.add(session_of_bytes(10));
  EXPECT_TRUE(store.get(a));
  EXPECT_FALSE(store.get(b));
  EXPECT_TRUE(store.get(c));
  EXPECT_EQ(store.stats().sessions, 2u);
  EXPECT_EQ(store.stats().evicted, 1);
}

TEST(SessionStore, EvictsToStayUnderTheMemoryCapAndRefusesAnOversizedSession) {
  const int64_t one = session_of_bytes(1000)->bytes();
  SessionStore store({100, 2 * one + one / 2, 1e9});
  auto a = store.add(session_of_bytes(1000));
  store.add(session_of_bytes(1000));
  store.add(session_of_bytes(1000));
  EXPECT_FALSE(store.get(a));
  EXPECT_LE(store.stats().bytes, 2 * one + one / 2);
  EXPECT_EQ(store.stats().sessions, 2u);
  EXPECT_THROW(store.add(session_of_bytes(100000)), std::length_error);
}

TEST(SessionStore, IdleSessionsExpire) {
  double now = 0;
  SessionStore store({10, int64_t{1} << 30, 60}, [&] { return now; });
  auto a = store.add(session_of_bytes(10)), b = store.add(session_of_bytes(10));
  now = 50;
  EXPECT_TRUE(store.get(a));
  now = 100;  // b idle for 100 s, a for 50 s
  EXPECT_FALSE(store.get(b));
  EXPECT_TRUE(store.get(a));
  EXPECT_EQ(store.stats().expired, 1);
  now = 1000;
  EXPECT_EQ(store.stats().sessions, 0u);
  EXPECT_EQ(store.stats().bytes, 0);
}

TEST(SessionStore, IdsAreRandomHex) {
  SessionStore store({1000, int64_t{1} << 30, 1e9});
  std::set<std::string> ids;
  for (int i = 0; i < 200; ++i) ids.insert(store.add(session_of_bytes(1)));
  EXPECT_EQ(ids.size(), 200u);
  for (const auto& id : ids) EXPECT_TRUE(std::regex_match(id, std::regex("[0-9a-f]{32}"))) << id;
}

TEST(Session, ANewerRequestMakesOlderOnesStale) {
  Session s;
  s.note_request(3);
  EXPECT_FALSE(s.stale(3));
  s.note_request(1);  // late arrival of an older request: does not move the newest back
  EXPECT_TRUE(s.stale(1));
  EXPECT_FALSE(s.stale(3));
  s.note_request(5);
  EXPECT_TRUE(s.stale(3));
}

}  // namespace
}  // namespace uplvsm::serve
