#include "scm/core/controller.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <random>
#include <set>

#include "common/config.h"
#include "common/test_support.h"
#include "scm/core/conflict_monitor.h"

namespace autodrive::scm {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using ::testing::HasSubstr;

/// A shipped city with the short clearances these tests' figures were written for (yellow 3 s,
/// red clearance and start-up all red 2 s), made legal by declaring a clearing vehicle fast
/// enough for them (docs/scm.md, "Clearances"); the shipped cities' own are 7 s.
City WithTwoSecondClearances(const char* name,
                             const std::vector<std::pair<std::string, std::string>>& more = {}) {
  const auto dir = test::SourceDir() / "config/cities";
  std::string text = config::ReadFile(dir / name);
  const auto edit = [&](const std::string& from, const std::string& to) {
    for (auto at = text.find(from); at != std::string::npos; at = text.find(from, at)) {
      text.replace(at, from.size(), to);
      at += to.size();
    }
  };
  edit("red_clearance_s: 7.0", "red_clearance_s: 2.0");
  edit("all_red_s: 7.0", "all_red_s: 2.0");
  edit("{name: nigel, length_m: 0.318, speed_mps: 0.2}",
       "{name: fast, length_m: 0.318, speed_mps: 1}");
  for (const auto& [from, to] : more) edit(from, to);
  return LoadCityString(text, name, dir);
}

const City& DrivingSchool() {
  static const City city = WithTwoSecondClearances("driving_school.yaml");
  return city;
}
const City& SmallTown() {
  static const City city = WithTwoSecondClearances("small_town.yaml");
  return city;
}

/// The day clock of a test: local midnight at the control timeline's origin, so the cycle of a
/// fixed plan (anchored at local midnight plus its offset) lines up with multiples of the cycle;
/// `minute` chooses the scheduled plan independently.
DayClock Day(MonoTime now, int minute) {
  return DayClock{minute, now.time_since_epoch() % std::chrono::hours(24)};
}

constexpr int kNoon = 12 * 60;     // the day plan (fixed)
constexpr int kEvening = 20 * 60;  // the evening plan (actuated)

/// A start time where the day plan's cycle (52 s) begins, so its phases line up with the clock.
MonoTime CycleStart() { return MonoTime(seconds(52 * 1000)); }

/// Drives a controller in fixed ticks and checks every output with a monitor.
struct Rig {
  explicit Rig(const IntersectionModel& x, MonoTime start = CycleStart())
      : model(x), now(start), controller(x, start), monitor(x, start) {}
  /// Steps until `until`, with `calls`; fails the test on any monitor violation.
  void RunTo(MonoTime until, const std::vector<bool>& calls = {}, int minute = kNoon) {
    while (now < until) {
      now = std::min(until, now + tick);
      controller.Step(now, calls, Day(now, minute));
      const auto v = monitor.CheckAndRecord(now, controller.aspects());
      ASSERT_FALSE(v) << v->message;
    }
  }
  void RunFor(Duration d, const std::vector<bool>& calls = {}, int minute = kNoon) {
    RunTo(now + d, calls, minute);
  }
  Aspect Of(std::size_t g) const { return controller.aspects()[g]; }
  const IntersectionModel& model;
  MonoTime now;
  Duration tick = milliseconds(100);
  IntersectionController controller;
  ConflictMonitor monitor;
};

TEST(Controller, StartsWithFlashThenAllRedThenThePlan) {
  Rig rig(DrivingSchool().intersections[0]);
  EXPECT_EQ(rig.Of(0), Aspect::kFlashingRed);
  rig.RunFor(milliseconds(2900));
  for (std::size_t g = 0; g < 4; ++g) EXPECT_EQ(rig.Of(g), Aspect::kFlashingRed);
  rig.RunFor(milliseconds(100));  // 3 s: start-up flash over
  for (std::size_t g = 0; g < 4; ++g) EXPECT_EQ(rig.Of(g), Aspect::kRed);
  EXPECT_EQ(rig.controller.stage(), Stage::kAllRed);
  rig.RunFor(milliseconds(1900));
  EXPECT_EQ(rig.Of(0), Aspect::kRed);
  rig.RunFor(milliseconds(100));  // 5 s: all red over; the cycle is at 5 s, in phase 1's green
  EXPECT_EQ(rig.Of(0), Aspect::kGreen);
  EXPECT_EQ(rig.controller.effective_mode(), Mode::kFixed);
  EXPECT_EQ(rig.controller.plan().name, "day");
}

TEST(Controller, AStartUpEndingInTheCyclesClearanceStaysRedToTheNextGreenAndKeepsToTheCycle) {
  // Started 5 s into the cycle, the start-up (3 s flash, 2 s all red) ends at 10 s, inside
  // phase 1's yellow and red clearance (8 to 13 s). Starting phase 2 then would put the whole
  // cycle 3 s early for good: fixed-time greens can shorten, not grow.
  const MonoTime c = CycleStart();
  Rig rig(DrivingSchool().intersections[0], c + seconds(5));
  rig.RunTo(c + seconds(10) + milliseconds(100));
  EXPECT_EQ(rig.controller.stage(), Stage::kAllRed);
  EXPECT_EQ(rig.controller.Signals(rig.now)[1].next_green, c + seconds(13))
      << "SPaT says when the wait ends";
  rig.RunTo(c + seconds(13) - milliseconds(100));
  for (std::size_t g = 0; g < 4; ++g) EXPECT_EQ(rig.Of(g), Aspect::kRed);
  rig.RunTo(c + seconds(13));
  EXPECT_EQ(rig.Of(1), Aspect::kGreen);
  rig.RunTo(c + seconds(21));
  EXPECT_EQ(rig.Of(1), Aspect::kYellow) << "a whole green, on the cycle";
  rig.RunTo(c + seconds(52 + 13) - milliseconds(100));
  EXPECT_EQ(rig.Of(1), Aspect::kRed);
  rig.RunTo(c + seconds(52 + 13));
  EXPECT_EQ(rig.Of(1), Aspect::kGreen) << "the next cycle on time";
}

/// The codes of `events` for phase `phase` (flash and plan codes left out), in order.
std::vector<std::uint16_t> PhaseCodes(const std::vector<HiresEvent>& events, std::uint16_t phase) {
  std::vector<std::uint16_t> codes;
  for (const HiresEvent& e : events) {
    if (e.code <= hires::kPreemptionForceOff && e.param == phase) codes.push_back(e.code);
  }
  return codes;
}

/// The time of the first event with `code` for `phase` at or after `from`.
MonoTime At(const std::vector<HiresEvent>& events, std::uint16_t code, std::uint16_t phase,
            MonoTime from = MonoTime::min()) {
  for (const HiresEvent& e : events) {
    if (e.code == code && e.param == phase && e.at >= from) return e.at;
  }
  ADD_FAILURE() << "no code " << code << " for phase " << phase;
  return MonoTime::min();
}

TEST(ControllerHires, AFixedCycleLogsEachPhasesIntervalsInTheIndianaOrderAtTheirTimes) {
  const auto& x = DrivingSchool().intersections[0];
  Rig rig(x);
  rig.RunTo(CycleStart() + seconds(52 * 2));
  const std::vector<HiresEvent> events = rig.controller.TakeHiresEvents();
  EXPECT_FALSE(rig.controller.has_hires_events());
  // The unit: start-up flash and the plan it starts with (day, the first), then out of flash
  // when the all red starts (at 3 s).
  ASSERT_GE(events.size(), 3u);
  EXPECT_EQ(events[0],
            (HiresEvent{CycleStart(), hires::kUnitFlashStatusChange, hires::kFlashStartup}));
  EXPECT_EQ(events[1], (HiresEvent{CycleStart(), hires::kCoordPatternChange, 1}));
  EXPECT_EQ(events[2], (HiresEvent{CycleStart() + seconds(3), hires::kUnitFlashStatusChange,
                                   hires::kNotFlash}));
  // Phase 2 (north), served twice in full: on, green, check (fixed time: every phase is on max
  // recall, so a conflicting call waits from the start), min complete, force off (fixed time
  // keeps to its cycle), green termination, yellow, end of yellow, red clearance, its end,
  // inactive.
  const std::vector<std::uint16_t> cycle{0, 1, 2, 3, 6, 7, 8, 9, 10, 11, 12};
  std::vector<std::uint16_t> twice = cycle;
  twice.insert(twice.end(), cycle.begin(), cycle.end());
  EXPECT_EQ(PhaseCodes(events, 2), twice);
  // Its times: green at 13 s of the cycle for 8 s, yellow 3 s, red clearance 2 s.
  const MonoTime green = At(events, hires::kPhaseBeginGreen, 2, CycleStart() + seconds(52));
  EXPECT_EQ(green, CycleStart() + seconds(52 + 13));
  EXPECT_EQ(At(events, hires::kPhaseMinComplete, 2, green), green + seconds(5));
  EXPECT_EQ(At(events, hires::kPhaseBeginYellow, 2, green), green + seconds(8));
  EXPECT_EQ(At(events, hires::kPhaseEndYellow, 2, green), green + seconds(11));
  EXPECT_EQ(At(events, hires::kPhaseBeginRedClearance, 2, green), green + seconds(11));
  EXPECT_EQ(At(events, hires::kPhaseEndRedClearance, 2, green), green + seconds(13));
  EXPECT_EQ(At(events, hires::kPhaseInactive, 2, green), green + seconds(13));
}

TEST(ControllerHires, ActuatedGreensLogTheirCheckAndGapOutOrMaxOutAndFlashItsCause) {
  const auto& x = DrivingSchool().intersections[0];
  Rig rig(x);
  const std::vector<bool> none(4, false);
  rig.RunFor(seconds(5), none, kEvening);
  ASSERT_EQ(rig.Of(0), Aspect::kGreen);
  (void)rig.controller.TakeHiresEvents();
  // A call on the south: phase 1 (east) has a conflicting call (check) and gaps out at its min
  // green, having no call of its own; phase 4 (south) then runs on its own call until calls
  // come everywhere, and maxes out 15 s after that (its max 1 from the check).
  std::vector<bool> south(4, false);
  south[3] = true;
  rig.RunFor(seconds(18), south, kEvening);
  ASSERT_EQ(rig.Of(3), Aspect::kGreen);
  rig.RunFor(seconds(20), std::vector<bool>(4, true), kEvening);
  const std::vector<HiresEvent> events = rig.controller.TakeHiresEvents();
  const std::vector<std::uint16_t> phase1 = PhaseCodes(events, 1);
  ASSERT_GE(phase1.size(), 5u);
  EXPECT_EQ(std::vector<std::uint16_t>(phase1.begin(), phase1.begin() + 5),
            (std::vector<std::uint16_t>{2, 3, 4, 7, 8}))
      << "check, min complete, gap out, green termination, yellow";
  const std::vector<std::uint16_t> phase4 = PhaseCodes(events, 4);
  ASSERT_GE(phase4.size(), 6u);
  EXPECT_EQ(std::vector<std::uint16_t>(phase4.begin(), phase4.begin() + 4),
            (std::vector<std::uint16_t>{0, 1, 3, 2}))
      << "on, green, min complete, then the check when the other calls come";
  EXPECT_EQ(phase4[4], hires::kPhaseMaxOut);
  EXPECT_EQ(At(events, hires::kPhaseMaxOut, 4), At(events, hires::kPhaseCheck, 4) + seconds(15));
  // A fail-safe: the phase in service goes inactive and the unit logs its flash's cause.
  rig.controller.FailSafe(rig.now, "test");
  const std::vector<HiresEvent> flash = rig.controller.TakeHiresEvents();
  ASSERT_EQ(flash.size(), 2u);
  EXPECT_EQ(flash[0].code, hires::kPhaseInactive);
  EXPECT_EQ(flash[1],
            (HiresEvent{rig.now, hires::kUnitFlashStatusChange, hires::kFlashFaultMonitor}));
}

TEST(Controller, StartUpWaitsForTheDevices) {
  Rig rig(DrivingSchool().intersections[0]);
  rig.controller.SetDevicesReady(false);
  rig.RunFor(seconds(10));
  EXPECT_EQ(rig.controller.stage(), Stage::kStartupFlash);
  rig.controller.SetDevicesReady(true);
  rig.RunFor(milliseconds(100));
  EXPECT_EQ(rig.controller.stage(), Stage::kAllRed);
}

TEST(Controller, FixedTimeRunsThePhasesInTurnKeepingToTheCycle) {
  Rig rig(DrivingSchool().intersections[0]);
  rig.RunTo(CycleStart() + seconds(52));  // settle into the cycle
  // Cycle position 0 (phase 1 green from 0 to 8 s, yellow to 11, all red to 13, phase 2 ...).
  const MonoTime c = CycleStart() + seconds(52);
  rig.RunTo(c + milliseconds(100));
  EXPECT_EQ(rig.Of(0), Aspect::kGreen);
  rig.RunTo(c + milliseconds(7900));
  EXPECT_EQ(rig.Of(0), Aspect::kGreen);
  rig.RunTo(c + seconds(8));
  EXPECT_EQ(rig.Of(0), Aspect::kYellow);
  rig.RunTo(c + seconds(11));
  EXPECT_EQ(rig.Of(0), Aspect::kRed);
  EXPECT_EQ(rig.Of(1), Aspect::kRed);
  rig.RunTo(c + seconds(13));
  EXPECT_EQ(rig.Of(1), Aspect::kGreen);
  rig.RunTo(c + seconds(52 + 1));
  EXPECT_EQ(rig.Of(0), Aspect::kGreen);
  EXPECT_EQ(rig.Of(3), Aspect::kRed);
}

TEST(Controller, FixedTimePredictionsMatchWhatHappens) {
  // At a few moments of the cycle (so that groups are seen green, yellow and red), record each
  // group's predictions, then check them against the changes that follow.
  std::set<Aspect> seen;
  for (const int at_s : {60, 63, 70}) {
    SCOPED_TRACE(at_s);
    Rig rig(DrivingSchool().intersections[0]);
    rig.RunTo(CycleStart() + seconds(at_s));
    const auto predicted = rig.controller.Signals(rig.now);
    std::vector<std::optional<MonoTime>> changed(4);
    std::vector<std::optional<MonoTime>> green_at(4);
    std::vector<bool> left_green(4, false);
    const auto start = rig.controller.aspects();
    seen.insert(start.begin(), start.end());
    // A whole cycle (72 s) and more: a group green now is green again within it.
    while (rig.now < CycleStart() + seconds(at_s + 80)) {
      rig.RunFor(milliseconds(100));
      for (std::size_t g = 0; g < 4; ++g) {
        if (!changed[g] && rig.Of(g) != start[g]) changed[g] = rig.now;
        left_green[g] = left_green[g] || rig.Of(g) != Aspect::kGreen;
        if (!green_at[g] && left_green[g] && rig.Of(g) == Aspect::kGreen) green_at[g] = rig.now;
      }
    }
    for (std::size_t g = 0; g < 4; ++g) {
      SCOPED_TRACE(g);
      const auto& s = predicted[g];
      ASSERT_TRUE(changed[g]);
      ASSERT_TRUE(s.likely_end);
      EXPECT_EQ(*s.likely_end, *changed[g]);
      EXPECT_LE(s.min_end, *changed[g]);
      if (s.max_end) {
        EXPECT_GE(*s.max_end, *changed[g]);
      }
      // The next green, of a red group and of a green or yellow one (after its red) alike.
      ASSERT_TRUE(s.next_green) << "aspect " << static_cast<int>(start[g]);
      ASSERT_TRUE(green_at[g]);
      EXPECT_EQ(*s.next_green, *green_at[g]) << "aspect " << static_cast<int>(start[g]);
    }
  }
  EXPECT_TRUE(seen.contains(Aspect::kGreen) && seen.contains(Aspect::kYellow) &&
              seen.contains(Aspect::kRed))
      << "the moments checked show every aspect";
}

TEST(Controller, ManualHoldsUntilAdvanceAndHonoursMinGreen) {
  Rig rig(DrivingSchool().intersections[0]);
  rig.RunTo(CycleStart() + seconds(6));  // phase 1 green since 5 s
  ASSERT_EQ(rig.Of(0), Aspect::kGreen);
  ASSERT_TRUE(rig.controller.SetMode(Mode::kManual, rig.now).ok);
  rig.RunFor(seconds(60));
  EXPECT_EQ(rig.Of(0), Aspect::kGreen);  // held
  const auto r = rig.controller.Advance(rig.now);
  EXPECT_TRUE(r.ok) << r.message;
  rig.RunFor(milliseconds(100));
  EXPECT_EQ(rig.Of(0), Aspect::kYellow);
  rig.RunFor(seconds(5));
  EXPECT_EQ(rig.Of(1), Aspect::kGreen);
  // Advance right after a green starts waits for the min green.
  const auto early = rig.controller.Advance(rig.now);
  EXPECT_THAT(early.message, HasSubstr("advancing when min green is served, in"));
  rig.RunFor(seconds(4));
  EXPECT_EQ(rig.Of(1), Aspect::kGreen);
  rig.RunFor(seconds(1));
  EXPECT_EQ(rig.Of(1), Aspect::kYellow);
}

TEST(Controller, AdvanceOutsideManualIsRefused) {
  Rig rig(DrivingSchool().intersections[0]);
  rig.RunFor(seconds(6));
  const auto r = rig.controller.Advance(rig.now);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.message, "advance needs manual mode; driving_school_crossing runs fixed");
}

