// Process supervision in-process: launchers' tables as views, explicit times.
#include "scm/core/process_watch.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>

#include <vector>

namespace autodrive::scm {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using ::testing::HasSubstr;

// Wall-clock times of the launcher (seconds after an arbitrary instant).
Time At(double s) { return TimeFromSeconds(1'795'000'000.0 + s); }

constexpr ExitStatus kKilled{128 + SIGKILL, SIGKILL};

class ProcessWatchTest : public ::testing::Test {
 protected:
  ProcessWatchTest() : watch_(Params()) {}
  static ProcessWatchParams Params() {
    ProcessWatchParams p;
    p.city = "small_town";
    return p;
  }

  // The lights as their launcher says after they were killed (pid 4242) at 10 s: to be started
  // again at 11 s.
  static ProcessView LightsKilled() {
    ProcessView p;
    p.name = "lights";
    p.phase = ProcessPhase::kExited;
    p.starts = 1;
    p.since = At(10);
    p.exits = 1;
    p.last_exit = ProcessExit{kKilled, 4242, At(10)};
    p.restart_at = At(11);
    return p;
  }
  // ... and once they run again (pid 5555) from 12 s.
  static ProcessView LightsBack() {
    ProcessView p = LightsKilled();
    p.phase = ProcessPhase::kRunning;
    p.pid = 5555;
    p.starts = 2;
    p.since = At(12);
    p.restart_at = Time{};
    return p;
  }
  static ProcessView Running(std::string_view name) {
    ProcessView p;
    p.name = name;
    p.phase = ProcessPhase::kRunning;
    p.pid = 100;
    p.starts = 1;
    p.since = At(1);
    return p;
  }

  void Report(std::vector<ProcessView> rows, MonoTime now, std::string_view host = "lab-pc",
              LauncherPhase phase = LauncherPhase::kRunning, std::string_view city = "small_town",
              std::uint64_t session = 7) {
    ProcessTableView t;
    t.city = city;
    t.host = host;
    t.session = session;
    t.phase = phase;
    t.period = seconds(1);
    t.processes = rows;
    watch_.Report(t, now, events_);
  }

  MonoTime t0_ = MonoFromSeconds(100);
  ProcessWatch watch_;
  EventRecorder events_;
};

TEST_F(ProcessWatchTest, AKilledProcessRaisesAnAlarmStampedAtItsDeathAndItsReturnClearsIt) {
  Report({Running("scm"), LightsKilled()}, t0_);
  ASSERT_EQ(events_.events().size(), 1u);
  const Event& exited = events_.events()[0];
  EXPECT_EQ(exited.code, kProcessExited);
  EXPECT_EQ(exited.severity, Severity::kAlarm);
  EXPECT_TRUE(exited.active);
  EXPECT_EQ(exited.device, "process/lights");
  EXPECT_EQ(events_.stamps()[0], At(10)) << "stamped when it died, not when the SCM heard";
  EXPECT_EQ(exited.message,
            "process lights (pid 4242, on lab-pc): killed by signal 9 (SIGKILL); the launcher "
            "starts it again in 1.0 s (restart 1)");

  // The launcher says the same every second: logged once.
  Report({Running("scm"), LightsKilled()}, t0_ + seconds(1));
  EXPECT_EQ(events_.events().size(), 1u);

  Report({Running("scm"), LightsBack()}, t0_ + seconds(2));
  ASSERT_EQ(events_.events().size(), 2u);
  const Event& back = events_.events()[1];
  EXPECT_EQ(back.code, kProcessRestarted);
  EXPECT_EQ(back.severity, Severity::kInfo);
  EXPECT_FALSE(back.active) << "clears the alarm";
  EXPECT_EQ(back.device, "process/lights");
  EXPECT_EQ(events_.stamps()[1], At(12)) << "stamped when it was back";
  EXPECT_EQ(back.message,
            "process lights (pid 5555, on lab-pc) is running again (restart 1) after it was "
            "killed by signal 9 (SIGKILL)");
  Report({Running("scm"), LightsBack()}, t0_ + seconds(3));
  EXPECT_EQ(events_.events().size(), 2u) << "and its return once";

  // Killed again: a new alarm.
  ProcessView again = LightsBack();
  again.phase = ProcessPhase::kExited;
  again.pid = 0;
  again.exits = 2;
  again.since = At(20);
  again.last_exit = ProcessExit{ExitStatus{3, 0}, 5555, At(20)};
  again.restart_at = At(21);
  Report({Running("scm"), again}, t0_ + seconds(10));
  ASSERT_EQ(events_.events().size(), 3u);
  EXPECT_EQ(events_.events()[2].code, kProcessExited);
  EXPECT_THAT(events_.events()[2].message, HasSubstr("exited with code 3"));
  EXPECT_THAT(events_.events()[2].message, HasSubstr("(restart 2)"));
}

TEST_F(ProcessWatchTest, AKilledScmLogsItsOwnDeathOnceBackFromTheLaunchersLastTable) {
  // The SCM's own row as the restarted SCM first reads it: started again, not ready yet.
  ProcessView scm;
  scm.name = "scm";
  scm.phase = ProcessPhase::kStarting;
  scm.pid = 901;
  scm.starts = 2;
  scm.since = At(30.05);
  scm.exits = 1;
  scm.last_exit = ProcessExit{kKilled, 900, At(30)};
  Report({scm}, t0_);
  ASSERT_EQ(events_.events().size(), 1u);
  EXPECT_EQ(events_.events()[0].code, kProcessExited);
  EXPECT_EQ(events_.stamps()[0], At(30)) << "the time of its death, before this SCM ran";
  EXPECT_THAT(events_.events()[0].message,
              HasSubstr("process scm (pid 900, on lab-pc): killed by signal 9 (SIGKILL); the "
                        "launcher is starting it again (restart 1)"));
  // Ready (its heartbeat heard): back.
  scm.phase = ProcessPhase::kRunning;
  scm.since = At(31);
  Report({scm}, t0_ + milliseconds(500));
  ASSERT_EQ(events_.events().size(), 2u);
  EXPECT_EQ(events_.events()[1].code, kProcessRestarted);
  EXPECT_EQ(events_.stamps()[1], At(31));
}

TEST_F(ProcessWatchTest, AnExitLearntAfterTheReturnIsLoggedBeforeIt) {
  // The SCM was down while the lights died and came back: it hears of both at once.
  Report({LightsBack()}, t0_);
  ASSERT_EQ(events_.events().size(), 2u);
  EXPECT_EQ(events_.events()[0].code, kProcessExited);
  EXPECT_EQ(events_.stamps()[0], At(10));
  EXPECT_THAT(events_.events()[0].message, HasSubstr("the launcher started it again (restart 1)"));
  EXPECT_EQ(events_.events()[1].code, kProcessRestarted);
  EXPECT_EQ(events_.stamps()[1], At(12));
}

TEST_F(ProcessWatchTest, WhatTheEventLogHoldsIsNotLoggedAgain) {
  // An SCM that logged the lights' death and return, then was restarted: it starts from its log.
  watch_.Logged(kProcessExited, "process/lights", At(10));
  watch_.Logged(kProcessRestarted, "process/lights", At(12));
  watch_.Logged(kProcessExited, "signal_1", At(50));       // not a process: ignored
  watch_.Logged("device_lost", "process/lights", At(50));  // not a process event: ignored
  Report({LightsBack()}, t0_);
  EXPECT_TRUE(events_.events().empty());
  // Only the death logged (the SCM died before the return): the return is.
  ProcessWatch other(Params());
  other.Logged(kProcessExited, "process/lights", At(10));
  ProcessView row = LightsBack();
  ProcessTableView t;
  t.city = "small_town";
  t.host = "lab-pc";
  t.processes = std::span(&row, 1);
  other.Report(t, t0_, events_);
  ASSERT_EQ(events_.events().size(), 1u);
  EXPECT_EQ(events_.events()[0].code, kProcessRestarted);
}

TEST_F(ProcessWatchTest, AnExitWithCodeZeroIsAWarningAndANoRestartIsSaid) {
  ProcessView agent;
  agent.name = "planner";
  agent.phase = ProcessPhase::kStopped;
  agent.starts = 1;
  agent.since = At(40);
  agent.exits = 1;
  agent.last_exit = ProcessExit{ExitStatus{0, 0}, 77, At(40)};
  Report({agent}, t0_);
  ASSERT_EQ(events_.events().size(), 1u);
  EXPECT_EQ(events_.events()[0].severity, Severity::kWarning);
  EXPECT_EQ(events_.events()[0].message,
            "process planner (pid 77, on lab-pc): exited with code 0; it is not started again");
}

TEST_F(ProcessWatchTest, ACrashLoopIsSaidWithTheWaitBeforeTheNextStart) {
  ProcessView p = LightsKilled();
  p.phase = ProcessPhase::kCrashLoop;
  p.starts = 5;
  p.exits = 5;
  p.restart_at = At(52);
  Report({p}, t0_);
  ASSERT_EQ(events_.events().size(), 1u);
  EXPECT_THAT(events_.events()[0].message,
              HasSubstr("it is in a crash loop (5 exits so far): the launcher starts it again in "
                        "42 s (restart 5)"));
}

TEST_F(ProcessWatchTest, AStopByTheLauncherRaisesNothing) {
  ProcessView stopped = Running("traffic");
  stopped.phase = ProcessPhase::kStopped;  // Down: no exit of its own
  Report({stopped}, t0_, "lab-pc", LauncherPhase::kStopping);
  EXPECT_TRUE(events_.events().empty());
  // And a launcher that said it was stopping is not lost when it falls silent.
  watch_.Check(t0_ + seconds(60), events_);
  EXPECT_TRUE(events_.events().empty());
  EXPECT_EQ(watch_.next_deadline(), MonoTime::max());
}

TEST_F(ProcessWatchTest, ASilentLauncherIsLostAfterThreePeriodsAndHeardAgainLater) {
  Report({Running("lights")}, t0_);
  EXPECT_EQ(watch_.launchers(), 1u);
  EXPECT_EQ(watch_.next_deadline(), t0_ + seconds(3) + Duration(1));
  watch_.Check(t0_ + seconds(3), events_);
  EXPECT_TRUE(events_.events().empty()) << "three periods of silence are not yet lost";
  watch_.Check(t0_ + seconds(3) + milliseconds(1), events_);
  ASSERT_EQ(events_.events().size(), 1u);
  EXPECT_EQ(events_.events()[0].code, kLauncherLost);
  EXPECT_EQ(events_.events()[0].severity, Severity::kAlarm);
  EXPECT_EQ(events_.events()[0].device, "launcher/lab-pc");
  EXPECT_EQ(watch_.launchers(), 0u);
  watch_.Check(t0_ + seconds(10), events_);
  EXPECT_EQ(events_.events().size(), 1u) << "lost once";
  // A new launcher session on the host (`autodrive-city up` again).
  Report({Running("lights")}, t0_ + seconds(20), "lab-pc", LauncherPhase::kStarting, "small_town",
         8);
  ASSERT_EQ(events_.events().size(), 2u);
  EXPECT_EQ(events_.events()[1].code, kLauncherBack);
  EXPECT_FALSE(events_.events()[1].active);
  EXPECT_THAT(events_.events()[1].message, HasSubstr("it was restarted"));
}

TEST_F(ProcessWatchTest, TheScmsOwnStallDoesNotMakeALauncherLost) {
  Report({Running("lights")}, t0_);
  // The SCM was stopped for 5 s: the tables of that time are still on their way in.
  watch_.OnStall(t0_ + seconds(5));
  watch_.Check(t0_ + seconds(5), events_);
  EXPECT_TRUE(events_.events().empty());
  EXPECT_EQ(watch_.next_deadline(), t0_ + seconds(5) + milliseconds(500) + Duration(1));
  Report({Running("lights")}, t0_ + seconds(5) + milliseconds(100));
  watch_.Check(t0_ + seconds(6), events_);
  EXPECT_TRUE(events_.events().empty());
}

TEST_F(ProcessWatchTest, AnotherCitysTableIsIgnoredAndEachHostsProcessesAreTheirOwn) {
  Report({LightsKilled()}, t0_, "lab-pc", LauncherPhase::kRunning, "other_town");
  EXPECT_TRUE(events_.events().empty());
  EXPECT_EQ(watch_.counters().foreign_city, 1u);
  // Two launchers each run a process called "lights": each death is its own.
  Report({LightsKilled()}, t0_, "host-a");
  ProcessView earlier = LightsKilled();
  earlier.last_exit->at = At(9);
  Report({earlier}, t0_, "host-b");
  ASSERT_EQ(events_.events().size(), 2u);
  EXPECT_THAT(events_.events()[0].message, HasSubstr("on host-a"));
  EXPECT_THAT(events_.events()[1].message, HasSubstr("on host-b"));
}

TEST(ProcessPhase, WireValuesOutsideTheStatesAreNone) {
  EXPECT_EQ(ProcessPhaseFromWire(2), ProcessPhase::kRunning);
  EXPECT_FALSE(ProcessPhaseFromWire(6).has_value());
  EXPECT_EQ(LauncherPhaseFromWire(2), LauncherPhase::kStopping);
  EXPECT_FALSE(LauncherPhaseFromWire(3).has_value());
}

}  // namespace
}  // namespace autodrive::scm
