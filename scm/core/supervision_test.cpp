// Device supervision in-process: reports as views, explicit times, the real runtime.
#include "scm/core/supervision.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <deque>

#include "common/test_support.h"
#include "scm/core/device_table.h"

namespace autodrive::scm {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using ::testing::HasSubstr;

class SupervisionTest : public ::testing::Test {
 protected:
  SupervisionTest()
      : runtime_(
            std::make_unique<City>(LoadCity(test::SourceDir() / "config/cities/small_town.yaml"))),
        supervisor_(runtime_, Params()),
        sent_(runtime_.heads().size()) {
    runtime_.Start(t0_, {});
    for (auto& s : sent_) s = SentCommand{Aspect::kRed, t0_};
  }
  static SupervisionParams Params() {
    SupervisionParams p;
    p.city = "small_town";
    p.timeout = milliseconds(500);
    p.mismatch = seconds(1);
    return p;
  }
  DeviceReportView Light(std::uint32_t head, Aspect shown, std::string_view host = "infra/a") {
    names_.push_back("signal_" + std::to_string(head));
    DeviceReportView r;
    r.device_id = names_.back();
    r.city = "small_town";
    r.host = host;
    r.displayed = shown;
    return r;
  }
  void ReportAll(MonoTime now, Aspect shown = Aspect::kRed) {
    for (const auto& h : runtime_.heads()) {
      supervisor_.Report(Light(h.id.value(), shown), now, runtime_, events_);
    }
  }
  std::size_t Index(const std::string& name) const { return *runtime_.Find(name); }
  bool Latched(const std::string& name) const {
    return runtime_.intersections()[Index(name)].controller->latched();
  }

