#include "infrastructure/device.h"

#include <gtest/gtest.h>

#include <array>
#include <limits>
#include <map>

namespace autodrive::infrastructure {
namespace {

// Simulated time as a plain variable: both timelines are the simulated time.
void AdvanceSim(SimClock& clock, MonoTime t) { clock.AdvanceTo(Time(t.time_since_epoch())); }

using namespace std::chrono_literals;

constexpr std::array<Aspect, 6> kAspects = {Aspect::kOff,         Aspect::kRed,
                                            Aspect::kYellow,      Aspect::kGreen,
                                            Aspect::kFlashingRed, Aspect::kFlashingYellow};

DeviceParams Params() {
  DeviceParams p;
  p.id = SignalHeadId(3);
  p.scm_heartbeat_timeout = 1s;
  p.flash_period = 1s;
  return p;
}

ScmHeartbeat Running(std::uint64_t sequence, std::uint64_t session = 77) {
  return ScmHeartbeat{session, sequence, ScmState::kRunning};
}

// Codes of the events raised since the last call.
std::vector<std::string> Codes(TrafficLightDevice& d) {
  std::vector<std::string> codes;
  for (const auto& e : d.TakeEvents()) codes.push_back(e.code);
  return codes;
}

// A device under SCM control (heartbeat at `now`) showing `target`, reached by legal commands.
TrafficLightDevice DeviceShowing(Aspect target, MonoTime now) {
  TrafficLightDevice d(Params(), now);
  d.OnHeartbeat(Running(1), now);
  d.OnCommand(ToWire(Aspect::kRed), now);
  const std::map<Aspect, std::vector<Aspect>> paths = {
      {Aspect::kOff, {Aspect::kOff}},
      {Aspect::kRed, {}},
      {Aspect::kYellow, {Aspect::kGreen, Aspect::kYellow}},
      {Aspect::kGreen, {Aspect::kGreen}},
      {Aspect::kFlashingRed, {Aspect::kFlashingRed}},
      {Aspect::kFlashingYellow, {Aspect::kFlashingYellow}},
  };
  for (const Aspect a : paths.at(target)) d.OnCommand(ToWire(a), now);
  EXPECT_EQ(d.aspect(), target);
  EXPECT_EQ(d.health(), Health::kOk) << d.detail();
  EXPECT_FALSE(d.in_fail_safe()) << d.detail();
  (void)d.TakeEvents();
  return d;
}

TEST(Transitions, TheTableIsTheHandWrittenOne) {
  // Rows: from; columns: to, in the order off, red, yellow, green, flashing red, flashing
  // yellow. 1 = legal.
  const std::map<Aspect, std::array<int, 6>> expected = {
      {Aspect::kOff, {1, 1, 0, 0, 1, 1}},         {Aspect::kRed, {1, 1, 0, 1, 1, 1}},
      {Aspect::kYellow, {1, 1, 1, 0, 1, 1}},      {Aspect::kGreen, {1, 0, 1, 1, 1, 1}},
      {Aspect::kFlashingRed, {1, 1, 0, 0, 1, 1}}, {Aspect::kFlashingYellow, {1, 1, 0, 0, 1, 1}},
  };
  int legal = 0;
  for (const Aspect from : kAspects) {
    for (std::size_t j = 0; j < kAspects.size(); ++j) {
      const Aspect to = kAspects[j];
      EXPECT_EQ(IsLegalTransition(from, to), expected.at(from)[j] == 1)
          << ToString(from) << " -> " << ToString(to);
      EXPECT_EQ(RefusalRule(from, to).empty(), IsLegalTransition(from, to));
      legal += IsLegalTransition(from, to) ? 1 : 0;
    }
  }
  EXPECT_EQ(legal, 27);
}

TEST(Transitions, RefusalsSayWhichRuleWasBroken) {
  EXPECT_EQ(RefusalRule(Aspect::kGreen, Aspect::kRed), "a green must end in yellow");
  EXPECT_EQ(RefusalRule(Aspect::kYellow, Aspect::kGreen), "a yellow must end in red");
  EXPECT_EQ(RefusalRule(Aspect::kRed, Aspect::kYellow), "yellow only follows green");
  EXPECT_EQ(RefusalRule(Aspect::kFlashingRed, Aspect::kGreen),
            "a dark or flashing head must show red first");
  EXPECT_EQ(RefusalRule(Aspect::kOff, Aspect::kYellow),
            "a dark or flashing head must show red first");
}

TEST(TrafficLightDevice, FollowsEveryLegalCommandAndRefusesEveryIllegalOne) {
  const MonoTime t0 = MonoFromSeconds(100);
  for (const Aspect from : kAspects) {
    for (const Aspect to : kAspects) {
      SCOPED_TRACE(std::string(ToString(from)) + " -> " + std::string(ToString(to)));
      TrafficLightDevice d = DeviceShowing(from, t0);
      d.OnCommand(ToWire(to), t0 + 10ms);
      const auto events = d.TakeEvents();
      if (IsLegalTransition(from, to)) {
        EXPECT_EQ(d.aspect(), to);
        EXPECT_EQ(d.health(), Health::kOk);
        EXPECT_TRUE(events.empty());
        EXPECT_EQ(d.refused_commands(), 0u);
      } else {
        EXPECT_EQ(d.aspect(), from) << "a refused command changes nothing";
        EXPECT_EQ(d.health(), Health::kDegraded);
        const std::string refusal = "refused " + std::string(ToString(from)) + " -> " +
                                    std::string(ToString(to)) + ": " +
                                    std::string(RefusalRule(from, to));
        EXPECT_EQ(d.detail(), refusal);
        ASSERT_EQ(events.size(), 1u);
        EXPECT_EQ(events[0].code, "illegal_sequence");
        EXPECT_EQ(events[0].severity, Severity::kWarning);
        EXPECT_EQ(events[0].message, "signal_3 " + refusal);
        EXPECT_EQ(d.refused_commands(), 1u);
      }
    }
  }
}

TEST(TrafficLightDevice, GreenToRedIsRefusedWithTheRuleInTheDetail) {
  TrafficLightDevice d = DeviceShowing(Aspect::kGreen, MonoFromSeconds(1));
  d.OnCommand(ToWire(Aspect::kRed), MonoFromSeconds(2));
  EXPECT_EQ(d.aspect(), Aspect::kGreen);
  EXPECT_EQ(d.health(), Health::kDegraded);
  EXPECT_EQ(d.detail(), "refused green -> red: a green must end in yellow");
}

TEST(TrafficLightDevice, AnAcceptedCommandEndsTheDegradedHealth) {
  TrafficLightDevice d = DeviceShowing(Aspect::kGreen, MonoFromSeconds(1));
  d.OnCommand(ToWire(Aspect::kRed), MonoFromSeconds(2));
  ASSERT_EQ(d.health(), Health::kDegraded);
  d.OnCommand(ToWire(Aspect::kYellow), MonoFromSeconds(3));
  EXPECT_EQ(d.aspect(), Aspect::kYellow);
  EXPECT_EQ(d.health(), Health::kOk);
  EXPECT_EQ(d.detail(), "");
}

TEST(TrafficLightDevice, ACommandThatIsNotAnAspectIsRefusedAndCounted) {
  TrafficLightDevice d = DeviceShowing(Aspect::kRed, MonoFromSeconds(1));
  for (const std::int32_t bad : {6, -1, 1000000, std::numeric_limits<std::int32_t>::min()}) {
    d.OnCommand(bad, MonoFromSeconds(2));
    EXPECT_EQ(d.aspect(), Aspect::kRed);
  }
  EXPECT_EQ(d.malformed_commands(), 4u);
  EXPECT_EQ(d.health(), Health::kDegraded);
  EXPECT_EQ(d.detail(), "refused command -2147483648: not an aspect (0..5)");
  EXPECT_EQ(Codes(d), std::vector<std::string>(4, "illegal_command"));
}

TEST(TrafficLightDevice, StartsInFlashingRedUntilItHasAHeartbeatAndACommand) {
  const MonoTime t0 = MonoFromSeconds(10);
  {
    TrafficLightDevice d(Params(), t0);
    EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
    EXPECT_EQ(d.mode(), Mode::kFlash);
    EXPECT_EQ(d.health(), Health::kOk);
    EXPECT_EQ(d.detail(), "start-up; waiting for the SCM's heartbeat");
    d.OnCommand(ToWire(Aspect::kRed), t0 + 100ms);  // the latched command comes first
    d.Update(t0 + 200ms);
    EXPECT_EQ(d.aspect(), Aspect::kFlashingRed) << "no heartbeat yet";
    d.OnHeartbeat(Running(5), t0 + 300ms);
    EXPECT_EQ(d.aspect(), Aspect::kRed);
    EXPECT_EQ(d.mode(), Mode::kNormal);
    EXPECT_EQ(d.last_scm_sequence(), 5u);
    EXPECT_TRUE(d.TakeEvents().empty()) << "start-up is not an alarm";
  }
  {
    TrafficLightDevice d(Params(), t0);
    d.OnHeartbeat(Running(1), t0 + 100ms);  // the heartbeat comes first
    EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
    EXPECT_EQ(d.detail(), "start-up; waiting for a command");
    d.OnCommand(ToWire(Aspect::kRed), t0 + 200ms);
    EXPECT_EQ(d.aspect(), Aspect::kRed);
  }
}

TEST(TrafficLightDevice, AtStartUpAGreenMustWaitForRed) {
  const MonoTime t0 = MonoFromSeconds(10);
  TrafficLightDevice d(Params(), t0);
  d.OnHeartbeat(Running(1), t0);
  d.OnCommand(ToWire(Aspect::kGreen), t0 + 10ms);  // the SCM is mid-cycle
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
  EXPECT_EQ(d.detail(), "start-up; waiting for a red, off or flashing command (commanded green)");
  d.OnCommand(ToWire(Aspect::kYellow), t0 + 20ms);
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
  d.OnCommand(ToWire(Aspect::kRed), t0 + 30ms);
  EXPECT_EQ(d.aspect(), Aspect::kRed);
  EXPECT_EQ(d.mode(), Mode::kNormal);
}

TEST(TrafficLightDevice, FlashesWhenTheHeartbeatIsMissingLongerThanTheTimeoutAndNotBefore) {
  SimClock clock;
  AdvanceSim(clock, MonoFromSeconds(50));
  TrafficLightDevice d = DeviceShowing(Aspect::kGreen, clock.Monotonic());
  // Heartbeats every 100 ms for 5 s keep it green.
  for (int i = 0; i < 50; ++i) {
    AdvanceSim(clock, clock.Monotonic() + 100ms);
    d.OnHeartbeat(Running(static_cast<std::uint64_t>(i + 2)), clock.Monotonic());
    d.Update(clock.Monotonic());
    ASSERT_EQ(d.aspect(), Aspect::kGreen) << ToString(clock.Monotonic());
  }
  const MonoTime last = clock.Monotonic();
  // Then they stop: exactly the timeout later it still holds ...
  AdvanceSim(clock, last + 1s);
  d.Update(clock.Monotonic());
  EXPECT_EQ(d.aspect(), Aspect::kGreen);
  EXPECT_TRUE(d.scm_alive());
  // ... and a nanosecond more is too long.
  AdvanceSim(clock, last + 1s + 1ns);
  d.Update(clock.Monotonic());
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
  EXPECT_EQ(d.mode(), Mode::kFlash);
  EXPECT_FALSE(d.scm_alive());
  EXPECT_EQ(d.detail(), "lost SCM heartbeat; waiting for the SCM's heartbeat");
  const auto events = d.TakeEvents();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].code, "local_flash");
  EXPECT_TRUE(events[0].active);
  EXPECT_EQ(events[0].message, "signal_3 flashes red on its own: lost SCM heartbeat");
}

