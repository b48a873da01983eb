#include "common/time.h"

#include <gtest/gtest.h>

#include <thread>
#include <type_traits>

#include "common/error.h"

namespace autodrive {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

// Reading the computer's clocks directly does not give system time: mixing does not compile.
static_assert(!std::is_convertible_v<std::chrono::system_clock::time_point, Time>);
static_assert(!std::is_convertible_v<std::chrono::steady_clock::time_point, Time>);
static_assert(!std::is_convertible_v<Time, std::chrono::system_clock::time_point>);
static_assert(!std::is_convertible_v<double, Duration>);

TEST(Time, FromSecondsRoundsToTheNearestNanosecond) {
  EXPECT_EQ(FromSeconds(1.5), milliseconds(1500));
  EXPECT_EQ(FromSeconds(0.1).count(), 100'000'000);
  EXPECT_EQ(FromSeconds(-2.0000000004).count(), -2'000'000'000);
  EXPECT_EQ(TimeFromSeconds(3.25).time_since_epoch(), milliseconds(3250));
  EXPECT_DOUBLE_EQ(ToSeconds(milliseconds(250)), 0.25);
}

TEST(Time, FromSecondsRejectsNonFiniteValuesNamingThem) {
  try {
    (void)FromSeconds(std::numeric_limits<double>::quiet_NaN());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "a time in seconds must be finite and below 9.2e9, got nan");
  }
  EXPECT_THROW((void)FromSeconds(1e300), InputError);
}

TEST(Time, ToStringPrintsSecondsWithNanoseconds) {
  EXPECT_EQ(ToString(Time(Duration(12'345'678'901))), "12.345678901s");
  EXPECT_EQ(ToString(Time(Duration(-500'000'000))), "-0.500000000s");
  EXPECT_EQ(ToString(Time{}), "0.000000000s");
}

TEST(WallClock, ReadsTheSystemClock) {
  WallClock clock;
  const auto before = std::chrono::system_clock::now().time_since_epoch();
  const Time now = clock.Now();
  const auto after = std::chrono::system_clock::now().time_since_epoch();
  EXPECT_GE(now.time_since_epoch(), before);
  EXPECT_LE(now.time_since_epoch(), after);
  EXPECT_EQ(clock.kind(), ClockKind::kWall);
}

TEST(WallClock, SleepForWaitsAtLeastThatLong) {
  WallClock clock;
  const auto start = std::chrono::steady_clock::now();
  EXPECT_TRUE(clock.SleepFor(milliseconds(30)));
  EXPECT_GE(std::chrono::steady_clock::now() - start, milliseconds(29));
}

TEST(WallClock, InterruptWakesASleeperWhichReturnsFalse) {
  WallClock clock;
  std::thread waker([&] {
    std::this_thread::sleep_for(milliseconds(20));
    clock.Interrupt();
  });
  const auto start = std::chrono::steady_clock::now();
  EXPECT_FALSE(clock.SleepFor(seconds(30)));
  EXPECT_LT(std::chrono::steady_clock::now() - start, seconds(10));
  waker.join();
  EXPECT_TRUE(clock.interrupted());
  EXPECT_FALSE(clock.SleepFor(milliseconds(1)));
}

TEST(SimClock, StartsAtTheEpochAndFollowsAdvances) {
  SimClock clock;
  EXPECT_FALSE(clock.started());
  EXPECT_EQ(clock.Now(), Time{});
  EXPECT_TRUE(clock.AdvanceTo(TimeFromSeconds(5)));
  EXPECT_TRUE(clock.started());
  EXPECT_EQ(clock.Now(), TimeFromSeconds(5));
  EXPECT_EQ(clock.kind(), ClockKind::kSimulated);
}

TEST(SimClock, IgnoresAndCountsBackwardJumps) {
  SimClock clock;
  ASSERT_TRUE(clock.AdvanceTo(TimeFromSeconds(10)));
  EXPECT_FALSE(clock.AdvanceTo(TimeFromSeconds(9)));
  EXPECT_EQ(clock.Now(), TimeFromSeconds(10));
  EXPECT_EQ(clock.backward_jumps(), 1u);
  EXPECT_TRUE(clock.AdvanceTo(TimeFromSeconds(10)));  // standing still is fine
  EXPECT_EQ(clock.backward_jumps(), 1u);
}

TEST(SimClock, SleepUntilWakesOnlyWhenSimulatedTimeReachesTheDeadline) {
  SimClock clock;
  std::atomic<bool> woke{false};
  std::thread sleeper([&] {
    EXPECT_TRUE(clock.SleepUntil(TimeFromSeconds(2)));
    woke = true;
  });
  clock.AdvanceTo(TimeFromSeconds(1));
  std::this_thread::sleep_for(milliseconds(30));
  EXPECT_FALSE(woke.load()) << "woke before the deadline in simulated time";
  clock.AdvanceTo(TimeFromSeconds(2));
  sleeper.join();
  EXPECT_TRUE(woke.load());
}

TEST(SimClock, DoesNotAdvanceWithWallTime) {
  SimClock clock;
  clock.AdvanceTo(TimeFromSeconds(1));
  std::this_thread::sleep_for(milliseconds(20));
  EXPECT_EQ(clock.Now(), TimeFromSeconds(1));
}

TEST(SimClock, InterruptReleasesSleepers) {
  SimClock clock;
  std::thread sleeper([&] { EXPECT_FALSE(clock.SleepUntil(TimeFromSeconds(100))); });
  std::this_thread::sleep_for(milliseconds(10));
  clock.Interrupt();
  sleeper.join();
}

TEST(Ticker, TicksAtFixedPeriodsOfTheClock) {
  SimClock clock;
  clock.AdvanceTo(TimeFromSeconds(0));
  Ticker ticker(clock, milliseconds(100));
  std::thread driver([&] {
    for (int i = 1; i <= 30; ++i) {
      std::this_thread::sleep_for(milliseconds(1));
      clock.AdvanceTo(Time(milliseconds(10 * i)));
    }
  });
  ASSERT_TRUE(ticker.WaitNext());
  EXPECT_EQ(ticker.last_tick(), Time(milliseconds(100)));
  EXPECT_GE(clock.Now(), Time(milliseconds(100)));
  ASSERT_TRUE(ticker.WaitNext());
  EXPECT_EQ(ticker.last_tick(), Time(milliseconds(200)));
  driver.join();
  EXPECT_EQ(ticker.missed(), 0u);
}

TEST(Ticker, SkipsTicksItWasTooLateForInsteadOfBunchingThem) {
  SimClock clock;
  clock.AdvanceTo(Time{});
  Ticker ticker(clock, milliseconds(100));
  clock.AdvanceTo(Time(milliseconds(350)));  // the loop was busy for 3.5 periods
  ASSERT_TRUE(ticker.WaitNext());            // returns at once for the 100 ms tick
  EXPECT_EQ(ticker.missed(), 2u);            // 200 and 300 are skipped
  clock.AdvanceTo(Time(milliseconds(400)));
  ASSERT_TRUE(ticker.WaitNext());
  EXPECT_EQ(ticker.last_tick(), Time(milliseconds(400)));
}

}  // namespace
}  // namespace autodrive
