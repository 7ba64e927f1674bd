// Tests of core/progress: the recent rate the bar shows (a run that slows down shows its new speed, not its average)
// and the durations it prints.
#include "uplvsm/core/progress.h"

#include <gtest/gtest.h>

using namespace uplvsm;

namespace {

TEST(RecentRate, IsTheRateOverTheLastWindowNotTheAverage) {
  RecentRate rate;
  rate.window_seconds = 60;
  EXPECT_EQ(rate.per_second(), 0.0) << "no rate from one sample";
  rate.add(0, 0);
  for (int s = 1; s <= 120; ++s) rate.add(s, 10 * s);  // 10 items/s for two minutes
  EXPECT_DOUBLE_EQ(rate.per_second(), 10.0);
  for (int s = 121; s <= 240; ++s) rate.add(s, 1200 + 2 * (s - 120));  // then 2 items/s
  EXPECT_DOUBLE_EQ(rate.per_second(), 2.0) << "the average since the start would be 6";
  EXPECT_LE(rate.samples.size(), 62u);
  EXPECT_GE(rate.samples.back().first - rate.samples.front().first, 60.0);
}

TEST(RecentRate, SpansTheWholeRunUntilItHasAWindowAndStaysShortInAFastLoop) {
  RecentRate rate;
  rate.add(0, 5);  // a resumed run: its start is counted from step 5
  rate.add(1, 6);
  rate.add(2, 9);
  EXPECT_DOUBLE_EQ(rate.per_second(), 2.0);
  for (int i = 1; i <= 100000; ++i) rate.add(2 + i * 1e-3, 9 + i);  // 1000 items/s for 100 s
  EXPECT_NEAR(rate.per_second(), 1000.0, 20.0);
  EXPECT_LE(rate.samples.size(), 130u) << "samples closer than half a second are merged";
  RecentRate stalled;
  stalled.add(0, 0);
  stalled.add(0, 3);  // no time has passed
  EXPECT_EQ(stalled.per_second(), 0.0);
}

TEST(Progress, DurationsAreMinutesOrHours) {
  EXPECT_EQ(format_duration(5), "00:05");
  EXPECT_EQ(format_duration(125), "02:05");
  EXPECT_EQ(format_duration(59.6), "01:00");
  EXPECT_EQ(format_duration(3725), "1:02:05");
  EXPECT_EQ(format_duration(-1), "--:--");
}

}  // namespace