TEST(TrafficLightDevice, AStoppingHeartbeatFlashesAtOnce) {
  const MonoTime t0 = MonoFromSeconds(5);
  TrafficLightDevice d = DeviceShowing(Aspect::kGreen, t0);
  d.OnHeartbeat(ScmHeartbeat{77, 2, ScmState::kStopping}, t0 + 10ms);
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
  EXPECT_EQ(d.detail(), "SCM stopped; waiting for the SCM's heartbeat");
  EXPECT_EQ(d.last_scm_sequence(), 2u);
}

TEST(TrafficLightDevice, AStartingHeartbeatDoesNotCountAsRunning) {
  const MonoTime t0 = MonoFromSeconds(5);
  TrafficLightDevice d(Params(), t0);
  d.OnCommand(ToWire(Aspect::kRed), t0);
  d.OnHeartbeat(ScmHeartbeat{77, 0, ScmState::kStarting}, t0 + 10ms);
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
  EXPECT_FALSE(d.scm_alive());
}

TEST(TrafficLightDevice, ANewScmSessionIsTreatedAsALostHeartbeat) {
  const MonoTime t0 = MonoFromSeconds(5);
  TrafficLightDevice d = DeviceShowing(Aspect::kGreen, t0);
  d.OnHeartbeat(Running(1, /*session=*/99), t0 + 100ms);
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
  EXPECT_EQ(d.detail(), "SCM restarted; waiting for a new red, off or flashing command");
  d.OnCommand(ToWire(Aspect::kRed), t0 + 200ms);
  EXPECT_EQ(d.aspect(), Aspect::kRed);
}

