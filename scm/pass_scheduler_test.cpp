#include "scm/pass_scheduler.h"

#include <gtest/gtest.h>

#include <chrono>

namespace autodrive::scm {
namespace {

using std::chrono::microseconds;
using std::chrono::milliseconds;
using std::chrono::minutes;
using std::chrono::seconds;

// A start well away from MonoTime{} (which means "never" to the scheduler).
const MonoTime kT0 = MonoTime{} + seconds(1000);

// Deadlines of the other parts far away, so that only the scheduler's own count.
const OtherDeadlines kIdle{MonoTime::max(), MonoTime::max(), MonoTime::max()};

TEST(PassScheduler, SpatIsDueAtStartThenEveryPeriodWithoutBunchingAfterALatePass) {
  PassScheduler s;
  s.Start(kT0);
  EXPECT_TRUE(s.SpatDue(kT0));
  s.SpatSent(kT0);
  EXPECT_FALSE(s.SpatDue(kT0 + milliseconds(99)));
  EXPECT_TRUE(s.SpatDue(kT0 + milliseconds(100)));
  // Sent 350 ms late: the periods missed are skipped, the next is on the period's grid.
  s.SpatSent(kT0 + milliseconds(450));
  EXPECT_FALSE(s.SpatDue(kT0 + milliseconds(499)));
  EXPECT_TRUE(s.SpatDue(kT0 + milliseconds(500)));
  // Sent slightly late: the next still keeps the grid.
  s.SpatSent(kT0 + milliseconds(530));
  EXPECT_FALSE(s.SpatDue(kT0 + milliseconds(599)));
  EXPECT_TRUE(s.SpatDue(kT0 + milliseconds(600)));
}

TEST(PassScheduler, RequestsWaitForSpatExceptTheFewItGivesWayToOncePerDeadline) {
  PassScheduleParams params;
  params.requests_before_spat = 3;
  PassScheduler s(params);
  s.Start(kT0);
  s.SpatSent(kT0);
  const MonoTime before = kT0 + milliseconds(50);
  const MonoTime due = kT0 + milliseconds(100);
  // Before SPaT's deadline: any number.
  for (int i = 0; i < 100; ++i) {
    ASSERT_TRUE(s.MayHandleRequest(before));
    s.CountRequest(before);
  }
  EXPECT_FALSE(s.MayHandleRequest(due));
  // SPaT's filling gives way once: three requests, then SPaT.
  ASSERT_TRUE(s.MayGiveWay());
  s.GiveWay();
  EXPECT_FALSE(s.MayGiveWay());
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(s.MayHandleRequest(due)) << i;
    s.CountRequest(due);
  }
  EXPECT_FALSE(s.MayHandleRequest(due));
  // Once sent, the next deadline may give way again, and requests flow until it.
  s.SpatSent(due);
  EXPECT_TRUE(s.MayGiveWay());
  EXPECT_TRUE(s.MayHandleRequest(due + milliseconds(1)));
}

TEST(PassScheduler, RequestsGivenWayToAreNotSpentBeforeTheDeadline) {
  PassScheduler s;
  s.Start(kT0);
  s.GiveWay();  // at kT0, SPaT due
  s.SpatSent(kT0);
  // SpatSent forgets what was left; before the next deadline nothing is counted.
  s.CountRequest(kT0 + milliseconds(10));
  EXPECT_FALSE(s.MayHandleRequest(kT0 + milliseconds(100)));
}

TEST(PassScheduler, HousekeepingEverySecondPruningOnItsPeriodFromTheFirstStart) {
  PassScheduleParams params;
  params.prune_period = minutes(10);
  PassScheduler s(params);
  s.Start(kT0);
  EXPECT_TRUE(s.HousekeepingDue(kT0));
  EXPECT_TRUE(s.Housekeep(kT0));  // prunes at the first start
  EXPECT_FALSE(s.HousekeepingDue(kT0 + milliseconds(999)));
  ASSERT_TRUE(s.HousekeepingDue(kT0 + seconds(1)));
  EXPECT_FALSE(s.Housekeep(kT0 + seconds(1)));
  // A new city: housekeeping at once, pruning still on its period.
  s.Start(kT0 + seconds(2));
  EXPECT_TRUE(s.HousekeepingDue(kT0 + seconds(2)));
  EXPECT_FALSE(s.Housekeep(kT0 + seconds(2)));
  EXPECT_TRUE(s.Housekeep(kT0 + minutes(10)));
  // A new session of the timeline: everything at once, pruning included.
  s.Restart(kT0 + minutes(11));
  EXPECT_TRUE(s.SpatDue(kT0 + minutes(11)));
  EXPECT_TRUE(s.Housekeep(kT0 + minutes(11)));
}

TEST(PassScheduler, TheLoopWakesForTheEarliestDeadline) {
  PassScheduler s;
  s.Start(kT0);
  s.SpatSent(kT0);
  // Housekeeping not done yet: it is due at once.
  EXPECT_EQ(s.NextDeadline(kT0, kIdle), kT0);
  EXPECT_TRUE(s.Housekeep(kT0));
  s.EndPass(kT0, kIdle);
  // The tick (20 ms) comes before SPaT (100 ms) and housekeeping (1 s).
  EXPECT_EQ(s.NextDeadline(kT0, kIdle), kT0 + milliseconds(20));
  // Supervision, the device table or a controller due sooner wins.
  EXPECT_EQ(s.NextDeadline(kT0, {MonoTime::max(), kT0 + milliseconds(5), MonoTime::max()}),
            kT0 + milliseconds(5));
  EXPECT_EQ(s.NextDeadline(kT0, {MonoTime::max(), MonoTime::max(), kT0 + milliseconds(7)}),
            kT0 + milliseconds(7));
  EXPECT_EQ(s.NextDeadline(kT0, {kT0 + milliseconds(3), MonoTime::max(), MonoTime::max()}),
            kT0 + milliseconds(3));
  // A controller due at or before the pass is left to the tick (no spinning).
  EXPECT_EQ(s.NextDeadline(kT0, {kT0, MonoTime::max(), MonoTime::max()}), kT0 + milliseconds(20));
  // The tick moves past a late pass on its grid.
  s.EndPass(kT0 + milliseconds(75), kIdle);
  EXPECT_EQ(s.NextDeadline(kT0 + milliseconds(75), kIdle), kT0 + milliseconds(80));
}

TEST(PassScheduler, APassWellAfterItsDeadlineIsAStall) {
  PassScheduler s;
  s.Start(kT0);
  EXPECT_FALSE(s.Stall(kT0 + seconds(5)));  // no deadline waited for yet
  s.SpatSent(kT0);
  (void)s.Housekeep(kT0);
  s.EndPass(kT0, kIdle);  // waits for the tick at kT0 + 20 ms
  EXPECT_FALSE(s.Stall(kT0 + milliseconds(20)));
  EXPECT_FALSE(s.Stall(kT0 + milliseconds(120)));  // 100 ms late: a busy machine, not a stall
  ASSERT_TRUE(s.Stall(kT0 + milliseconds(121)));
  EXPECT_EQ(*s.Stall(kT0 + milliseconds(121)), milliseconds(101));
  // Lateness counts from the deadline, however small; a pass woken before it is not late.
  EXPECT_EQ(s.Lateness(kT0 + milliseconds(10)), Duration{0});
  EXPECT_EQ(s.Lateness(kT0 + milliseconds(23)), milliseconds(3));
}

TEST(LoopTimes, QuantilesOverTheLastPassesOnly) {
  LoopTimes t;
  EXPECT_EQ(t.WorkQuantile(0.99), Duration{0});  // nothing yet
  for (int i = 1; i <= 100; ++i) t.Note(microseconds(i), microseconds(1000 + i));
  EXPECT_EQ(t.size(), 100u);
  EXPECT_EQ(t.WorkQuantile(0.5), microseconds(50));
  EXPECT_EQ(t.WorkQuantile(0.99), microseconds(99));
  EXPECT_EQ(t.WorkQuantile(1.0), microseconds(100));
  EXPECT_EQ(t.LateQuantile(0.99), microseconds(1099));
  // A full window of short passes pushes the long ones out.
  for (std::size_t i = 0; i < LoopTimes::kWindow; ++i) t.Note(microseconds(2), microseconds(0));
  EXPECT_EQ(t.size(), LoopTimes::kWindow);
  EXPECT_EQ(t.WorkQuantile(1.0), microseconds(2));
  EXPECT_EQ(t.LateQuantile(0.99), Duration{0});
}

TEST(StallWatch, ReportsLongStallsAtMostOncePerPeriod) {
  StallWatch w;
  EXPECT_FALSE(w.Note(milliseconds(249), kT0));  // short: neither reported nor counted
  const auto first = w.Note(milliseconds(250), kT0);
  ASSERT_TRUE(first);
  EXPECT_EQ(*first, 1u);
  EXPECT_FALSE(w.Note(seconds(1), kT0 + minutes(1)));
  EXPECT_FALSE(w.Note(milliseconds(100), kT0 + minutes(2)));
  EXPECT_FALSE(w.Note(seconds(2), kT0 + minutes(9)));
  const auto second = w.Note(milliseconds(300), kT0 + minutes(10));
  ASSERT_TRUE(second);
  EXPECT_EQ(*second, 3u);  // the two long ones held back, and this one
}

}  // namespace
}  // namespace autodrive::scm