// Phase controls (NTCIP's phase control group): docs/controller.md, "Phase controls".
using Kind = PhaseControlKind;

TEST(ControllerPhaseControls, AFixedTimeOmitGivesItsTimeToThePhaseBeforeAndKeepsTheCycle) {
  const auto& x = DrivingSchool().intersections[0];
  Rig rig(x);
  // The day plan: each phase 8 s green, 3 s yellow, 2 s red clearance; cycle 52 s.
  const MonoTime c = CycleStart() + seconds(52);
  rig.RunTo(c - seconds(1));  // phase 4's red clearance
  (void)rig.controller.TakeHiresEvents();
  const auto r = rig.controller.Control(Kind::kOmit, 2, seconds(52), rig.now);
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_EQ(r.message, "driving_school_crossing omit phase 2 of plan day for 52.0 s");
  rig.RunTo(c + seconds(1));
  const auto predicted = rig.controller.Signals(rig.now);
  EXPECT_EQ(predicted[0].likely_end, c + seconds(21)) << "phase 1 keeps phase 2's 13 s";
  EXPECT_EQ(predicted[2].next_green, c + seconds(26)) << "phase 3 on its time";
  EXPECT_FALSE(predicted[2].max_end) << "an omit's end may bring phase 2 back first";
  bool north_green = false;
  while (rig.now < c + seconds(21) - milliseconds(100)) {
    rig.RunFor(milliseconds(100));
    north_green = north_green || rig.Of(1) == Aspect::kGreen;
    ASSERT_EQ(rig.Of(0), Aspect::kGreen);
  }
  rig.RunTo(c + seconds(21));
  EXPECT_EQ(rig.Of(0), Aspect::kYellow);
  rig.RunTo(c + seconds(26) - milliseconds(100));
  EXPECT_EQ(rig.Of(2), Aspect::kRed);
  rig.RunTo(c + seconds(26));
  EXPECT_EQ(rig.Of(2), Aspect::kGreen);
  rig.RunTo(c + seconds(52));
  EXPECT_FALSE(north_green);
  EXPECT_TRUE(rig.controller.controls().empty()) << "expired at c + 51 s";
  // The next cycle serves phase 2 on its time again.
  rig.RunTo(c + seconds(52 + 13));
  EXPECT_EQ(rig.Of(1), Aspect::kGreen);
  const auto events = rig.controller.TakeHiresEvents();
  EXPECT_EQ(At(events, hires::kPhaseOmitOn, 2), c - seconds(1));
  EXPECT_EQ(At(events, hires::kPhaseOmitOff, 2), c + seconds(51));
}

TEST(ControllerPhaseControls, AnActuatedOmitIgnoresItsPhasesCallsAndAnOperatorCallIsServed) {
  const auto& x = DrivingSchool().intersections[0];
  Rig rig(x);
  const std::vector<bool> none(4, false);
  rig.RunFor(seconds(5), none, kEvening);
  ASSERT_EQ(rig.Of(0), Aspect::kGreen);
  ASSERT_TRUE(rig.controller.Control(Kind::kOmit, 4, seconds(60), rig.now).ok);
  std::vector<bool> south(4, false);
  south[3] = true;
  rig.RunFor(seconds(20), south, kEvening);
  EXPECT_EQ(rig.Of(0), Aspect::kGreen) << "the south's call is for an omitted phase: it rests";
  // The operator calls phase 3 (west): east gaps out, west is served, south still waits.
  ASSERT_TRUE(rig.controller.Control(Kind::kCall, 3, seconds(10), rig.now).ok);
  rig.RunFor(milliseconds(100), south, kEvening);
  EXPECT_EQ(rig.Of(0), Aspect::kYellow);
  rig.RunFor(seconds(5), south, kEvening);
  EXPECT_EQ(rig.Of(2), Aspect::kGreen);
  EXPECT_EQ(rig.Of(3), Aspect::kRed);
  // The omit ends (60 s after it was set): the south's call is served.
  rig.RunFor(seconds(40), south, kEvening);
  EXPECT_TRUE(rig.controller.controls().empty());
  EXPECT_EQ(rig.Of(3), Aspect::kGreen);
  const auto events = rig.controller.TakeHiresEvents();
  EXPECT_EQ(At(events, hires::kPhaseCallDropped, 3),
            At(events, hires::kPhaseCallRegistered, 3) + seconds(10));
  EXPECT_EQ(At(events, hires::kPhaseOmitOff, 4), At(events, hires::kPhaseOmitOn, 4) + seconds(60));
}