TEST(TrafficLightDevice, AfterTheHeartbeatReturnsItFlashesUntilANewLegalCommand) {
  SimClock clock;
  AdvanceSim(clock, MonoFromSeconds(1));
  TrafficLightDevice d = DeviceShowing(Aspect::kGreen, clock.Monotonic());
  AdvanceSim(clock, clock.Monotonic() + 1500ms);
  d.Update(clock.Monotonic());
  ASSERT_EQ(d.aspect(), Aspect::kFlashingRed);
  // The heartbeat returns; the latched command is still green, and nothing new came.
  for (int i = 0; i < 30; ++i) {
    AdvanceSim(clock, clock.Monotonic() + 100ms);
    d.OnHeartbeat(Running(static_cast<std::uint64_t>(100 + i)), clock.Monotonic());
    d.Update(clock.Monotonic());
    ASSERT_EQ(d.aspect(), Aspect::kFlashingRed);
  }
  EXPECT_EQ(d.detail(), "lost SCM heartbeat; waiting for a new red, off or flashing command");
  // A new green cannot end the flash; it is not an error either (the SCM may be mid-cycle).
  d.OnCommand(ToWire(Aspect::kGreen), clock.Monotonic());
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
  EXPECT_EQ(d.health(), Health::kOk);
  (void)d.TakeEvents();
  d.OnCommand(ToWire(Aspect::kRed), clock.Monotonic() + 10ms);
  EXPECT_EQ(d.aspect(), Aspect::kRed);
  EXPECT_EQ(d.mode(), Mode::kNormal);
  const auto events = d.TakeEvents();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].code, "local_flash");
  EXPECT_FALSE(events[0].active);
}

