// The simulator service's pure rules on a simulated clock, in-process.
#include "vehicle_sim/internal/service_rules.h"

#include <gtest/gtest.h>

#include <chrono>

namespace autodrive::vehicle_sim::internal {
namespace {

using namespace std::chrono_literals;
using Change = CommandWatch::Change;

constexpr Duration kTimeout = 500ms;

TEST(CommandWatch, ACarNeverCommandedIsNeverHeld) {
  CommandWatch watch;
  for (Duration t{0}; t < 10s; t += 10ms) {
    ASSERT_EQ(watch.Update(false, t, kTimeout), Change::kNone);
    ASSERT_FALSE(watch.timed_out());
  }
}

TEST(CommandWatch, HoldsACarOnlyAfterMoreThanTheTimeOutWithoutCommandUntilOneComes) {
  CommandWatch watch;
  EXPECT_EQ(watch.Update(true, 1s, kTimeout), Change::kNone);
  EXPECT_EQ(watch.Update(false, 1s + kTimeout, kTimeout), Change::kNone) << "not more than it";
  EXPECT_FALSE(watch.timed_out());
  EXPECT_EQ(watch.Update(false, 1s + kTimeout + 1ns, kTimeout), Change::kTimedOut);
  EXPECT_TRUE(watch.timed_out());
  EXPECT_EQ(watch.Update(false, 5s, kTimeout), Change::kNone) << "said once";
  EXPECT_TRUE(watch.timed_out());
  EXPECT_EQ(watch.Update(true, 6s, kTimeout), Change::kResumed);
  EXPECT_FALSE(watch.timed_out());
  EXPECT_EQ(watch.Update(true, 6s + 10ms, kTimeout), Change::kNone);
  // The time-out runs from the last command again.
  EXPECT_EQ(watch.Update(false, 6s + 10ms + kTimeout, kTimeout), Change::kNone);
  EXPECT_EQ(watch.Update(false, 6s + 11ms + kTimeout, kTimeout), Change::kTimedOut);
}

TEST(TouchLog, AFirstTouchIsACollisionAndTouchingOnIsTheSameOne) {
  TouchLog log(1s);
  EXPECT_TRUE(log.Touch(0, "bus", 0ms));
  for (Duration t = 10ms; t < 5s; t += 10ms) {
    ASSERT_FALSE(log.Touch(0, "bus", t)) << ToSeconds(t);
    log.Forget(t);
  }
  EXPECT_EQ(log.size(), 1u);
  // Another car, another object: each pair is its own.
  EXPECT_TRUE(log.Touch(1, "bus", 5s));
  EXPECT_TRUE(log.Touch(0, "truck", 5s));
  EXPECT_EQ(log.size(), 3u);
}

TEST(TouchLog, TouchingAgainAfterMoreThanTheGapIsANewCollisionWithinItTheSame) {
  TouchLog log(1s);
  EXPECT_TRUE(log.Touch(0, "bus", 0ms));
  log.Forget(0ms);
  // A contact that flickers: apart for exactly the gap.
  log.Forget(1s);
  EXPECT_EQ(log.size(), 1u);
  EXPECT_FALSE(log.Touch(0, "bus", 1s));
  // Apart for longer: forgotten, then a new collision.
  log.Forget(2s + 1ns);
  EXPECT_EQ(log.size(), 0u);
  EXPECT_TRUE(log.Touch(0, "bus", 3s));
  // Not forgotten (no step called Forget), but apart for longer than the gap: new too.
  EXPECT_TRUE(log.Touch(0, "bus", 5s));
}

}  // namespace
}  // namespace autodrive::vehicle_sim::internal
