#include "common/time.h"

#include <gtest/gtest.h>

#include <atomic>
#include <memory>
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

TEST(WallClock, ReadsBothTimelinesFromOneMapping) {
  WallClock clock;
  const ClockReading a = clock.Read();
  const ClockReading b = clock.Read();
  EXPECT_GE(b.mono, a.mono);
  EXPECT_EQ(b.wire - b.mono.time_since_epoch(), a.wire - a.mono.time_since_epoch())
      << "the wall - monotonic offset must not move between two readings without a step";
  EXPECT_EQ(a.ToWire(a.mono + seconds(3)), a.wire + seconds(3));
  EXPECT_EQ(a.FromWire(a.wire - seconds(2)), a.mono - seconds(2));
  EXPECT_EQ(clock.steps(), 0u);
}

/// Time sources a test controls: the monotonic clock moves only when told, and the wall clock
/// is the monotonic clock plus an offset the test can step.
struct ManualSources {
  std::atomic<std::int64_t> mono_ns{1'000'000'000};
  std::atomic<std::int64_t> wall_offset_ns{1'795'000'000'000'000'000};
  WallTimeSources Get() {
    return {[this] { return Time(Duration(mono_ns.load() + wall_offset_ns.load())); },
            [this] { return MonoTime(Duration(mono_ns.load())); }};
  }
};

TEST(WallClock, AWallClockStepMovesWireTimesOnceAndNeverTheControlTimeline) {
  ManualSources src;
  WallClock clock(src.Get());
  const ClockReading r0 = clock.Read();
  src.mono_ns += 500'000'000;
  src.wall_offset_ns += 5'000'000'000;  // NTP steps the wall clock 5 s forwards
  const ClockReading r1 = clock.Read();
  EXPECT_EQ(r1.mono - r0.mono, milliseconds(500))
      << "durations are measured on the monotonic clock";
  EXPECT_EQ(r1.wire - r0.wire, milliseconds(5500)) << "wire time follows the wall clock";
  EXPECT_EQ(clock.steps(), 1u);
  EXPECT_EQ(clock.stepped(), seconds(5));
  src.wall_offset_ns -= 10'000'000'000;  // and 10 s back
  const ClockReading r2 = clock.Read();
  EXPECT_EQ(r2.mono, r1.mono);
  EXPECT_EQ(r2.wire - r1.wire, seconds(-10));
  EXPECT_EQ(clock.steps(), 2u);
  // Within one reading every control instant maps with the same offset.
  EXPECT_EQ(r2.ToWire(r2.mono + seconds(3)) - r2.wire, seconds(3));
}

TEST(WallClock, SmallDifferencesBelowTheStepThresholdDoNotReanchor) {
  ManualSources src;
  WallClock clock(src.Get());
  const ClockReading r0 = clock.Read();
  src.wall_offset_ns += 200'000;  // 0.2 ms: a slew, or reading noise
  const ClockReading r1 = clock.Read();
  EXPECT_EQ(r1.wire - r0.wire, Duration{0});
  EXPECT_EQ(clock.steps(), 0u);
}

TEST(WallClock, ReadsTheSystemClock) {
  WallClock clock;
  const auto before = std::chrono::system_clock::now().time_since_epoch();
  const Time now = clock.Now();
  const auto after = std::chrono::system_clock::now().time_since_epoch();
  // The mapping is anchored at the first reading, within the step threshold of the wall clock.
  EXPECT_GE(now.time_since_epoch(), before - WallClock::kStepThreshold);
  EXPECT_LE(now.time_since_epoch(), after + WallClock::kStepThreshold);
  EXPECT_EQ(clock.kind(), ClockKind::kWall);
}

TEST(WallClock, SleepForWaitsAtLeastThatLongOnTheMonotonicClock) {
  WallClock clock;
  const MonoTime start = clock.Monotonic();
  EXPECT_TRUE(clock.SleepFor(milliseconds(30)));
  EXPECT_GE(clock.Monotonic() - start, milliseconds(30));
  EXPECT_LE(*clock.RealTimeUntil(start + milliseconds(30)), Duration{0});
}

TEST(WallClock, InterruptWakesASleeperWhichReturnsFalse) {
  WallClock clock;
  std::atomic<bool> sleeping{false};
  std::thread sleeper([&] {
    sleeping = true;
    EXPECT_FALSE(clock.SleepFor(std::chrono::hours(1)));
  });
  while (!sleeping) std::this_thread::yield();
  clock.Interrupt();
  sleeper.join();  // returns only because of the interrupt
  EXPECT_TRUE(clock.interrupted());
  EXPECT_FALSE(clock.SleepFor(milliseconds(1)));
}

TEST(WallClock, InterruptCallsTheWaker) {
  WallClock clock;
  int woken = 0;
  clock.SetWaker([&] { ++woken; });
  clock.WakeAt(clock.Monotonic() + seconds(10));
  EXPECT_EQ(woken, 0) << "the wall clock times waits itself";
  clock.Interrupt();
  EXPECT_EQ(woken, 1);
}

TEST(SimClock, StartsAtTheEpochAndFollowsAdvances) {
  SimClock clock;
  EXPECT_FALSE(clock.started());
  EXPECT_EQ(clock.Now(), Time{});
  EXPECT_EQ(clock.AdvanceTo(TimeFromSeconds(5)), SimClock::Advance::kForward);
  EXPECT_TRUE(clock.started());
  EXPECT_EQ(clock.Now(), TimeFromSeconds(5));
  EXPECT_EQ(clock.Monotonic(), MonoFromSeconds(5)) << "both timelines are the simulated time";
  EXPECT_EQ(clock.kind(), ClockKind::kSimulated);
  EXPECT_FALSE(clock.RealTimeUntil(MonoFromSeconds(6)).has_value());
}

TEST(SimClock, IgnoresAndCountsSmallBackwardJumps) {
  SimClock clock;
  ASSERT_EQ(clock.AdvanceTo(TimeFromSeconds(10)), SimClock::Advance::kForward);
  EXPECT_EQ(clock.AdvanceTo(TimeFromSeconds(9.5)), SimClock::Advance::kIgnored);
  EXPECT_EQ(clock.Now(), TimeFromSeconds(10));
  EXPECT_EQ(clock.backward_jumps(), 1u);
  EXPECT_EQ(clock.AdvanceTo(TimeFromSeconds(10)), SimClock::Advance::kForward);  // standing still
  EXPECT_EQ(clock.backward_jumps(), 1u);
  EXPECT_EQ(clock.Read().session, 0u);
}

TEST(SimClock, AJumpBackOfASecondOrMoreIsANewSessionNotAFreeze) {
  SimClock clock;
  clock.AdvanceTo(TimeFromSeconds(100));
  EXPECT_EQ(clock.AdvanceTo(TimeFromSeconds(0)), SimClock::Advance::kRestarted);
  const ClockReading r = clock.Read();
  EXPECT_EQ(r.session, 1u);
  EXPECT_EQ(r.mono, MonoFromSeconds(0)) << "time follows the restarted simulation";
  EXPECT_EQ(clock.restarts(), 1u);
  EXPECT_EQ(clock.AdvanceTo(TimeFromSeconds(0.1)), SimClock::Advance::kForward);
}

TEST(SimClock, ARestartWakesSleepers) {
  SimClock clock;
  clock.AdvanceTo(TimeFromSeconds(100));
  std::atomic<bool> returned{false};
  std::thread sleeper([&] {
    EXPECT_TRUE(clock.SleepUntil(MonoFromSeconds(200)));  // simulated time never gets there
    returned = true;
  });
  // Restart the simulation until the sleeper has been woken by one (it may not be asleep yet
  // at the first).
  for (int restarts = 0; !returned.load(); ++restarts) {
    ASSERT_LT(restarts, 1'000'000);
    clock.AdvanceTo(TimeFromSeconds(100));
    clock.AdvanceTo(TimeFromSeconds(0));
    std::this_thread::yield();
  }
  sleeper.join();
}

TEST(SimClock, SleepUntilWakesOnlyWhenSimulatedTimeReachesTheDeadline) {
  SimClock clock;
  std::atomic<int> stage{0};
  std::thread sleeper([&] {
    EXPECT_TRUE(clock.SleepUntil(MonoFromSeconds(2)));
    EXPECT_GE(clock.Monotonic(), MonoFromSeconds(2)) << "woke before the deadline";
    stage = 1;
  });
  clock.AdvanceTo(TimeFromSeconds(1));
  clock.AdvanceTo(TimeFromSeconds(1.999));
  clock.AdvanceTo(TimeFromSeconds(2));
  sleeper.join();
  EXPECT_EQ(stage.load(), 1);
}

TEST(SimClock, WakeAtCallsTheWakerOnceWhenTheDeadlineComes) {
  SimClock clock;
  clock.AdvanceTo(TimeFromSeconds(1));
  int woken = 0;
  clock.SetWaker([&] { ++woken; });
  clock.WakeAt(MonoFromSeconds(2));
  clock.AdvanceTo(TimeFromSeconds(1.5));
  EXPECT_EQ(woken, 0);
  clock.AdvanceTo(TimeFromSeconds(2));
  EXPECT_EQ(woken, 1);
  clock.AdvanceTo(TimeFromSeconds(3));
  EXPECT_EQ(woken, 1) << "once";
  clock.WakeAt(MonoFromSeconds(2.5));  // already past: at once
  EXPECT_EQ(woken, 2);
  clock.WakeAt(MonoFromSeconds(10));
  clock.AdvanceTo(TimeFromSeconds(0));  // restart
  EXPECT_EQ(woken, 3);
  clock.WakeAt(MonoFromSeconds(10));
  clock.Interrupt();
  EXPECT_EQ(woken, 4);
}

TEST(SimClock, OnceTheWakerIsClearedNoCallOfTheOldOneRunsOrStarts) {
  // A loop's waker points at its waitset; the loop clears the waker, then the waitset goes. A
  // clock that called a copy of the waker outside any lock could call into the freed waitset.
  SimClock clock;
  std::atomic<bool> stop{false};
  std::thread simulator([&] {
    Time t{};
    while (!stop) {
      t += milliseconds(1);
      clock.AdvanceTo(t);
    }
  });
  for (int round = 0; round < 2000; ++round) {
    auto alive = std::make_shared<std::atomic<bool>>(true);
    std::atomic<int> bad{0};
    clock.SetWaker([alive, &bad] {
      if (!alive->load()) ++bad;
    });
    clock.WakeAt(clock.Read().mono + milliseconds(1));
    clock.SetWaker(nullptr);
    alive->store(false);  // the owner goes away
    EXPECT_EQ(bad.load(), 0) << "round " << round;
  }
  stop = true;
  simulator.join();
}

TEST(SimClock, InterruptReleasesSleepers) {
  SimClock clock;
  std::thread sleeper([&] { EXPECT_FALSE(clock.SleepUntil(MonoFromSeconds(100))); });
  clock.Interrupt();
  sleeper.join();
  EXPECT_FALSE(clock.WaitForStart());
}

TEST(Ticker, TicksAtFixedPeriodsOfTheClock) {
  SimClock clock;
  clock.AdvanceTo(TimeFromSeconds(0));
  Ticker ticker(clock, milliseconds(100));
  clock.AdvanceTo(Time(milliseconds(100)));
  ASSERT_TRUE(ticker.WaitNext());
  EXPECT_EQ(ticker.last_tick(), MonoTime(milliseconds(100)));
  std::thread driver([&] {
    for (int i = 11; i <= 30; ++i) clock.AdvanceTo(Time(milliseconds(10 * i)));
  });
  ASSERT_TRUE(ticker.WaitNext());  // sleeps until the clock reaches 200 ms
  EXPECT_GE(clock.Monotonic(), MonoTime(milliseconds(200)));
  driver.join();
  EXPECT_GE(ticker.last_tick(), MonoTime(milliseconds(200)));
  EXPECT_EQ(ticker.last_tick().time_since_epoch() % milliseconds(100), Duration{0});
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
  EXPECT_EQ(ticker.last_tick(), MonoTime(milliseconds(400)));
}

TEST(Ticker, RestartsItsTicksWhenTheClockStartsANewSession) {
  SimClock clock;
  clock.AdvanceTo(TimeFromSeconds(50));
  Ticker ticker(clock, milliseconds(100));
  clock.AdvanceTo(TimeFromSeconds(2));  // the simulation restarted
  // The simulator runs on from 2 s (10 ms of simulated time per millisecond) until the ticker
  // ticks. (A single advance to 2.1 s could come before the ticker first looks at the clock:
  // it would then wait for 2.2 s, which never came, and the test hung.)
  std::atomic<bool> ticked{false};
  std::thread driver([&] {
    for (double t = 2.01; !ticked.load(); t += 0.01) {
      clock.AdvanceTo(TimeFromSeconds(t));
      std::this_thread::sleep_for(milliseconds(1));
    }
  });
  const bool ok = ticker.WaitNext();
  ticked = true;
  driver.join();
  ASSERT_TRUE(ok);
  EXPECT_GE(ticker.last_tick(), MonoFromSeconds(2.1)) << "a period after the restart at least";
  EXPECT_LT(ticker.last_tick(), MonoFromSeconds(40)) << "on the new timeline, not at 50.1 s";
}

}  // namespace
}  // namespace autodrive