TEST(TrafficLightDevice, ACommandReceivedWhileTheHeartbeatWasMissingIsNotANewCommand) {
  const MonoTime t0 = MonoFromSeconds(1);
  TrafficLightDevice d = DeviceShowing(Aspect::kRed, t0);
  d.Update(t0 + 2s);
  ASSERT_EQ(d.aspect(), Aspect::kFlashingRed);
  d.OnCommand(ToWire(Aspect::kRed), t0 + 2100ms);  // written before the heartbeat came back
  d.OnHeartbeat(Running(9), t0 + 2200ms);
  d.Update(t0 + 2200ms);
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
  d.OnCommand(ToWire(Aspect::kRed), t0 + 2300ms);
  EXPECT_EQ(d.aspect(), Aspect::kRed);
}

TEST(TrafficLightDevice, FlashingAspectsAreOnForTheFirstHalfOfEachPeriod) {
  const MonoTime t0 = MonoFromSeconds(20);
  TrafficLightDevice d(Params(), t0);  // start-up: flashing red from t0
  const Lamps red_on = LampsFor(Aspect::kRed);
  const Lamps dark;
  EXPECT_EQ(d.LampsAt(t0), red_on);
  EXPECT_EQ(d.LampsAt(t0 + 499999999ns), red_on);
  EXPECT_EQ(d.LampsAt(t0 + 500ms), dark);
  EXPECT_EQ(d.LampsAt(t0 + 999ms), dark);
  EXPECT_EQ(d.LampsAt(t0 + 1s), red_on);
  EXPECT_EQ(d.LampsAt(t0 + 7s + 250ms), red_on);
  EXPECT_EQ(d.LampsAt(t0 + 7s + 750ms), dark);

  // Sampled at the host's 50 Hz for 10 s: on half the time, switching twice per second.
  SimClock clock;
  AdvanceSim(clock, t0);
  int on = 0;
  int switches = 0;
  bool previous = true;
  for (int i = 0; i < 500; ++i) {
    const bool lit = d.LampsAt(clock.Monotonic()).red;
    on += lit ? 1 : 0;
    switches += (lit != previous) ? 1 : 0;
    previous = lit;
    AdvanceSim(clock, clock.Monotonic() + 20ms);
  }
  EXPECT_EQ(on, 250);
  EXPECT_EQ(switches, 19);  // 10 periods: off at 0.5, on at 1.0, ..., off at 9.5
}