TEST(ControllerPhaseControls, AHoldKeepsAGreenUntilReleasedAndAForceOffEndsOneAtItsMinGreen) {
  const auto& x = DrivingSchool().intersections[0];
  Rig rig(x);
  const MonoTime c = CycleStart() + seconds(52);
  rig.RunTo(c + seconds(1));
  ASSERT_TRUE(rig.controller.Control(Kind::kHold, 1, seconds(60), rig.now).ok);
  rig.RunTo(c + seconds(20));
  EXPECT_EQ(rig.Of(0), Aspect::kGreen) << "held past its 8 s";
  EXPECT_FALSE(rig.controller.Signals(rig.now)[0].max_end) << "a hold has no known end";
  EXPECT_GE(rig.controller.Signals(rig.now)[1].min_end, rig.now + seconds(5))
      << "the clearance is still ahead of a red group";
  const auto released = rig.controller.ClearControl(Kind::kHold, 1, rig.now);
  ASSERT_TRUE(released.ok) << released.message;
  rig.RunFor(milliseconds(100));
  EXPECT_EQ(rig.Of(0), Aspect::kYellow);
  // Actuated, with calls everywhere: a force-off on phase 1 ends each of its greens at its min
  // green (5 s) rather than at its max, logged as a force-off.
  Rig act(x);
  const std::vector<bool> all(4, true);
  act.RunFor(seconds(6), all, kEvening);
  ASSERT_EQ(act.Of(0), Aspect::kGreen);
  ASSERT_TRUE(act.controller.Control(Kind::kForceOff, 1, seconds(600), act.now).ok);
  const MonoTime green = act.now - seconds(1);
  act.RunTo(green + seconds(5) - milliseconds(100), all, kEvening);
  EXPECT_EQ(act.Of(0), Aspect::kGreen);
  act.RunTo(green + seconds(5), all, kEvening);
  EXPECT_EQ(act.Of(0), Aspect::kYellow);
  const auto events = act.controller.TakeHiresEvents();
  EXPECT_EQ(At(events, hires::kPhaseForceOff, 1), green + seconds(5));
  EXPECT_EQ(rig.controller.TakeHiresEvents().back().code, hires::kPhaseBeginYellow);
}

TEST(ControllerPhaseControls, RefusesWhatCannotBeDoneAndOmitsDoNotStopAnEmergencyVehicle) {
  const auto& x = DrivingSchool().intersections[0];
  Rig rig(x);
  rig.RunTo(CycleStart() + seconds(6));
  auto& c = rig.controller;
  EXPECT_EQ(c.Control(Kind::kOmit, 0, seconds(1), rig.now).message,
            "plan day of driving_school_crossing has phases 1 to 4; there is no phase 0");
  EXPECT_FALSE(c.Control(Kind::kHold, 5, seconds(1), rig.now).ok);
  EXPECT_EQ(c.Control(Kind::kPedCall, 1, seconds(1), rig.now).message,
            "phase 1 of plan day serves no crosswalk: driving_school_crossing has no pedestrian "
            "signals");
  EXPECT_FALSE(c.Control(Kind::kCall, 1, seconds(0), rig.now).ok);
  EXPECT_FALSE(c.Control(Kind::kCall, 1, std::chrono::hours(25), rig.now).ok);
  EXPECT_EQ(c.ClearControl(Kind::kHold, 2, rig.now).message,
            "driving_school_crossing has no hold on phase 2 of plan day");
  for (std::size_t k = 2; k <= 4; ++k)
    ASSERT_TRUE(c.Control(Kind::kOmit, k, seconds(60), rig.now).ok);
  EXPECT_EQ(c.Control(Kind::kOmit, 1, seconds(60), rig.now).message,
            "omitting phase 1 would leave plan day of driving_school_crossing no phase to serve");
  // Phase 1 alone is served: it rests in green past its cycle.
  rig.RunFor(seconds(30));
  EXPECT_EQ(rig.Of(0), Aspect::kGreen);
  // A bus asking for an omitted phase is refused; an ambulance is served.
  const ServiceRequest bus{"bus", 1, false, 3, rig.now + seconds(20), seconds(5)};
  EXPECT_EQ(c.Request(bus, rig.now).reason,
            "the operator omits every phase of plan day with that group");
  const ServiceRequest ambulance{"ambulance", 2, true, 3, rig.now + seconds(20), seconds(5)};
  ASSERT_EQ(c.Request(ambulance, rig.now).status, RequestStatus::kGranted);
  rig.RunFor(seconds(15));
  EXPECT_EQ(rig.Of(3), Aspect::kGreen);
}

TEST(Controller, ActuatedRestsInGreenAndGapsOutToACall) {
  const auto& x = DrivingSchool().intersections[0];
  Rig rig(x);
  const std::vector<bool> none(4, false);
  rig.RunFor(seconds(5), none, kEvening);  // start-up; the first phase begins
  ASSERT_EQ(rig.Of(0), Aspect::kGreen);
  rig.RunFor(seconds(30), none, kEvening);
  EXPECT_EQ(rig.Of(0), Aspect::kGreen);  // no calls anywhere: rests
  // A call on the south approach: east's green gaps out (no call of its own).
  std::vector<bool> south(4, false);
  south[3] = true;
  rig.RunFor(milliseconds(100), south, kEvening);
  EXPECT_EQ(rig.Of(0), Aspect::kYellow);
  rig.RunFor(seconds(5), south, kEvening);
  EXPECT_EQ(rig.Of(3), Aspect::kGreen);  // phases 2 and 3 skipped
  EXPECT_EQ(rig.Of(1), Aspect::kRed);
  // Calls on its own approach extend it up to max green (15 s) even with a call waiting: 15 s
  // from the first conflicting call (NTCIP phaseMaximum1), the east call's first step.
  std::vector<bool> both(4, false);
  both[3] = both[0] = true;
  rig.RunFor(milliseconds(100), both, kEvening);
  const MonoTime conflicting = rig.now;
  rig.RunTo(conflicting + seconds(15) - milliseconds(100), both, kEvening);
  EXPECT_EQ(rig.Of(3), Aspect::kGreen);
  rig.RunTo(conflicting + seconds(15), both, kEvening);
  EXPECT_EQ(rig.Of(3), Aspect::kYellow);
}

TEST(Controller, TheMaxTimerRunsOnlyWhileAConflictingCallWaits) {
  // NTCIP phaseMaximum1: "the maximum length of time this phase may be held Green in the
  // presence of a serviceable conflicting call. In the absence of a serviceable conflicting call
  // the Maximum Green timer shall be held reset".
  const auto& x = DrivingSchool().intersections[0];
  Rig rig(x);
  std::vector<bool> own(4, false);
  own[0] = true;
  rig.RunFor(seconds(5), own, kEvening);
  ASSERT_EQ(rig.Of(0), Aspect::kGreen);
  rig.RunFor(seconds(30), own, kEvening);  // extended by its own calls, none elsewhere
  EXPECT_EQ(rig.Of(0), Aspect::kGreen);
  std::vector<bool> both = own;
  both[2] = true;
  rig.RunFor(seconds(10), both, kEvening);  // a conflicting call for 10 s, then gone
  rig.RunFor(seconds(10), own, kEvening);   // ... the timer held reset
  EXPECT_EQ(rig.Of(0), Aspect::kGreen);
  rig.RunFor(milliseconds(100), both, kEvening);  // back: 15 s from here, not 5
  const MonoTime from = rig.now;
  EXPECT_EQ(rig.controller.Signals(rig.now)[0].max_end,
            from + seconds(15) + x.priority.max_extension)
      << "SPaT's latest end counts from the conflicting call";
  rig.RunTo(from + seconds(15) - milliseconds(100), both, kEvening);
  EXPECT_EQ(rig.Of(0), Aspect::kGreen);
  rig.RunTo(from + seconds(15), both, kEvening);
  EXPECT_EQ(rig.Of(0), Aspect::kYellow) << "maxed out";
}

TEST(Controller, TheNextPhaseIsChosenWhenTheGreenEndsOrAgainThroughTheClearanceAsConfigured) {
  // East (phase 1) rests in green; a south call gaps it out, so the next phase chosen is
  // south's (4). Calls on north (2) and west (3) come during the yellow: deciding at the end of
  // the green keeps 4; deciding again through the clearance (SUMO's NEMA controller) serves 3,
  // the nearest called on 4's side of the middle barrier (1, 2 | 3, 4), not 2. SPaT's min_end
  // for the groups that may still be chosen is the clearance's end.
  for (const auto decision : {NextPhaseDecision::kEndOfGreen, NextPhaseDecision::kEndOfClearance}) {
    IntersectionModel x = DrivingSchool().intersections[0];
    x.next_phase_decision = decision;
    const bool again = decision == NextPhaseDecision::kEndOfClearance;
    SCOPED_TRACE(again ? "end of clearance" : "end of green");
    Rig rig(x);
    std::vector<bool> calls(4, false);
    rig.RunFor(seconds(20), calls, kEvening);
    ASSERT_EQ(rig.Of(0), Aspect::kGreen);
    calls[3] = true;
    rig.RunFor(milliseconds(100), calls, kEvening);
    ASSERT_EQ(rig.Of(0), Aspect::kYellow);
    const MonoTime clearance_end =
        rig.now + x.groups[0].timing.yellow + x.groups[0].timing.red_clearance;
    const auto signals = rig.controller.Signals(rig.now);
    EXPECT_EQ(signals[3].min_end, clearance_end);
    if (again) {
      EXPECT_EQ(signals[2].min_end, clearance_end) << "west may still be chosen";
    } else {
      EXPECT_GT(signals[2].min_end, clearance_end) << "only after south's green";
    }
    calls[1] = calls[2] = true;
    rig.RunFor(seconds(1), calls, kEvening);
    EXPECT_EQ(rig.controller.Signals(rig.now)[2].min_end,
              again ? clearance_end : signals[2].min_end);
    rig.RunTo(clearance_end, calls, kEvening);
    EXPECT_EQ(rig.Of(2), again ? Aspect::kGreen : Aspect::kRed);
    EXPECT_EQ(rig.Of(3), again ? Aspect::kRed : Aspect::kGreen);
    EXPECT_EQ(rig.Of(1), Aspect::kRed) << "north lies across the middle barrier";
    EXPECT_EQ(rig.Of(0), Aspect::kRed);
  }
}