  MonoTime t0_ = MonoFromSeconds(100);
  CityRuntime runtime_;
  DeviceSupervisor supervisor_;
  std::vector<SentCommand> sent_;
  EventRecorder events_;
  std::deque<std::string> names_;  // keeps the views' text alive
};

TEST_F(SupervisionTest, StartUpWaitsUntilEveryLightOfTheIntersectionHasReported) {
  supervisor_.Check(t0_, sent_, runtime_, events_);
  const auto& centre = *runtime_.intersections()[Index("centre")].controller;
  // Nothing reported yet: the controller is told its devices are not ready, so its start-up
  // flash does not end even when its time is up.
  runtime_.Step(ClockReading{t0_ + seconds(10), Time{}, 0}, DayClock::At(std::chrono::hours(12)),
                nullptr, events_);
  EXPECT_EQ(centre.stage(), Stage::kStartupFlash);
  ReportAll(t0_ + seconds(10));
  supervisor_.Check(t0_ + seconds(10), sent_, runtime_, events_);
  runtime_.Step(ClockReading{t0_ + seconds(10), Time{}, 0}, DayClock::At(std::chrono::hours(12)),
                nullptr, events_);
  EXPECT_EQ(centre.stage(), Stage::kAllRed) << "every light reported: the start-up goes on";
  EXPECT_FALSE(centre.latched());
  EXPECT_EQ(supervisor_.lost(), 0u);
}

TEST_F(SupervisionTest, StartUpWaitsUntilEveryLightFollowsTheScmNotOnlyReports) {
  // A big city's light host may report before it has discovered the SCM's command writers:
  // its lights report their own start-up flash (mode FLASH) until the SCM's first command
  // arrives. Taking them as ready would command red and latch the intersection on a
  // mismatch that is only a command still on its way.
  const auto& centre = *runtime_.intersections()[Index("centre")].controller;
  for (auto& s : sent_) s = SentCommand{Aspect::kFlashingRed, t0_};  // the start-up flash's
  const auto report_all = [&](MonoTime at, std::uint8_t mode) {
    for (const auto& h : runtime_.heads()) {
      DeviceReportView r = Light(h.id.value(), Aspect::kFlashingRed);
      r.mode = mode;
      supervisor_.Report(r, at, runtime_, events_);
    }
    supervisor_.Check(at, sent_, runtime_, events_);
    runtime_.Step(ClockReading{at, Time{}, 0}, DayClock::At(std::chrono::hours(12)), nullptr,
                  events_);
  };
  report_all(t0_ + seconds(10), /*FLASH*/ 1);
  EXPECT_EQ(centre.stage(), Stage::kStartupFlash) << "reported, but not following yet";
  report_all(t0_ + seconds(20), /*FLASH*/ 1);
  EXPECT_EQ(centre.stage(), Stage::kStartupFlash);
  EXPECT_FALSE(centre.latched());
  EXPECT_TRUE(events_.WithCode("device_mismatch").empty());
  report_all(t0_ + seconds(21), /*NORMAL: showing the SCM's flashing red*/ 0);
  EXPECT_EQ(centre.stage(), Stage::kAllRed) << "every light follows: the start-up goes on";
  EXPECT_FALSE(centre.latched());
}

TEST_F(SupervisionTest, AFaultDuringTheStartUpHoldsItAndOnlyAFaultAfterItLatches) {
  // A serial board that answers after its light host's first report: the light reports
  // itself offline for a moment during the start-up flash. The intersection waits for it, as
  // for a light not yet heard, instead of latching until an operator resets it.
  const auto& centre = *runtime_.intersections()[Index("centre")].controller;
  const auto report = [&](MonoTime at, DeviceHealth signal5) {
    for (const auto& h : runtime_.heads()) {
      DeviceReportView r = Light(h.id.value(), Aspect::kRed);
      r.health = h.id.value() == 5 ? signal5 : DeviceHealth::kOk;
      supervisor_.Report(r, at, runtime_, events_);
    }
    supervisor_.Check(at, sent_, runtime_, events_);
    runtime_.Step(ClockReading{at, Time{}, 0}, DayClock::At(std::chrono::hours(12)), nullptr,
                  events_);
  };
  report(t0_ + seconds(10), DeviceHealth::kOffline);
  EXPECT_EQ(centre.stage(), Stage::kStartupFlash) << "the start-up waits for signal_5";
  EXPECT_FALSE(centre.latched());
  ASSERT_EQ(events_.WithCode("device_fault").size(), 1u);
  EXPECT_THAT(events_.WithCode("device_fault")[0].message,
              HasSubstr("signal_5 reports a fault: ; the start-up flash waits for it"));
  EXPECT_EQ(runtime_.intersections()[Index("north_t")].controller->stage(), Stage::kAllRed)
      << "the other intersection starts";
  report(t0_ + seconds(11), DeviceHealth::kOffline);
  EXPECT_EQ(centre.stage(), Stage::kStartupFlash);
  EXPECT_EQ(events_.WithCode("device_fault").size(), 1u) << "raised once";
  report(t0_ + seconds(12), DeviceHealth::kOk);
  EXPECT_EQ(centre.stage(), Stage::kAllRed) << "healthy and following: the start-up goes on";
  EXPECT_FALSE(centre.latched());
  // After the start-up a fault latches, as before.
  report(t0_ + seconds(13), DeviceHealth::kFault);
  EXPECT_TRUE(centre.latched());
  EXPECT_EQ(centre.latch_reason(), "signal_5 has a fault");
  EXPECT_EQ(events_.WithCode("device_fault").size(), 2u);
}

TEST_F(SupervisionTest, ALightNotHeardForTheTimeOutIsLostAndLatchesItsIntersectionOnly) {
  ReportAll(t0_);
  // Everyone but signal_5 (centre) reports again.
  const MonoTime later = t0_ + milliseconds(600);
  for (const auto& h : runtime_.heads()) {
    if (h.id.value() != 5)
      supervisor_.Report(Light(h.id.value(), Aspect::kRed), later, runtime_, events_);
  }
  supervisor_.Check(later, sent_, runtime_, events_);
  EXPECT_TRUE(Latched("centre"));
  EXPECT_FALSE(Latched("north_t"));
  ASSERT_EQ(events_.WithCode("device_lost").size(), 1u);
  EXPECT_THAT(events_.WithCode("device_lost")[0].message, HasSubstr("signal_5 lost"));
  EXPECT_THAT(events_.WithCode("failsafe_flash")[0].message, HasSubstr("devices lost: signal_5"));
  EXPECT_THAT(*supervisor_.ResetRefusal(Index("centre")), HasSubstr("signal_5 is still lost"));
  EXPECT_FALSE(supervisor_.ResetRefusal(Index("north_t")));
}

// Found from outside (issue 30): a 0.49 s stall of the SCM (no fault, no command) was read as
// every light's silence and latched the city, although the lights' reports came 40 ms later.
TEST_F(SupervisionTest, AfterTheScmsOwnStallDevicesAreReCheckedBeforeAnyIsDeclaredLost) {
  ReportAll(t0_);
  supervisor_.Check(t0_, sent_, runtime_, events_);
  // The SCM stalls for 0.6 s: at the pass that follows, every light's last report is older than
  // the time-out, because the reports sent meanwhile have not been taken yet.
  const MonoTime resumed = t0_ + milliseconds(600);
  supervisor_.OnStall(resumed);
  EXPECT_EQ(supervisor_.stall_settle(), milliseconds(250));
  supervisor_.Check(resumed, sent_, runtime_, events_);
  EXPECT_EQ(supervisor_.lost(), 0u);
  EXPECT_FALSE(Latched("centre"));
  EXPECT_FALSE(Latched("north_t"));
  // The loop is told when to re-check.
  EXPECT_LE(supervisor_.next_deadline(), resumed + supervisor_.stall_settle() + milliseconds(1));
  // The backlog arrives 40 ms later, for every light but signal_5, which is really gone.
  const MonoTime backlog = resumed + milliseconds(40);
  for (const auto& h : runtime_.heads()) {
    if (h.id.value() != 5) {
      supervisor_.Report(Light(h.id.value(), Aspect::kRed), backlog, runtime_, events_);
    }
  }
  supervisor_.Check(backlog, sent_, runtime_, events_);
  EXPECT_EQ(supervisor_.lost(), 0u) << "still within the re-check";
  // At the re-check only the light that stayed silent is lost, and only its intersection
  // latches.
  const MonoTime recheck = resumed + supervisor_.stall_settle() + milliseconds(1);
  supervisor_.Check(recheck, sent_, runtime_, events_);
  EXPECT_EQ(supervisor_.lost(), 1u);
  EXPECT_TRUE(Latched("centre"));
  EXPECT_FALSE(Latched("north_t"));
  ASSERT_EQ(events_.WithCode("device_lost").size(), 1u);
  EXPECT_THAT(events_.WithCode("device_lost")[0].message, HasSubstr("signal_5 lost"));
}

TEST_F(SupervisionTest, WithNoStallALostLightLatchesOnTheTimeOutAsBefore) {
  ReportAll(t0_);
  supervisor_.Check(t0_, sent_, runtime_, events_);
  supervisor_.Check(t0_ + milliseconds(500), sent_, runtime_, events_);
  EXPECT_EQ(supervisor_.lost(), 0u);
  EXPECT_EQ(supervisor_.next_deadline(), t0_ + milliseconds(500) + Duration(1));
  supervisor_.Check(t0_ + milliseconds(501), sent_, runtime_, events_);
  EXPECT_EQ(supervisor_.lost(), runtime_.heads().size());
  EXPECT_TRUE(Latched("centre"));
  EXPECT_TRUE(Latched("north_t"));
}

// Issue 36: a light host's network cut latches its intersections; once every light reports
// again and follows the SCM for `recover_after`, the flash ends on its own through start-up.
class RecoveryTest : public SupervisionTest {
 protected:
  // signal_5 (centre) silent from `from` for 0.6 s: centre latches for a lost light.
  MonoTime LoseSignal5(MonoTime from) {
    ReportAll(from);
    supervisor_.Check(from, sent_, runtime_, events_);
    const MonoTime later = from + milliseconds(600);
    for (const auto& h : runtime_.heads()) {
      if (h.id.value() != 5)
        supervisor_.Report(Light(h.id.value(), Aspect::kRed), later, runtime_, events_);
    }
    supervisor_.Check(later, sent_, runtime_, events_);
    EXPECT_TRUE(Latched("centre"));
    return later;
  }
  // Every light reports at `at` (mode: 0 NORMAL, following; 1 FLASH, its own), then a check.
  void Back(MonoTime at, std::uint8_t mode = 0, DeviceHealth health = DeviceHealth::kOk) {
    for (const auto& h : runtime_.heads()) {
      DeviceReportView r = Light(h.id.value(), Aspect::kFlashingRed);
      r.mode = mode;
      r.health = h.id.value() == 5 ? health : DeviceHealth::kOk;
      supervisor_.Report(r, at, runtime_, events_);
    }
    supervisor_.Check(at, sent_, runtime_, events_);
  }
};

TEST_F(RecoveryTest, LostLightsBackAndFollowingEndTheFlashAfterRecoverAfter) {
  const MonoTime latched = LoseSignal5(t0_);
  const MonoTime back = latched + seconds(2);
  Back(back);
  EXPECT_TRUE(Latched("centre")) << "back, but not for recover_after yet";
  EXPECT_LE(supervisor_.next_deadline(), back + seconds(1)) << "the loop wakes to recover";
  Back(back + milliseconds(999));
  EXPECT_TRUE(Latched("centre"));
  Back(back + seconds(1));
  EXPECT_FALSE(Latched("centre"));
  EXPECT_EQ(runtime_.intersections()[Index("centre")].controller->stage(), Stage::kFlash)
      << "restarting through start-up, as after a reset";
  ASSERT_EQ(events_.WithCode("failsafe_recovered").size(), 1u);
  EXPECT_THAT(events_.WithCode("failsafe_recovered")[0].message,
              HasSubstr("was: devices lost: signal_5"));
  EXPECT_FALSE(Latched("north_t"));
}

TEST_F(RecoveryTest, LightsInTheirOwnFlashAreNotFollowingAndDoNotRecover) {
  const MonoTime latched = LoseSignal5(t0_);
  Back(latched + seconds(1), /*FLASH*/ 1);
  Back(latched + seconds(5), /*FLASH*/ 1);
  EXPECT_TRUE(Latched("centre"));
  Back(latched + seconds(6));  // they take the SCM's flashing red: following from now
  EXPECT_TRUE(Latched("centre"));
  Back(latched + seconds(7));
  EXPECT_FALSE(Latched("centre"));
}

TEST_F(RecoveryTest, AFaultWhileLatchedIsACauseTheLightsReturnDoesNotClear) {
  const MonoTime latched = LoseSignal5(t0_);
  Back(latched + seconds(1), 0, DeviceHealth::kFault);
  Back(latched + seconds(2));  // the fault went away: still for an operator to reset
  Back(latched + seconds(10));
  EXPECT_TRUE(Latched("centre"));
  EXPECT_TRUE(events_.WithCode("failsafe_recovered").empty());
  EXPECT_FALSE(supervisor_.ResetRefusal(Index("centre")));
}

TEST_F(RecoveryTest, AtMostMaxRecoveriesPerHourThenTheFlashWaitsForAReset) {
  MonoTime t = t0_;
  const int budget = SupervisionParams{}.max_recoveries_per_hour;
  EXPECT_EQ(budget, 20);
  for (int i = 0; i < budget; ++i) {
    t = LoseSignal5(t) + seconds(1);
    Back(t);
    Back(t + seconds(1));
    EXPECT_FALSE(Latched("centre")) << "recovery " << i + 1;
    t += seconds(2);
  }
  t = LoseSignal5(t) + seconds(1);
  Back(t);
  Back(t + seconds(1));
  EXPECT_TRUE(Latched("centre")) << "one more than the budget within the hour";
  ASSERT_EQ(events_.WithCode("failsafe_recovery_exhausted").size(), 1u);
  Back(t + seconds(30));
  EXPECT_EQ(events_.WithCode("failsafe_recovery_exhausted").size(), 1u) << "said once";
  EXPECT_TRUE(Latched("centre"));
  // An hour after the first, the budget has room again.
  t = t0_ + std::chrono::hours(1) + seconds(10);
  ASSERT_TRUE(runtime_.intersections()[Index("centre")].controller->Reset(t).ok);
  supervisor_.OnReset(Index("centre"), t, std::nullopt);
  t = LoseSignal5(t) + seconds(1);
  Back(t);
  Back(t + seconds(1));
  EXPECT_FALSE(Latched("centre"));
}

TEST(RecoveryOff, WithRecoverAfterZeroALostLightFlashLastsUntilReset) {
  CityRuntime runtime(
      std::make_unique<City>(LoadCity(test::SourceDir() / "config/cities/small_town.yaml")));
  SupervisionParams p;
  p.city = "small_town";
  p.recover_after = Duration::zero();
  DeviceSupervisor supervisor(runtime, p);
  const MonoTime t0 = MonoFromSeconds(100);
  runtime.Start(t0, {});
  std::vector<SentCommand> sent(runtime.heads().size(), SentCommand{Aspect::kRed, t0});
  EventRecorder events;
  const auto report = [&](MonoTime at) {
    for (const auto& h : runtime.heads()) {
      const std::string name = "signal_" + std::to_string(h.id.value());
      DeviceReportView r;
      r.device_id = name;
      r.city = "small_town";
      r.host = "infra/a";
      r.displayed = Aspect::kFlashingRed;
      supervisor.Report(r, at, runtime, events);
    }
    supervisor.Check(at, sent, runtime, events);
  };
  report(t0);
  supervisor.Check(t0 + seconds(1), sent, runtime, events);  // everyone silent: lost
  const auto& centre = *runtime.intersections()[*runtime.Find("centre")].controller;
  EXPECT_TRUE(centre.latched());
  report(t0 + seconds(2));
  report(t0 + seconds(60));
  EXPECT_TRUE(centre.latched());
  EXPECT_TRUE(events.WithCode("failsafe_recovered").empty());
}

TEST_F(SupervisionTest, AnotherCitysLightsAreIgnoredAndReportedOnce) {
  DeviceReportView r = Light(1, Aspect::kGreen);
  r.city = "driving_school";
  for (int i = 0; i < 5; ++i) supervisor_.Report(r, t0_, runtime_, events_);
  EXPECT_EQ(supervisor_.counters().foreign_city, 5u);
  ASSERT_EQ(events_.WithCode("foreign_device").size(), 1u);
  EXPECT_THAT(events_.WithCode("foreign_device")[0].message,
              HasSubstr("ignored signal_1 from host 'infra/a' of city 'driving_school'"));
  EXPECT_FALSE(supervisor_.head(*runtime_.HeadIndex(SignalHeadId(1))).seen);
}

TEST_F(SupervisionTest, ASecondHostClaimingALightIsIgnoredAndRaisesAnAlarm) {
  ReportAll(t0_);
  supervisor_.Report(Light(2, Aspect::kGreen, "infra/b"), t0_, runtime_, events_);
  EXPECT_EQ(supervisor_.counters().foreign_host, 1u);
  ASSERT_EQ(events_.WithCode("device_host_conflict").size(), 1u);
  const HeadHealth& h = supervisor_.head(*runtime_.HeadIndex(SignalHeadId(2)));
  EXPECT_EQ(h.host, "infra/a");
  EXPECT_EQ(h.displayed, Aspect::kRed) << "the stranger's report changed nothing";
}

TEST_F(SupervisionTest, ALightShowingAnotherAspectThanItsCommandForTheMismatchTimeLatches) {
  ReportAll(t0_);
  supervisor_.Check(t0_, sent_, runtime_, events_);
  const std::size_t h = *runtime_.HeadIndex(SignalHeadId(4));
  for (int i = 1; i <= 12; ++i) {
    const MonoTime now = t0_ + milliseconds(100 * i);
    ReportAll(now);
    supervisor_.Report(Light(4, Aspect::kGreen), now, runtime_, events_);
    supervisor_.Check(now, sent_, runtime_, events_);
    if (i <= 10) {
      EXPECT_FALSE(Latched("centre")) << i;
    }
  }
  EXPECT_TRUE(Latched("centre"));
  EXPECT_THAT(events_.WithCode("device_mismatch")[0].message,
              HasSubstr("signal_4 shows green but was commanded red"));
  (void)h;
}

TEST_F(SupervisionTest, AMonitorLatchIsFollowedAndStaleReportsAfterAResetAreIgnored) {
  const std::size_t x = Index("centre");
  DeviceReportView m;
  m.device_id = "mmu_centre";
  m.city = "small_town";
  m.host = "infra/a";
  m.health = DeviceHealth::kFault;
  m.detail = "latched: signal_4 and signal_5 both showed go";
  supervisor_.Report(m, t0_, runtime_, events_);
  EXPECT_TRUE(Latched("centre"));
  EXPECT_TRUE(supervisor_.monitor_seen(x));
  ASSERT_EQ(events_.WithCode("mmu_flash").size(), 1u);
  // The operator's reset is accepted; the monitor is asked to reset with command 7.
  runtime_.intersections()[x].controller->Reset(t0_ + seconds(1));
  supervisor_.OnReset(x, t0_ + seconds(1), 7);
  m.last_command_id = 6;  // a report sent before the command arrived
  supervisor_.Report(m, t0_ + seconds(1), runtime_, events_);
  EXPECT_FALSE(Latched("centre")) << "a stale latch report does not latch again";
  EXPECT_EQ(supervisor_.counters().stale_monitor, 1u);
  m.last_command_id = 7;
  m.health = DeviceHealth::kOk;
  supervisor_.Report(m, t0_ + seconds(1), runtime_, events_);
  EXPECT_FALSE(supervisor_.monitor_latched(x));
  m.health = DeviceHealth::kFault;  // latched again, after our reset: that counts
  supervisor_.Report(m, t0_ + seconds(2), runtime_, events_);
  EXPECT_TRUE(Latched("centre"));
  EXPECT_FALSE(Latched("north_t"));
}

TEST_F(SupervisionTest, AResetTheMonitorNeverConfirmsRaisesAnAlarmAndItsReportsCountAgain) {
  const std::size_t x = Index("north_t");
  supervisor_.OnReset(x, t0_, 3);
  supervisor_.Check(t0_ + seconds(6), sent_, runtime_, events_);
  ASSERT_EQ(events_.WithCode("mmu_reset_unconfirmed").size(), 1u);
  DeviceReportView m;
  m.device_id = "mmu_north_t";
  m.city = "small_town";
  m.host = "infra/a";
  m.health = DeviceHealth::kFault;
  supervisor_.Report(m, t0_ + seconds(6), runtime_, events_);
  EXPECT_TRUE(Latched("north_t"));
}

// The device table shows what the supervisor took as the city's own devices, and nothing else.
TEST_F(SupervisionTest, TheDeviceTableHasEveryLightAndOnlyTheCitysOwnReports) {
  DeviceTable table(runtime_, Params().timeout, t0_);
  ASSERT_EQ(table.rows().size(), runtime_.heads().size()) << "every light, before any report";
  for (const auto& row : table.rows()) EXPECT_FALSE(row.reported) << row.device_id;
  const auto take = [&](const DeviceReportView& r, MonoTime at) {
    if (supervisor_.Report(r, at, runtime_, events_)) table.Take(r, at);
  };
  DeviceReportView r = Light(1, Aspect::kRed);
  r.health = DeviceHealth::kDegraded;
  r.detail = "refused green -> yellow";
  r.displayed_state = 1;
  r.stamp = Time(seconds(1234));
  take(r, t0_);
  const DeviceRow& row = table.rows()[*runtime_.HeadIndex(SignalHeadId(1))];
  EXPECT_TRUE(row.reported);
  EXPECT_EQ(row.host, "infra/a");
  EXPECT_EQ(row.health, 1);
  EXPECT_EQ(row.detail, "refused green -> yellow");
  EXPECT_EQ(row.last_report, Time(seconds(1234)));
  const std::uint64_t revision = table.revision();
  // A second host claiming the light, and another city's light of the same name: not shown.
  DeviceReportView stranger = Light(1, Aspect::kGreen, "infra/b");
  stranger.health = DeviceHealth::kFault;
  take(stranger, t0_ + milliseconds(10));
  DeviceReportView foreign = Light(1, Aspect::kGreen);
  foreign.city = "other_town";
  foreign.health = DeviceHealth::kFault;
  take(foreign, t0_ + milliseconds(20));
  EXPECT_EQ(row.host, "infra/a");
  EXPECT_EQ(row.health, 1);
  EXPECT_EQ(table.revision(), revision);
  // A monitor gets its row with its first report.
  DeviceReportView m;
  m.device_id = "mmu_centre";
  m.city = "small_town";
  m.host = "infra/a";
  take(m, t0_ + milliseconds(30));
  ASSERT_EQ(table.rows().size(), runtime_.heads().size() + 1);
  EXPECT_EQ(table.rows().back().device_id, "mmu_centre");
  EXPECT_GT(table.revision(), revision);
}

TEST_F(SupervisionTest, TheDeviceTableGoesOutEveryPeriodAndSoonAfterAChangeButNotMoreOften) {
  DeviceTable table(runtime_, Params().timeout, t0_);
  EXPECT_FALSE(table.Due(t0_));
  EXPECT_EQ(table.next_deadline(), t0_ + DeviceTable::kPeriod);
  table.Take(Light(1, Aspect::kRed), t0_ + milliseconds(100));
  EXPECT_TRUE(table.Due(t0_ + milliseconds(100))) << "a change, nothing sent for long";
  table.Refresh(t0_ + milliseconds(100));
  table.Take(Light(1, Aspect::kRed), t0_ + milliseconds(150));
  EXPECT_FALSE(table.Due(t0_ + milliseconds(150))) << "the same report again changes nothing";
  DeviceReportView green = Light(1, Aspect::kGreen);
  green.displayed_state = 3;
  const std::uint64_t revision = table.revision();
  table.Take(green, t0_ + milliseconds(160));
  EXPECT_GT(table.revision(), revision);
  EXPECT_EQ(table.rows()[*runtime_.HeadIndex(SignalHeadId(1))].displayed_state, 3);
  EXPECT_EQ(table.next_deadline(), t0_ + milliseconds(100) + DeviceTable::kPeriod)
      << "the lamps a light shows go out with the period";
  DeviceReportView degraded = green;
  degraded.health = DeviceHealth::kDegraded;
  table.Take(degraded, t0_ + milliseconds(170));
  EXPECT_FALSE(table.Due(t0_ + milliseconds(299))) << "at most every kMinInterval";
  EXPECT_EQ(table.next_deadline(), t0_ + milliseconds(100) + DeviceTable::kMinInterval);
  EXPECT_TRUE(table.Due(t0_ + milliseconds(300)));
  table.Refresh(t0_ + milliseconds(300));
  EXPECT_EQ(table.next_deadline(), t0_ + milliseconds(300) + DeviceTable::kPeriod);
}

TEST_F(SupervisionTest, ALightNotHeardForTheTimeOutIsLostInTheNextDeviceTable) {
  DeviceTable table(runtime_, Params().timeout, t0_);
  table.Take(Light(2, Aspect::kRed), t0_);
  const DeviceRow& row = table.rows()[*runtime_.HeadIndex(SignalHeadId(2))];
  table.Refresh(t0_ + milliseconds(400));
  EXPECT_FALSE(row.lost);
  const std::uint64_t revision = table.revision();
  table.Refresh(t0_ + milliseconds(600));  // 0.5 s time-out
  EXPECT_TRUE(row.lost);
  EXPECT_GT(table.revision(), revision);
  EXPECT_FALSE(table.rows()[*runtime_.HeadIndex(SignalHeadId(3))].lost) << "never reported";
  table.Take(Light(2, Aspect::kRed), t0_ + milliseconds(700));
  EXPECT_FALSE(row.lost) << "it reports again";
  EXPECT_TRUE(table.Due(t0_ + milliseconds(800))) << "and the table says so soon";
}

}  // namespace
}  // namespace autodrive::scm