TEST(TrafficLightDevice, FlashingYellowFlashesTheYellowLampFromWhenItWasCommanded) {
  const MonoTime t0 = MonoFromSeconds(1);
  TrafficLightDevice d = DeviceShowing(Aspect::kRed, t0);
  const MonoTime t1 = t0 + 333ms;
  d.OnCommand(ToWire(Aspect::kFlashingYellow), t1);
  EXPECT_EQ(d.LampsAt(t1), LampsFor(Aspect::kYellow));
  EXPECT_EQ(d.LampsAt(t1 + 600ms), Lamps{});
  EXPECT_EQ(d.LampsAt(t1 + 1100ms), LampsFor(Aspect::kYellow));
  EXPECT_EQ(d.mode(), Mode::kNormal) << "commanded flash is the SCM's, not a fail-safe";
}

TEST(TrafficLightDevice, LeavingFailSafeForACommandedFlashingRedKeepsThePhase) {
  const MonoTime t0 = MonoFromSeconds(1);
  TrafficLightDevice d(Params(), t0);
  d.OnHeartbeat(Running(1), t0 + 700ms);
  d.OnCommand(ToWire(Aspect::kFlashingRed), t0 + 700ms);
  EXPECT_EQ(d.mode(), Mode::kNormal);
  EXPECT_EQ(d.LampsAt(t0 + 700ms), Lamps{}) << "still in the dark half that began at t0+0.5s";
}

TEST(TrafficLightDevice, CommandedOffIsDark) {
  TrafficLightDevice d = DeviceShowing(Aspect::kOff, MonoFromSeconds(1));
  EXPECT_EQ(d.mode(), Mode::kDark);
  EXPECT_EQ(d.LampsAt(MonoFromSeconds(2)), Lamps{});
}