TEST(Controller, GreenRestAsSumoForgetsThePassageWhenConflictingCallsBreakOffAfterAWait) {
  // East green with its own call; a south call waits from 6 s, east's own call ends at 8 s, the
  // south call breaks off at 8.3 s and comes back at 8.8 s. NTCIP: east's passage (2 s) runs
  // out at about 10 s whatever south does. SUMO's green rest: at 8.3 s the time since its slid
  // start less the min green (2.4 s) is above the passage left (1.6 s), so it forgets the
  // passage and ends as south comes back.
  for (const auto rest : {GreenRest::kNtcip, GreenRest::kSumo}) {
    IntersectionModel x = DrivingSchool().intersections[0];
    x.green_rest = rest;
    const bool sumo = rest == GreenRest::kSumo;
    SCOPED_TRACE(sumo ? "sumo" : "ntcip");
    Rig rig(x);
    std::vector<bool> calls(4, false);
    calls[0] = true;
    rig.RunFor(seconds(20), calls, kEvening);
    ASSERT_EQ(rig.Of(0), Aspect::kGreen);
    // A green of its own from here: all red to east's next green, its call kept on.
    std::vector<bool> south = calls;
    south[3] = true;
    rig.RunFor(seconds(20), south, kEvening);  // ... east maxes out, south served
    rig.RunFor(seconds(30), calls, kEvening);  // ... and east again, resting with its call
    ASSERT_EQ(rig.Of(0), Aspect::kGreen);
    ASSERT_EQ(rig.controller.stage(), Stage::kGreen);
    const MonoTime t0 = rig.now;  // long since its green began: its rest start has slid along
    rig.RunTo(t0 + seconds(6), calls, kEvening);
    rig.RunTo(t0 + seconds(8), south, kEvening);
    std::vector<bool> only_south(4, false);
    only_south[3] = true;
    rig.RunTo(t0 + milliseconds(8300), only_south, kEvening);
    rig.RunTo(t0 + milliseconds(8800), std::vector<bool>(4, false), kEvening);
    ASSERT_EQ(rig.Of(0), Aspect::kGreen);
    rig.RunTo(t0 + milliseconds(8900), only_south, kEvening);
    EXPECT_EQ(rig.Of(0), sumo ? Aspect::kYellow : Aspect::kGreen);
    rig.RunTo(t0 + milliseconds(9500), only_south, kEvening);
    EXPECT_EQ(rig.Of(0), sumo ? Aspect::kYellow : Aspect::kGreen) << "the passage runs to ~10 s";
  }
}

TEST(Controller, PlanChangesAtTheEndOfAGreen) {
  Rig rig(DrivingSchool().intersections[0]);
  rig.RunTo(CycleStart() + seconds(6));
  ASSERT_EQ(rig.Of(0), Aspect::kGreen);
  const auto r = rig.controller.SetPlan("night", rig.now);
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_EQ(r.message, "driving_school_crossing runs plan night from the next safe point");
  rig.RunFor(milliseconds(100));
  // Not before min green (5 s from 5 s): yellow at 10 s, red at 13 s, flash at 15 s.
  EXPECT_EQ(rig.Of(0), Aspect::kGreen);
  rig.RunTo(CycleStart() + seconds(10));
  EXPECT_EQ(rig.Of(0), Aspect::kYellow);
  rig.RunTo(CycleStart() + seconds(15));
  EXPECT_EQ(rig.Of(0), Aspect::kFlashingRed);
  EXPECT_EQ(rig.controller.effective_mode(), Mode::kFlash);
  // Back to the schedule: out of flash through all red.
  ASSERT_TRUE(rig.controller.SetPlan("auto", rig.now).ok);
  rig.RunFor(milliseconds(100));
  EXPECT_EQ(rig.Of(0), Aspect::kRed);
  EXPECT_EQ(rig.controller.stage(), Stage::kAllRed);
  EXPECT_FALSE(rig.controller.SetPlan("nope", rig.now).ok);
  EXPECT_EQ(rig.controller.SetPlan("nope", rig.now).message,
            "driving_school_crossing has no plan \"nope\" (plans: day, evening, night, off, or "
            "auto)");
}

TEST(Controller, PreemptionServesTheEmergencyMovementSafelyAndReportsIt) {
  Rig rig(DrivingSchool().intersections[0]);
  rig.RunTo(CycleStart() + seconds(6));
  ASSERT_EQ(rig.Of(0), Aspect::kGreen);
  ServiceRequest req{"nigel_2", 7, true, 2, rig.now + seconds(20)};
  const auto u = rig.controller.Request(req, rig.now);
  EXPECT_EQ(u.status, RequestStatus::kGranted);
  ASSERT_TRUE(u.expected_green);
  EXPECT_TRUE(rig.controller.preemption_active());
  // Group 1's min green ends at 10 s; yellow 3 s, all red 2 s: west green at 15 s, skipping north.
  rig.RunTo(CycleStart() + seconds(10));
  EXPECT_EQ(rig.Of(0), Aspect::kYellow);
  rig.RunTo(CycleStart() + seconds(15));
  EXPECT_EQ(rig.Of(2), Aspect::kGreen);
  EXPECT_EQ(rig.Of(1), Aspect::kRed);
  EXPECT_EQ(*u.expected_green, CycleStart() + seconds(15));
  // Held past its max green until the vehicle's end time (26 s), then completed.
  rig.RunTo(CycleStart() + seconds(25));
  EXPECT_EQ(rig.Of(2), Aspect::kGreen);
  rig.RunTo(CycleStart() + seconds(27));
  const auto updates = rig.controller.TakeRequestUpdates();
  ASSERT_EQ(updates.size(), 1u);
  EXPECT_EQ(updates[0].status, RequestStatus::kCompleted);
  EXPECT_EQ(updates[0].vehicle, "nigel_2");
  // The log: call input on and entry (no delay) at the request, the preemption force off of
  // east, dwell as west turns green, exit and call input off at its end.
  std::vector<std::pair<std::uint16_t, double>> preempt;
  for (const HiresEvent& e : rig.controller.hires_events()) {
    if ((e.code >= 100 && e.code < 120) || e.code == hires::kPreemptionForceOff) {
      preempt.push_back({e.code, ToSeconds(e.at - CycleStart())});
    }
  }
  const std::vector<std::pair<std::uint16_t, double>> expected{
      {hires::kPreemptCallInputOn, 6.0},  {hires::kPreemptEntryStarted, 6.0},
      {hires::kPreemptionForceOff, 10.0}, {hires::kPreemptBeginDwell, 15.0},
      {hires::kPreemptBeginExit, 26.0},   {hires::kPreemptCallInputOff, 26.0}};
  EXPECT_EQ(preempt, expected);
}

TEST(Controller, APreemptionGrantedInTheStartUpsAllRedIsServedAsItEndsNotAfterTheCycle) {
  // The all red (3 to 5 s after the start) ends at 10 s of the cycle, in phase 1's clearance;
  // without a request it stays red to phase 2's green at 13 s. A pre-emption for west (phase 3)
  // is served as soon as the all red ends instead.
  const MonoTime c = CycleStart();
  Rig rig(DrivingSchool().intersections[0], c + seconds(5));
  rig.RunTo(c + seconds(9));
  ASSERT_EQ(rig.controller.stage(), Stage::kAllRed);
  const auto u =
      rig.controller.Request(ServiceRequest{"nigel_2", 8, true, 2, rig.now + seconds(5)}, rig.now);
  ASSERT_EQ(u.status, RequestStatus::kGranted) << u.reason;
  rig.RunTo(c + seconds(10));
  EXPECT_EQ(rig.Of(2), Aspect::kGreen);
  EXPECT_EQ(rig.Of(1), Aspect::kRed);
}

TEST(Controller, ARequestServedAfterItsEndStillGetsItsDurationOfGreen) {
  Rig rig(DrivingSchool().intersections[0]);
  rig.RunTo(CycleStart() + seconds(6));
  ASSERT_EQ(rig.Of(0), Aspect::kGreen);
  // The vehicle is already due (end = now) and needs 6 s of green (more than the 5 s minimum
  // dwell); west turns green at 15 s.
  ServiceRequest req{"nigel_3", 1, true, 2, rig.now, seconds(6)};
  ASSERT_EQ(rig.controller.Request(req, rig.now).status, RequestStatus::kGranted);
  rig.RunTo(CycleStart() + seconds(15));
  EXPECT_EQ(rig.Of(2), Aspect::kGreen);
  EXPECT_EQ(rig.controller.preempt_state(), PreemptState::kDwell);
  rig.RunTo(CycleStart() + milliseconds(20900));
  EXPECT_EQ(rig.Of(2), Aspect::kGreen);
  EXPECT_TRUE(rig.controller.TakeRequestUpdates().empty());
  rig.RunTo(CycleStart() + milliseconds(21100));
  EXPECT_EQ(rig.Of(2), Aspect::kYellow);
  EXPECT_EQ(rig.controller.preempt_state(), PreemptState::kExitStarted);
  const auto updates = rig.controller.TakeRequestUpdates();
  ASSERT_EQ(updates.size(), 1u);
  EXPECT_EQ(updates[0].status, RequestStatus::kCompleted);
  // The exit phase (the one after west in the sequence: phase 4, south) turns green after the
  // clearance, and the pre-emption is over.
  rig.RunTo(CycleStart() + milliseconds(26100));
  EXPECT_EQ(rig.Of(3), Aspect::kGreen);
  EXPECT_EQ(rig.controller.preempt_state(), PreemptState::kNotActive);
  EXPECT_FALSE(rig.controller.preemption_active());
}

TEST(Controller, RequestsAreRefusedInFlashAndManual) {
  Rig rig(DrivingSchool().intersections[0]);
  const auto in_startup = rig.controller.Request({"nigel_1", 1, true, 0, rig.now}, rig.now);
  EXPECT_EQ(in_startup.status, RequestStatus::kRejected);
  EXPECT_EQ(in_startup.reason, "driving_school_crossing is in flash");
  rig.RunFor(seconds(6));
  ASSERT_TRUE(rig.controller.SetMode(Mode::kManual, rig.now).ok);
  const auto in_manual = rig.controller.Request({"nigel_1", 1, false, 1, rig.now}, rig.now);
  EXPECT_EQ(in_manual.reason, "driving_school_crossing is under manual control");
}