TEST(TrafficLightDevice, AFailedLampMakesItFaultyUntilRepaired) {
  TrafficLightDevice d = DeviceShowing(Aspect::kGreen, MonoFromSeconds(1));
  LampFeedback feedback;
  feedback.faults = {{Lamp::kGreen, "open_circuit"}};
  d.OnFeedback(feedback);
  EXPECT_EQ(d.health(), Health::kFault);
  EXPECT_EQ(d.detail(), "green lamp failed (open_circuit)");
  d.OnFeedback(feedback);  // the same fault again raises nothing new
  auto events = d.TakeEvents();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].code, "lamp_fault");
  EXPECT_EQ(events[0].severity, Severity::kAlarm);
  EXPECT_TRUE(events[0].active);
  EXPECT_EQ(events[0].message, "signal_3: green lamp failed (open_circuit)");

  d.OnFeedback(LampFeedback{});
  EXPECT_EQ(d.health(), Health::kOk);
  events = d.TakeEvents();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_FALSE(events[0].active);
}

TEST(TrafficLightDevice, AnOfflineBackendMakesItOffline) {
  TrafficLightDevice d = DeviceShowing(Aspect::kRed, MonoFromSeconds(1));
  LampFeedback feedback;
  feedback.online = false;
  feedback.offline_reason = "no answer";
  d.OnFeedback(feedback);
  EXPECT_EQ(d.health(), Health::kOffline);
  EXPECT_EQ(d.detail(), "offline: no answer");
  EXPECT_EQ(Codes(d), std::vector<std::string>{"device_offline"});
  d.OnFeedback(LampFeedback{});
  EXPECT_EQ(d.health(), Health::kOk);
}

TEST(TrafficLightDevice, WhileForcedItFlashesAndIgnoresCommandsThenWaitsForANewOne) {
  const MonoTime t0 = MonoFromSeconds(1);
  TrafficLightDevice d = DeviceShowing(Aspect::kGreen, t0);
  d.ForceFlash("mmu_x latched", t0 + 1s);
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
  EXPECT_EQ(d.mode(), Mode::kFlash);
  EXPECT_TRUE(d.forced());
  d.OnCommand(ToWire(Aspect::kRed), t0 + 2s);
  d.OnHeartbeat(Running(2), t0 + 2s);
  d.Update(t0 + 2s);
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
  EXPECT_EQ(d.detail(), "forced to flash by the conflict monitor: mmu_x latched");
  d.ReleaseForce(t0 + 3s);
  EXPECT_FALSE(d.forced());
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed) << "the red it had before the reset is not new";
  EXPECT_EQ(d.detail(), "conflict monitor reset; waiting for a new red, off or flashing command");
  d.OnHeartbeat(Running(3), t0 + 3s);
  d.OnCommand(ToWire(Aspect::kRed), t0 + 3100ms);
  EXPECT_EQ(d.aspect(), Aspect::kRed);
  EXPECT_EQ(d.mode(), Mode::kNormal);
}

TEST(TrafficLightDevice, ARedReceivedRightAfterTheReleaseEndsTheFlash) {
  // The host takes the SCM's reset before the light commands of the same pass: a red taken
  // in the same instant, after the release, is a new command.
  const MonoTime t0 = MonoFromSeconds(1);
  TrafficLightDevice d = DeviceShowing(Aspect::kGreen, t0);
  d.ForceFlash("mmu_x latched", t0 + 1s);
  d.OnHeartbeat(Running(2), t0 + 2s);
  d.ReleaseForce(t0 + 2s);
  d.OnCommand(ToWire(Aspect::kRed), t0 + 2s);
  EXPECT_EQ(d.aspect(), Aspect::kRed);
  EXPECT_EQ(d.mode(), Mode::kNormal);
  // The same red sent again by the SCM keeps it red.
  d.OnCommand(ToWire(Aspect::kRed), t0 + 2100ms);
  EXPECT_EQ(d.aspect(), Aspect::kRed);
}