TEST(Controller, FailSafeLatchesUntilReset) {
  Rig rig(DrivingSchool().intersections[0]);
  rig.RunTo(CycleStart() + seconds(6));
  rig.controller.FailSafe(rig.now, "devices lost: signal_1");
  rig.RunFor(milliseconds(100));
  for (std::size_t g = 0; g < 4; ++g) EXPECT_EQ(rig.Of(g), Aspect::kFlashingRed);
  EXPECT_TRUE(rig.controller.latched());
  ASSERT_TRUE(rig.controller.SetPlan("day", rig.now).ok);
  rig.RunFor(seconds(30));
  EXPECT_EQ(rig.Of(0), Aspect::kFlashingRed);  // a plan does not clear the latch
  const auto r = rig.controller.Reset(rig.now);
  EXPECT_TRUE(r.ok);
  rig.RunFor(milliseconds(100));
  EXPECT_EQ(rig.Of(0), Aspect::kRed);
  rig.RunFor(seconds(2));
  EXPECT_FALSE(rig.controller.latched());
  EXPECT_EQ(rig.controller.Reset(rig.now).message,
            "driving_school_crossing is not in fail-safe flash; nothing to reset");
}

// --- The conflict monitor on its own ---

struct MonitorRig {
  MonitorRig() : model(DrivingSchool().intersections[0]), now(CycleStart()), monitor(model, now) {
    Show({Aspect::kRed, Aspect::kRed, Aspect::kRed, Aspect::kRed}, seconds(0));
  }
  std::optional<Violation> Show(std::vector<Aspect> a, Duration after) {
    now += after;
    return monitor.CheckAndRecord(now, a);
  }
  const IntersectionModel& model;
  MonoTime now;
  ConflictMonitor monitor;
};
constexpr Aspect R = Aspect::kRed, Y = Aspect::kYellow, G = Aspect::kGreen,
                 F = Aspect::kFlashingRed;

TEST(ConflictMonitor, LatchesWhenTwoConflictingGroupsAreGreen) {
  MonitorRig m;
  const auto v = m.Show({G, G, R, R}, seconds(3));
  ASSERT_TRUE(v);
  EXPECT_EQ(v->rule, "conflict");
  EXPECT_EQ(v->message,
            "driving_school_crossing: group 1 (east) green and group 2 (north) green conflict; "
            "rule: conflicting groups are never green or yellow together");
}

TEST(ConflictMonitor, CatchesShortYellowShortGreenAndShortAllRed) {
  {
    MonitorRig m;
    ASSERT_FALSE(m.Show({G, R, R, R}, seconds(2)));
    const auto v = m.Show({Y, R, R, R}, seconds(4));
    ASSERT_TRUE(v);
    EXPECT_EQ(v->rule, "short_green");
    EXPECT_THAT(v->message, HasSubstr("green lasted 4.000 s of its min green 5.000 s"));
  }
  {
    MonitorRig m;
    ASSERT_FALSE(m.Show({G, R, R, R}, seconds(2)));
    ASSERT_FALSE(m.Show({Y, R, R, R}, seconds(5)));
    const auto v = m.Show({R, R, R, R}, milliseconds(2900));
    ASSERT_TRUE(v);
    EXPECT_EQ(v->rule, "short_yellow");
  }
  {
    MonitorRig m;
    ASSERT_FALSE(m.Show({G, R, R, R}, seconds(2)));
    ASSERT_FALSE(m.Show({Y, R, R, R}, seconds(5)));
    ASSERT_FALSE(m.Show({R, R, R, R}, seconds(3)));
    const auto v = m.Show({R, G, R, R}, milliseconds(1900));
    ASSERT_TRUE(v);
    EXPECT_EQ(v->rule, "short_all_red");
    EXPECT_THAT(v->message, HasSubstr("group 2 (north) turned green while conflicting group 1 "
                                      "(east) was red for 1.900 s, under its red clearance"));
    EXPECT_FALSE(m.Show({R, G, R, R}, milliseconds(100)));  // 2 s: fine
  }
  {
    MonitorRig m;
    ASSERT_FALSE(m.Show({G, R, R, R}, seconds(2)));
    const auto v = m.Show({R, R, R, R}, seconds(10));
    ASSERT_TRUE(v);
    EXPECT_EQ(v->rule, "green_not_to_yellow");
  }
}

TEST(ConflictMonitor, AllowsGoingToFlashAtAnyTimeButNotGreenStraightFromFlash) {
  MonitorRig m;
  ASSERT_FALSE(m.Show({G, R, R, R}, seconds(2)));
  EXPECT_FALSE(m.Show({F, F, F, F}, seconds(1)));
  const auto v = m.Show({G, F, F, F}, seconds(1));
  ASSERT_TRUE(v);
  EXPECT_EQ(v->rule, "green_not_from_red");
}

// --- Property test: random operator commands, plans, requests and faults ---

/// The safety rules, checked from the outside on the controller's raw output.
class RuleChecker {
 public:
  RuleChecker(const IntersectionModel& x, MonoTime now)
      : x_(x),
        last_(x.groups.size(), Aspect::kFlashingRed),
        since_(x.groups.size(), now),
        red_since_(x.groups.size()) {}
  /// Returns a description of the first broken rule, or "".
  std::string Check(MonoTime now, const std::vector<Aspect>& a) {
    const std::size_t n = a.size();
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t j = i + 1; j < n; ++j) {
        if (x_.conflicts[i][j] && IsGo(a[i]) && IsGo(a[j])) return "conflicting go";
      }
    }
    for (std::size_t g = 0; g < n; ++g) {
      if (a[g] == last_[g]) continue;
      const auto& t = x_.groups[g].timing;
      const bool flash = IsFlashing(a[g]) || a[g] == Aspect::kOff;
      if (last_[g] == Aspect::kGreen && !flash && now - since_[g] < t.min_green)
        return "short green";
      if (last_[g] == Aspect::kYellow && !flash && now - since_[g] < t.yellow)
        return "short yellow";
      if (last_[g] == Aspect::kGreen && !flash && a[g] != Aspect::kYellow)
        return "green not to yellow";
      if (a[g] == Aspect::kGreen) {
        if (last_[g] != Aspect::kRed) return "green not from red";
        for (std::size_t h = 0; h < n; ++h) {
          if (x_.conflicts[g][h] &&
              (!red_since_[h] || now - *red_since_[h] < x_.groups[h].timing.red_clearance)) {
            return "short all-red";
          }
        }
      }
    }
    for (std::size_t g = 0; g < n; ++g) {
      if (a[g] != last_[g]) {
        last_[g] = a[g];
        since_[g] = now;
        red_since_[g] = a[g] == Aspect::kRed ? std::optional<MonoTime>(now) : std::nullopt;
      }
    }
    return "";
  }

 private:
  const IntersectionModel& x_;
  std::vector<Aspect> last_;
  std::vector<MonoTime> since_;
  std::vector<std::optional<MonoTime>> red_since_;
};