TEST(TrafficLightDevice, ARestartOfTheTimeBaseIsAStartUpOnTheNewTimeline) {
  SimClock clock;
  AdvanceSim(clock, MonoFromSeconds(1000));
  TrafficLightDevice d = DeviceShowing(Aspect::kGreen, clock.Monotonic());
  // The simulator restarts at 5 s.
  const MonoTime t1 = MonoFromSeconds(5);
  d.Restart("simulated clock restarted", t1);
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
  EXPECT_EQ(d.mode(), Mode::kFlash);
  EXPECT_FALSE(d.scm_alive());
  EXPECT_EQ(d.detail(), "simulated clock restarted; waiting for the SCM's heartbeat");
  EXPECT_EQ(d.LampsAt(t1), LampsFor(Aspect::kRed)) << "flashing from the restart";
  EXPECT_EQ(d.LampsAt(t1 + 500ms), Lamps{});
  const auto events = d.TakeEvents();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].code, "local_flash");
  EXPECT_TRUE(events[0].active);
  EXPECT_EQ(events[0].message, "signal_3 flashes red on its own: simulated clock restarted");
  // The heartbeat comes back on the new timeline; the latest command (green) cannot end the
  // flash, a red can; then the time-out counts on the new timeline.
  d.OnHeartbeat(Running(9), t1 + 100ms);
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed);
  EXPECT_EQ(d.detail(),
            "simulated clock restarted; waiting for a red, off or flashing command (commanded "
            "green)");
  d.OnCommand(ToWire(Aspect::kRed), t1 + 200ms);
  EXPECT_EQ(d.aspect(), Aspect::kRed);
  d.Update(t1 + 1100ms);
  EXPECT_EQ(d.aspect(), Aspect::kRed);
  d.Update(t1 + 1100ms + 1ns);
  EXPECT_EQ(d.aspect(), Aspect::kFlashingRed) << "lost heartbeat, timed on the new timeline";
}

TEST(TrafficLightDevice, AfterARestartALatestRedCountsOnceTheHeartbeatComes) {
  const MonoTime t0 = MonoFromSeconds(1000);
  TrafficLightDevice d = DeviceShowing(Aspect::kRed, t0);
  d.Restart("simulated clock restarted", MonoFromSeconds(5));
  d.OnHeartbeat(Running(3), MonoFromSeconds(5.1));
  EXPECT_EQ(d.aspect(), Aspect::kRed) << "as a latched command at start-up";
}

TEST(TrafficLightDevice, NextChangeIsTheNextFlashEdgeOrTheHeartbeatTimeOut) {
  const MonoTime t0 = MonoFromSeconds(20);
  TrafficLightDevice d(Params(), t0);  // flashing red from t0, period 1 s, no heartbeat
  EXPECT_EQ(d.NextChange(t0), t0 + 500ms);
  EXPECT_EQ(d.NextChange(t0 + 499ms), t0 + 500ms);
  EXPECT_EQ(d.NextChange(t0 + 500ms), t0 + 1s);
  EXPECT_EQ(d.NextChange(t0 + 2750ms), t0 + 3s);
  // Each edge is where `LampsAt` changes.
  for (MonoTime t = t0; t < t0 + 3s; t = d.NextChange(t)) {
    const MonoTime edge = d.NextChange(t);
    EXPECT_NE(d.LampsAt(edge - 1ns), d.LampsAt(edge)) << ToString(edge);
  }
  // Steady red under a heartbeat: only the time-out is pending.
  d.OnHeartbeat(Running(1), t0 + 10ms);
  d.OnCommand(ToWire(Aspect::kRed), t0 + 10ms);
  ASSERT_EQ(d.aspect(), Aspect::kRed);
  EXPECT_EQ(d.NextChange(t0 + 20ms), t0 + 1010ms + 1ns);
  d.Update(d.NextChange(t0 + 20ms));
  EXPECT_TRUE(d.in_fail_safe()) << "the time-out is at that instant";
  d.OnHeartbeat(ScmHeartbeat{77, 2, ScmState::kStopping}, t0 + 2s);
  d.OnCommand(ToWire(Aspect::kOff), t0 + 2s);  // cannot end a flash without the SCM
  // Flashing from the time-out (t0 + 1010 ms + 1 ns): off at +500 ms, on again at +1 s.
  EXPECT_EQ(d.NextChange(t0 + 2s), t0 + 2010ms + 1ns);
}

}  // namespace
}  // namespace autodrive::infrastructure