void RunRandomSequences(const City& city, int sequences, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> tick_ms(20, 600);
  std::uniform_int_distribution<int> percent(0, 99);
  long long ticks = 0;
  long long lazy_steps = 0;
  int latches = 0;
  int grants = 0;
  for (int s = 0; s < sequences; ++s) {
    const auto& x = city.intersections[static_cast<std::size_t>(s) % city.intersections.size()];
    MonoTime now =
        MonoTime(seconds(1'000'000 + std::uniform_int_distribution<int>(0, 86'400)(rng)));
    const auto modes = {Mode::kAuto,   Mode::kFixed, Mode::kActuated,
                        Mode::kManual, Mode::kFlash, Mode::kDark};
    const Mode first_mode = *(modes.begin() + percent(rng) % 6);
    const std::optional<std::size_t> first_plan =
        percent(rng) < 50
            ? std::optional<std::size_t>(static_cast<std::size_t>(percent(rng)) % x.plans.size())
            : std::nullopt;
    IntersectionController c(x, now, first_mode, first_plan);
    // The same controller stepped only when it is due or its inputs changed, as the daemon
    // does (next_wake): it must show exactly the same at every tick.
    IntersectionController lazy(x, now, first_mode, first_plan);
    bool lazy_due = true;  // an input changed since its last step
    ConflictMonitor monitor(x, now);
    RuleChecker checker(x, now);
    int minute = std::uniform_int_distribution<int>(0, 1439)(rng);
    std::vector<bool> calls(x.groups.size(), false);
    const int steps = 200;
    // The latest min_end SPaT promised each group since it last changed: a change before it is
    // allowed only into fail-safe flash (the intersection latched), whatever commands came.
    std::vector<std::optional<MonoTime>> promised(x.groups.size());
    std::vector<GroupSignal> prev;
    std::vector<std::string> trace;  // the last steps, printed when a rule breaks
    auto note = [&](std::string what) {
      if (trace.size() >= 40) trace.erase(trace.begin());
      std::string aspects;
      for (Aspect a : c.aspects()) aspects += std::string(ToString(a)) + " ";
      trace.push_back(fmt::format("t={:.2f} {} -> stage {} [{}] preempt {} / lazy {}",
                                  ToSeconds(now) - 1e6, what, ToString(c.stage()), aspects,
                                  ToString(c.preempt_state()), ToString(lazy.preempt_state())));
    };
    auto dump = [&] {
      std::string out;
      for (const auto& t : trace) out += "\n  " + t;
      return out;
    };
    std::optional<std::pair<std::string, std::uint32_t>> granted;  // the last request granted
    // Every command goes to both controllers.
    auto both = [&](auto&& command) {
      auto result = command(c);
      (void)command(lazy);
      lazy_due = true;
      return result;
    };
    for (int k = 0; k < steps; ++k) {
      const auto before = c.aspects();  // before this round's command and step
      const int p = percent(rng);
      std::string what = "tick";
      if (p < 3) {
        const Mode m = *(modes.begin() + percent(rng) % 6);
        what = fmt::format("mode {}: {}", ToString(m),
                           both([&](auto& ctl) { return ctl.SetMode(m, now); }).message);
      } else if (p < 6) {
        const std::size_t plan = static_cast<std::size_t>(percent(rng)) % (x.plans.size() + 1);
        const std::string name = plan == x.plans.size() ? "auto" : x.plans[plan].name;
        what = both([&](auto& ctl) { return ctl.SetPlan(name, now); }).message;
      } else if (p < 12) {
        what = "advance: " + both([&](auto& ctl) { return ctl.Advance(now); }).message;
      } else if (p < 16 && granted && percent(rng) < 25) {
        const auto u =
            both([&](auto& ctl) { return ctl.Cancel(granted->first, granted->second, now); });
        what = fmt::format("cancel {} {}: {} {}", granted->first, granted->second,
                           ToString(u.status), u.reason);
        granted.reset();
      } else if (p < 16) {
        const std::size_t g = static_cast<std::size_t>(percent(rng)) % x.groups.size();
        const ServiceRequest r{"nigel_" + std::to_string(1 + percent(rng) % 3),
                               static_cast<std::uint32_t>(percent(rng)), percent(rng) < 50, g,
                               now + milliseconds(percent(rng) * 300)};
        const auto u = both([&](auto& ctl) { return ctl.Request(r, now); });
        if (u.status == RequestStatus::kGranted) {
          ++grants;
          granted = {r.vehicle, r.request_id};
        }
        what = fmt::format("request group {} status {} {}", g, ToString(u.status), u.reason);
      } else if (p < 17) {
        both([&](auto& ctl) {
          ctl.FailSafe(now, "injected device fault");
          return 0;
        });
        what = "fail-safe";
        ++latches;
      } else if (p < 20) {
        what = "reset: " + both([&](auto& ctl) { return ctl.Reset(now); }).message;
      } else if (p < 22) {
        const bool ready = percent(rng) < 70;
        both([&](auto& ctl) {
          ctl.SetDevicesReady(ready);
          return 0;
        });
      } else if (p < 30) {
        calls[static_cast<std::size_t>(percent(rng)) % calls.size()].flip();
        lazy_due = true;
      } else if (p < 35) {
        // A phase control on a phase (sometimes not one), set or taken off.
        const auto kind = static_cast<PhaseControlKind>(percent(rng) % 6);
        const std::size_t phase = 1 + static_cast<std::size_t>(percent(rng)) % 5;
        const auto d = milliseconds(100 + percent(rng) * 400);
        what = percent(rng) < 25
                   ? both([&](auto& ctl) { return ctl.ClearControl(kind, phase, now); }).message
                   : both([&](auto& ctl) { return ctl.Control(kind, phase, d, now); }).message;
      } else if (p < 36) {
        minute = std::uniform_int_distribution<int>(0, 1439)(rng);
        what = "schedule";
        lazy_due = true;
      }
      now += milliseconds(tick_ms(rng));
      c.Step(now, calls, Day(now, minute));
      if (lazy_due || now >= lazy.next_wake()) {
        lazy.Step(now, calls, Day(now, minute));
        lazy_due = false;
        ++lazy_steps;
      }
      note(what);
      ASSERT_EQ(lazy.aspects(), c.aspects())
          << "stepping only when due (next_wake) changed the output" << dump();
      ASSERT_EQ(lazy.stage(), c.stage()) << dump();
      // SPaT timing: a change never comes before a min end promised since the group's last
      // change (commands cannot take a promise back), except into fail-safe flash; with no
      // command in between, never later than one tick after the max end the last tick gave.
      for (std::size_t g = 0; g < before.size(); ++g) {
        if (c.aspects()[g] == before[g]) continue;
        if (!c.latched() && promised[g]) {
          ASSERT_GE(now, *promised[g])
              << "group " << g << " changed to " << ToString(c.aspects()[g])
              << " before its promise" << dump();
        }
        if (what == "tick" && !prev.empty() && prev[g].max_end) {
          ASSERT_LE(now, *prev[g].max_end + milliseconds(600)) << "group " << g << dump();
        }
        promised[g].reset();
      }
      // Fail-safe flash voids every promise made before it.
      if (c.latched()) std::fill(promised.begin(), promised.end(), std::nullopt);
      prev = c.Signals(now);
      for (std::size_t g = 0; g < prev.size(); ++g) {
        ASSERT_GE(prev[g].min_end, now);
        promised[g] = promised[g] ? std::max(*promised[g], prev[g].min_end) : prev[g].min_end;
      }
      for (const auto& u : c.TakeRequestUpdates())
        note("update " + std::string(ToString(u.status)) + " " + u.reason);
      (void)lazy.TakeRequestUpdates();
      ++ticks;
      const std::string broken = checker.Check(now, c.aspects());
      if (!broken.empty()) note("checked");
      ASSERT_EQ(broken, "") << "sequence " << s << " step " << k << " at " << x.name << dump();
      const auto v = monitor.CheckAndRecord(now, c.aspects());
      ASSERT_FALSE(v) << "sequence " << s << " step " << k << ": " << v->message << dump();
    }
  }
  std::printf(
      "%s: %d sequences, %lld ticks (%lld steps when due), %d injected faults, %d "
      "requests granted\n",
      city.config.name.c_str(), sequences, ticks, lazy_steps, latches, grants);
  EXPECT_GT(grants, 0);
  EXPECT_LT(lazy_steps, ticks) << "next_wake let no step be skipped";
}

/// Liveness: under a fixed plan (or an actuated one with every group called) and no faults or
/// commands, every group turns green within one cycle plus its clearances, from the end of
/// the start-up sequence on, whatever the start time and the tick.
void RunLiveness(const City& city, int runs, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> tick_ms(20, 200);
  long long checked = 0;
  for (int r = 0; r < runs; ++r) {
    const auto& x = city.intersections[static_cast<std::size_t>(r) % city.intersections.size()];
    for (std::size_t plan = 0; plan < x.plans.size(); ++plan) {
      const Plan& p = x.plans[plan];
      if (p.type != PlanType::kFixed && p.type != PlanType::kActuated) continue;
      // The longest a group can wait: every phase at its longest green (or min green), each
      // followed by the longest clearance, plus one tick of lateness per change.
      Duration bound{0};
      for (const auto& phase : p.phases) {
        Duration longest = phase.green;
        Duration clearance{0};
        for (std::size_t g : phase.groups) {
          const auto& t = x.groups[g].timing;
          longest = std::max(
              {longest, t.min_green, p.type == PlanType::kActuated ? t.max_green : Duration{0}});
          clearance = std::max(clearance, t.yellow + t.red_clearance);
        }
        bound += longest + clearance + 2 * milliseconds(200);
      }
      MonoTime now =
          MonoTime(seconds(2'000'000 + std::uniform_int_distribution<int>(0, 86'400)(rng)));
      IntersectionController c(x, now, Mode::kAuto, plan);
      const std::vector<bool> calls(x.groups.size(), true);
      const int minute = std::uniform_int_distribution<int>(0, 1439)(rng);
      std::optional<MonoTime> cycling_since;
      std::vector<MonoTime> last_green(x.groups.size());
      const MonoTime end = now + 4 * bound + x.startup_flash + x.startup_all_red;
      while (now < end) {
        now += milliseconds(tick_ms(rng));
        c.Step(now, calls, Day(now, minute));
        ASSERT_FALSE(c.latched());
        if (!cycling_since && c.stage() == Stage::kGreen) {
          cycling_since = now;
          std::fill(last_green.begin(), last_green.end(), now);
        }
        if (!cycling_since) continue;
        for (std::size_t g = 0; g < x.groups.size(); ++g) {
          if (c.aspects()[g] == Aspect::kGreen) last_green[g] = now;
          ASSERT_LE(now - last_green[g], bound)
              << x.name << " plan " << p.name << ": group " << x.groups[g].name << " has waited "
              << ToSeconds(now - last_green[g]) << " s for its green (bound " << ToSeconds(bound)
              << " s)";
          ++checked;
        }
      }
      ASSERT_TRUE(cycling_since) << x.name << " plan " << p.name << " never left the start-up";
    }
  }
  std::printf("%s: liveness checked at %lld group-ticks\n", city.config.name.c_str(), checked);
}

TEST(ControllerProperty, EveryGroupGetsItsGreenWithinACyclePlusClearancesDrivingSchool) {
  RunLiveness(DrivingSchool(), 200 * test::SoakFactor(), 3);
}

TEST(ControllerProperty, EveryGroupGetsItsGreenWithinACyclePlusClearancesSmallTown) {
  RunLiveness(SmallTown(), 200 * test::SoakFactor(), 4);
}

TEST(ControllerProperty, RandomSequencesNeverBreakASafetyRuleDrivingSchool) {
  RunRandomSequences(DrivingSchool(), test::Cases(10'000), 1);
}

TEST(ControllerProperty, RandomSequencesNeverBreakASafetyRuleSmallTown) {
  RunRandomSequences(SmallTown(), test::Cases(10'000), 2);
}

/// `city` with every intersection choosing its next phase again through the clearance and
/// resting in green as SUMO's NEMA controller does.
City AsSumosController(const City& city) {
  City out = city;
  for (auto& x : out.intersections) {
    x.next_phase_decision = NextPhaseDecision::kEndOfClearance;
    x.green_rest = GreenRest::kSumo;
  }
  return out;
}

TEST(ControllerProperty, RandomSequencesNeverBreakASafetyRuleAsSumosController) {
  RunRandomSequences(AsSumosController(DrivingSchool()), test::Cases(5'000), 5);
  RunRandomSequences(AsSumosController(SmallTown()), test::Cases(5'000), 6);
}

// --- Pre-emption as NTCIP 1202's preempt state machine (docs/controller.md, "Pre-emption") ---

/// The Driving School (2 s clearances) with `priority` (a YAML flow map's contents) set at its
/// intersection.
City DrivingSchoolWithPriority(const std::string& priority) {
  return WithTwoSecondClearances(
      "driving_school.yaml", {{"    timing: {min_green_s: 5.0",
                               "    priority: {" + priority + "}\n    timing: {min_green_s: 5.0"}});
}

/// The pre-emption of the acceptance tests: delay 2 s, minimum duration 12 s, minimum green 6 s
/// (above the 5 s min greens: the lesser is the min green), dwell 8 s, and with `track` the
/// north group green 6 s as track clearance.
const City& PreemptSchool(bool track) {
  static const City with_track = DrivingSchoolWithPriority(
      "preempt_delay_s: 2.0, preempt_min_duration_s: 12.0, preempt_min_green_s: 6.0, "
      "preempt_dwell_green_s: 8.0, preempt_track_green_s: 6.0, preempt_track_groups: [2]");
  static const City without = DrivingSchoolWithPriority(
      "preempt_delay_s: 1.5, preempt_dwell_green_s: 5.0, max_preemption_s: 40.0");
  return track ? with_track : without;
}

/// The time of the first event with `code` (any parameter) at or after `from`, if any.
std::optional<MonoTime> Find(const std::vector<HiresEvent>& events, std::uint16_t code,
                             MonoTime from) {
  for (const HiresEvent& e : events) {
    if (e.code == code && e.at >= from) return e.at;
  }
  return std::nullopt;
}

/// The last event with `code` for phase `phase` at or before `at`, if any.
std::optional<MonoTime> LastBefore(const std::vector<HiresEvent>& events, std::uint16_t code,
                                   std::uint16_t phase, MonoTime at) {
  std::optional<MonoTime> last;
  for (const HiresEvent& e : events) {
    if (e.at > at) break;
    if (e.code == code && e.param == phase) last = e.at;
  }
  return last;
}

/// Every yellow and red clearance in `events` lasted at least its groups' (the Driving School:
/// one group per phase).
void ExpectNoClearanceShortened(const IntersectionModel& x, const std::vector<HiresEvent>& events) {
  int seen = 0;
  for (std::size_t i = 0; i < events.size(); ++i) {
    const HiresEvent& e = events[i];
    if (e.code != hires::kPhaseBeginYellow && e.code != hires::kPhaseBeginRedClearance) continue;
    const bool yellow = e.code == hires::kPhaseBeginYellow;
    const auto end =
        Find(std::vector<HiresEvent>(events.begin() + static_cast<long>(i) + 1, events.end()),
             yellow ? hires::kPhaseEndYellow : hires::kPhaseEndRedClearance, e.at);
    if (!end) continue;  // still under way at the end of the run
    const auto& t = x.groups[x.plans[0].phases[e.param - 1u].groups[0]].timing;
    EXPECT_GE(*end - e.at, yellow ? t.yellow : t.red_clearance)
        << (yellow ? "yellow" : "red clearance") << " of phase " << e.param << " at "
        << ToSeconds(e.at - CycleStart()) << " s";
    ++seen;
  }
  EXPECT_GT(seen, 0);
}

/// Places one emergency request at `offset` into a settled cycle of the day plan, for `group`,
/// its input on for `input`, and checks the whole pre-emption against the NTCIP text from the
/// high-resolution log, the aspects (monitor and rule checker at every tick) and the states.
struct PreemptFigures {
  double delay_s = 0;           ///< 105 - 102
  double dwell_s = 0;           ///< 111 - 107
  double entry_to_exit_s = 0;   ///< 111 - 105
  double green_to_dwell_s = 0;  ///< 107 - 102
};

void CheckOnePreemption(const City& city, Duration offset, std::size_t group, Duration input,
                        PreemptFigures& figures) {
  const IntersectionModel& x = city.intersections[0];
  const PriorityParams& pp = x.priority;
  Rig rig(x);
  RuleChecker checker(x, rig.now);
  const MonoTime at = CycleStart() + seconds(52) + offset;
  const auto run_to = [&](MonoTime until) {
    while (rig.now < until) {
      rig.RunTo(std::min(until, rig.now + milliseconds(100)));
      ASSERT_EQ(checker.Check(rig.now, rig.controller.aspects()), "");
    }
  };
  run_to(at);
  const bool group_green_at = rig.Of(group) == Aspect::kGreen;
  const ServiceRequest req{"nigel_9", 1, true, group, at + input, seconds(2)};
  const RequestUpdate u = rig.controller.Request(req, rig.now);
  ASSERT_EQ(u.status, RequestStatus::kGranted) << u.reason;
  ASSERT_TRUE(u.expected_green);
  if (!group_green_at) {
    EXPECT_GE(*u.expected_green, at + pp.preempt_delay) << "the delay counts";
  }
  // Run a minute and a half, stepping as the daemon does, the monitor and the rules checked at
  // every tick, and the states seen kept.
  std::vector<PreemptState> states{rig.controller.preempt_state()};
  while (rig.now < at + seconds(90)) {
    run_to(rig.now + milliseconds(100));
    if (rig.controller.preempt_state() != states.back()) {
      states.push_back(rig.controller.preempt_state());
    }
  }
  const std::vector<HiresEvent> all = rig.controller.TakeHiresEvents();
  std::vector<HiresEvent> events;
  for (const HiresEvent& e : all) {
    if (e.at >= at) events.push_back(e);
  }
  const auto e102 = Find(events, hires::kPreemptCallInputOn, at);
  const auto e105 = Find(events, hires::kPreemptEntryStarted, at);
  const auto e106 = Find(events, hires::kPreemptBeginTrackClearance, at);
  const auto e107 = Find(events, hires::kPreemptBeginDwell, at);
  const auto e111 = Find(events, hires::kPreemptBeginExit, at);
  const auto e104 = Find(events, hires::kPreemptCallInputOff, at);
  ASSERT_TRUE(e102 && e105 && e107 && e111 && e104);
  EXPECT_EQ(*e102, at);
  // Entry starts preemptDelay after the input.
  EXPECT_NEAR(ToSeconds(*e105 - *e102), ToSeconds(pp.preempt_delay), 0.1);
  // A green in service at entry that the pre-emption does not want ends (code 20) at the lesser
  // of its min green and preemptMinimumGreen, not before; a clearance under way runs out.
  const std::uint16_t dwell_phase = static_cast<std::uint16_t>(group + 1);
  const std::uint16_t first_wanted = pp.track() ? std::uint16_t{2} : dwell_phase;
  for (std::uint16_t k = 1; k <= 4; ++k) {
    const auto green = LastBefore(all, hires::kPhaseBeginGreen, k, *e105);
    const auto yellow = LastBefore(all, hires::kPhaseBeginYellow, k, *e105);
    if (!green || (yellow && *yellow >= *green && *yellow < *e105) || k == first_wanted) {
      continue;  // not green at entry, or the green the pre-emption wants
    }
    const auto ended = Find(events, hires::kPhaseBeginYellow, *e105);
    ASSERT_TRUE(ended);
    const Duration lesser =
        std::min(x.groups[k - 1u].timing.min_green, pp.preempt_min_green.value_or(Duration::max()));
    EXPECT_GE(*ended, *green + lesser) << "phase " << k << " cut under its minimum";
    EXPECT_NEAR(ToSeconds(*ended), ToSeconds(std::max(*e105, *green + lesser)), 0.1)
        << "phase " << k << " kept past the entry's end of green";
    EXPECT_EQ(Find(events, hires::kPreemptionForceOff, *e105), *ended);
  }
  ExpectNoClearanceShortened(x, all);
  // Track clearance (106): the north phase green for preemptTrackGreen, then the dwell (107).
  if (pp.track()) {
    ASSERT_TRUE(e106);
    EXPECT_GE(*e106, *e105);
    EXPECT_LT(*e106, *e107);
    const auto track_green = LastBefore(all, hires::kPhaseBeginGreen, 2, *e106);
    ASSERT_TRUE(track_green);
    if (dwell_phase != 2) {
      const auto track_end = Find(events, hires::kPhaseBeginYellow, *e106);
      ASSERT_TRUE(track_end);
      EXPECT_NEAR(ToSeconds(*track_end - *e106), ToSeconds(pp.preempt_track_green), 0.1);
    } else {
      EXPECT_NEAR(ToSeconds(*e107 - *e106), ToSeconds(pp.preempt_track_green), 0.1);
    }
  } else {
    EXPECT_FALSE(e106);
  }
  // The dwell: the request's group green from 107 (its phase's green began then, or was already
  // in service), lasting at least preemptDwellGreen, preemptMinimumDuration from entry and while
  // the input is on; then the exit (111) as the dwell phase goes to yellow.
  const auto dwell_green = LastBefore(all, hires::kPhaseBeginGreen, dwell_phase, *e107);
  ASSERT_TRUE(dwell_green);
  EXPECT_GE(*e107, *e105);
  const MonoTime input_end = std::max(at + input, *e107 + req.duration);
  const MonoTime due =
      std::max({*e107 + pp.preempt_dwell_green, *e105 + pp.preempt_min_duration, input_end});
  EXPECT_GE(*e111, due - milliseconds(1));
  EXPECT_NEAR(ToSeconds(*e111), ToSeconds(due), 0.1);
  EXPECT_EQ(Find(events, hires::kPhaseBeginYellow, *e111), *e111);
  EXPECT_NEAR(ToSeconds(*e104), ToSeconds(input_end), 0.1);
  // The exit phase (the one after the dwell phase) is the next green.
  const std::uint16_t exit_phase = static_cast<std::uint16_t>((group + 1) % 4 + 1);
  for (const HiresEvent& e : events) {
    if (e.code == hires::kPhaseBeginGreen && e.at > *e111) {
      EXPECT_EQ(e.param, exit_phase);
      break;
    }
  }
  // The states, in NTCIP's order (a state passed within a step is not seen).
  const std::vector<PreemptState> order{
      PreemptState::kNotActive,    PreemptState::kNotActiveWithCall,
      PreemptState::kEntryStarted, PreemptState::kTrackService,
      PreemptState::kDwell,        PreemptState::kExitStarted,
      PreemptState::kNotActive};
  std::size_t next = 0;
  std::string seen;
  for (const PreemptState s : states) {
    seen += std::string(ToString(s)) + " ";
    while (next < order.size() && order[next] != s) ++next;
    ASSERT_LT(next, order.size()) << "states out of order: " << seen;
    ++next;
  }
  EXPECT_EQ(states.back(), PreemptState::kNotActive) << seen;
  EXPECT_NE(std::ranges::find(states, PreemptState::kDwell), states.end()) << seen;
  if (pp.track() && dwell_phase != 2) {
    EXPECT_NE(std::ranges::find(states, PreemptState::kTrackService), states.end()) << seen;
  }
  const auto updates = rig.controller.TakeRequestUpdates();
  ASSERT_EQ(updates.size(), 1u);
  EXPECT_EQ(updates[0].status, RequestStatus::kCompleted);
  figures = {ToSeconds(*e105 - *e102), ToSeconds(*e111 - *e107), ToSeconds(*e111 - *e105),
             ToSeconds(*e107 - *e102)};
}

/// The acceptance's twenty seeded emergency requests: one in each interval of the day plan's
/// cycle (each phase's green, yellow and red clearance), then eight anywhere.
void RunTwentyPreemptions(bool track) {
  const City& city = PreemptSchool(track);
  std::mt19937 rng(track ? 37 : 38);
  std::uniform_int_distribution<int> group(0, 3);
  std::uniform_int_distribution<int> input_ms(2500, 25'000);
  const std::array<int, 3> starts{0, 8, 11};  // green, yellow, red clearance (2 s clearances)
  const std::array<int, 3> lengths{8, 3, 2};
  for (int k = 0; k < 20; ++k) {
    int offset_ms = 0;
    if (k < 12) {
      const auto kind = static_cast<std::size_t>(k % 3);
      offset_ms = 13'000 * (k / 3) + 1000 * starts[kind] +
                  100 * std::uniform_int_distribution<int>(0, 10 * lengths[kind] - 1)(rng);
    } else {
      offset_ms = 100 * std::uniform_int_distribution<int>(0, 519)(rng);
    }
    const auto g = static_cast<std::size_t>(group(rng));
    const auto input = milliseconds(100 * (input_ms(rng) / 100));
    SCOPED_TRACE(fmt::format("request {}: at {:.1f} s of the cycle, group {}, input {:.1f} s", k,
                             offset_ms / 1000.0, g + 1, ToSeconds(input)));
    PreemptFigures f;
    CheckOnePreemption(city, milliseconds(offset_ms), g, input, f);
    std::printf(
        "%s request %2d at %4.1f s group %zu input %4.1f s: 105-102 %.1f s, 107-102 "
        "%4.1f s, dwell %4.1f s, 111-105 %4.1f s\n",
        track ? "track" : "no track", k, offset_ms / 1000.0, g + 1, ToSeconds(input), f.delay_s,
        f.green_to_dwell_s, f.dwell_s, f.entry_to_exit_s);
  }
}

TEST(ControllerPreempt, TwentyRequestsInEveryIntervalFollowTheNtcipSequenceWithTrackClearance) {
  RunTwentyPreemptions(true);
}

TEST(ControllerPreempt, TwentyRequestsInEveryIntervalFollowTheNtcipSequenceWithoutTrack) {
  RunTwentyPreemptions(false);
}

TEST(ControllerPreempt, AStuckInputIsReleasedByMaxPresenceAndGoesOffOnlyWhenItEnds) {
  const City city = DrivingSchoolWithPriority("max_preemption_s: 20.0");
  Rig rig(city.intersections[0]);
  rig.RunTo(CycleStart() + seconds(6));
  ASSERT_EQ(rig.Of(0), Aspect::kGreen);
  (void)rig.controller.TakeHiresEvents();
  // West, its input on for 1000 s (stuck).
  const ServiceRequest stuck{"nigel_4", 3, true, 2, rig.now + seconds(1000)};
  ASSERT_EQ(rig.controller.Request(stuck, rig.now).status, RequestStatus::kGranted);
  rig.RunTo(CycleStart() + seconds(26) - milliseconds(100));
  EXPECT_EQ(rig.Of(2), Aspect::kGreen);
  EXPECT_EQ(rig.controller.preempt_state(), PreemptState::kDwell);
  rig.RunTo(CycleStart() + seconds(26));  // 20 s after the input: released
  EXPECT_EQ(rig.Of(2), Aspect::kYellow);
  EXPECT_EQ(rig.controller.preempt_state(), PreemptState::kExitStarted);
  auto updates = rig.controller.TakeRequestUpdates();
  ASSERT_EQ(updates.size(), 1u);
  EXPECT_EQ(updates[0].status, RequestStatus::kCompleted);
  EXPECT_THAT(updates[0].reason, HasSubstr("expired"));
  rig.RunTo(CycleStart() + seconds(31));  // the exit phase (south) after the clearance
  EXPECT_EQ(rig.Of(3), Aspect::kGreen);
  EXPECT_EQ(rig.controller.preempt_state(), PreemptState::kMaxPresence);
  EXPECT_FALSE(rig.controller.preemption_active());
  // The input stays on: it is not served again, the plan runs (every group green in a cycle).
  std::vector<bool> green(4, false);
  while (rig.now < CycleStart() + seconds(31 + 60)) {
    rig.RunFor(milliseconds(100));
    for (std::size_t g = 0; g < 4; ++g) green[g] = green[g] || rig.Of(g) == Aspect::kGreen;
    ASSERT_EQ(rig.controller.preempt_state(), PreemptState::kMaxPresence);
  }
  EXPECT_EQ(green, std::vector<bool>(4, true));
  const auto again = rig.controller.Request(stuck, rig.now);
  EXPECT_EQ(again.status, RequestStatus::kRejected);
  EXPECT_THAT(again.reason, HasSubstr("max presence"));
  // The input goes off (the vehicle cancels): 104, and the preempt is free again.
  EXPECT_EQ(rig.controller.Cancel("nigel_4", 3, rig.now).status, RequestStatus::kCancelled);
  EXPECT_EQ(rig.controller.preempt_state(), PreemptState::kNotActive);
  std::vector<std::pair<std::uint16_t, double>> log;
  for (const HiresEvent& e : rig.controller.TakeHiresEvents()) {
    if ((e.code >= 100 && e.code < 112) || e.code == hires::kPreemptionForceOff) {
      log.push_back({e.code, ToSeconds(e.at - CycleStart())});
    }
  }
  const std::vector<std::pair<std::uint16_t, double>> expected{
      {hires::kPreemptCallInputOn, 6.0},
      {hires::kPreemptEntryStarted, 6.0},
      {hires::kPreemptionForceOff, 10.0},
      {hires::kPreemptBeginDwell, 15.0},
      {hires::kPreemptMaxPresenceExceeded, 26.0},
      {hires::kPreemptBeginExit, 26.0},
      {hires::kPreemptCallInputOff, ToSeconds(rig.now - CycleStart())}};
  EXPECT_EQ(log, expected);
}

TEST(ControllerPreempt, AnInputThatGoesOffInTheDelayStartsNoPreemption) {
  const City& city = PreemptSchool(false);  // delay 1.5 s
  for (const bool cancel : {true, false}) {
    SCOPED_TRACE(cancel ? "cancelled" : "ended");
    Rig rig(city.intersections[0]);
    const MonoTime c = CycleStart() + seconds(52);  // a settled cycle
    rig.RunTo(c + seconds(6));
    (void)rig.controller.TakeHiresEvents();
    const ServiceRequest r{"nigel_5", 4, true, 2, rig.now + seconds(1)};
    ASSERT_EQ(rig.controller.Request(r, rig.now).status, RequestStatus::kGranted);
    EXPECT_EQ(rig.controller.preempt_state(), PreemptState::kNotActiveWithCall);
    EXPECT_TRUE(rig.controller.preemption_active());
    rig.RunFor(milliseconds(500));
    if (cancel) {
      EXPECT_EQ(rig.controller.Cancel("nigel_5", 4, rig.now).status, RequestStatus::kCancelled);
    } else {
      rig.RunFor(milliseconds(500));  // its end, 1 s after the call
      const auto updates = rig.controller.TakeRequestUpdates();
      ASSERT_EQ(updates.size(), 1u);
      EXPECT_EQ(updates[0].status, RequestStatus::kCancelled);
      EXPECT_THAT(updates[0].reason, HasSubstr("preempt delay"));
    }
    EXPECT_EQ(rig.controller.preempt_state(), PreemptState::kNotActive);
    const MonoTime off = rig.now;
    // The plan goes on as if nothing had come: east's green ends at 8 s of the cycle, north's
    // follows at 13 s.
    rig.RunTo(c + seconds(8) - milliseconds(100));
    EXPECT_EQ(rig.Of(0), Aspect::kGreen);
    rig.RunTo(c + seconds(8));
    EXPECT_EQ(rig.Of(0), Aspect::kYellow);
    rig.RunTo(c + seconds(13));
    EXPECT_EQ(rig.Of(1), Aspect::kGreen);
    std::vector<std::pair<std::uint16_t, MonoTime>> log;
    for (const HiresEvent& e : rig.controller.TakeHiresEvents()) {
      if (e.code >= 100 && e.code < 120) log.push_back({e.code, e.at});
    }
    const std::vector<std::pair<std::uint16_t, MonoTime>> expected{
        {hires::kPreemptCallInputOn, c + seconds(6)}, {hires::kPreemptCallInputOff, off}};
    EXPECT_EQ(log, expected);
  }
}

TEST(ControllerPreempt, ConfigsThatWouldCutAGreenUnderItsMinimumAreRefused) {
  const auto error = [](const std::string& priority) {
    return test::ErrorMessage<ConfigError>([&] { (void)DrivingSchoolWithPriority(priority); });
  };
  EXPECT_THAT(error("preempt_min_green_s: 3.0"),
              HasSubstr("priority: preempt_min_green_s 3 s is below group 1 (east)'s min green "
                        "5 s; rule: the conflict monitor holds every green to its min green"));
  EXPECT_THAT(error("preempt_track_green_s: 4.0, preempt_track_groups: [2]"),
              HasSubstr("preempt_track_green_s 4 s is below track group 2 (north)'s min green"));
  EXPECT_THAT(error("preempt_track_groups: [2]"),
              HasSubstr("preempt_track_green_s and preempt_track_groups come together"));
  EXPECT_THAT(error("preempt_track_green_s: 6.0, preempt_track_groups: [9]"), HasSubstr("9"));
  EXPECT_THAT(error("preempt_exit: first"), HasSubstr("preempt_exit"));
  EXPECT_EQ(PreemptSchool(true).intersections[0].priority.preempt_track_groups,
            std::vector<std::size_t>{1});
  EXPECT_EQ(PreemptSchool(true).intersections[0].priority.preempt_delay, seconds(2));
}

/// `city` with a pre-emption sequence at every intersection: delay 2 s, minimum duration 12 s,
/// dwell 8 s, max presence 20 s (the random requests last up to 30 s), and a track clearance by
/// the groups of the first plan's second phase where every plan with phases has a phase with
/// them all.
City WithPreemptSequence(const City& city) {
  City out = city;
  for (auto& x : out.intersections) {
    PriorityParams& p = x.priority;
    p.preempt_delay = seconds(2);
    p.preempt_min_duration = seconds(12);
    p.preempt_dwell_green = seconds(8);
    p.max_preemption = seconds(20);
    const auto& track = x.plans[0].phases.at(1).groups;
    const bool everywhere = std::ranges::all_of(x.plans, [&](const Plan& plan) {
      return plan.phases.empty() || std::ranges::any_of(plan.phases, [&](const Phase& ph) {
               return std::ranges::all_of(track, [&](std::size_t t) {
                 return std::ranges::find(ph.groups, t) != ph.groups.end();
               });
             });
    });
    if (!everywhere) continue;
    p.preempt_track_groups = track;
    p.preempt_track_green = seconds(6);
    for (std::size_t t : track) {
      p.preempt_track_green = std::max(p.preempt_track_green, x.groups[t].timing.min_green);
    }
  }
  return out;
}

TEST(ControllerProperty, RandomSequencesNeverBreakASafetyRuleWithAPreemptSequence) {
  RunRandomSequences(WithPreemptSequence(DrivingSchool()), test::Cases(5'000), 7);
  RunRandomSequences(WithPreemptSequence(SmallTown()), test::Cases(5'000), 8);
}

}  // namespace
}  // namespace autodrive::scm
