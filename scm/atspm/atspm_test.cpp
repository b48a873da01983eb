// The ATSPM measures on hand-built high-resolution logs: UDOT's golden PCD cycle, an
// oversaturated and an undersaturated approach, terminations, splits, pedestrians and
// pre-emptions (codes the SCM does not log yet), and the edges of a log: cut mid-cycle, a
// record missing, a plan change inside the window, records out of order, an empty window.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>

#include "common/error.h"
#include "scm/atspm/arrivals.h"
#include "scm/atspm/event_log.h"
#include "scm/atspm/pedestrian.h"
#include "scm/atspm/preemption.h"
#include "scm/atspm/report.h"
#include "scm/atspm/split_failure.h"
#include "scm/atspm/splits.h"
#include "scm/atspm/yellow_red.h"

namespace autodrive::scm::atspm {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

const Time kT0 = TimeFromSeconds(1'795'240'000.0);

Time At(double s) { return kT0 + FromSeconds(s); }
Window Span(double from_s, double to_s) { return {At(from_s), At(to_s)}; }

/// A log written in any order and read in time order (records of one instant in the order
/// they were added), as the SCM stores it.
class Log {
 public:
  void Add(double s, std::uint16_t code, std::uint16_t param) {
    events_.push_back({At(s), code, param});
  }
  /// A phase served as the SCM logs it: on and green, its termination, yellow, red clearance.
  void Service(std::uint16_t phase, double green_s, double green_len, double yellow,
               double red_clear, std::uint16_t termination = code::kPhaseForceOff) {
    const double y = green_s + green_len, r = y + yellow, end = r + red_clear;
    Add(green_s, 0, phase);
    Add(green_s, code::kPhaseBeginGreen, phase);
    Add(y, termination, phase);
    Add(y, code::kPhaseGreenTermination, phase);
    Add(y, code::kPhaseBeginYellow, phase);
    Add(r, code::kPhaseEndYellow, phase);
    Add(r, code::kPhaseBeginRedClearance, phase);
    Add(end, code::kPhaseEndRedClearance, phase);
    Add(end, 12, phase);
  }
  /// Channel `channel` occupied from `on_s` to `off_s`.
  void Detector(std::uint16_t channel, double on_s, double off_s) {
    Add(on_s, code::kDetectorOn, channel);
    Add(off_s, code::kDetectorOff, channel);
  }
  std::vector<Event> Events() const {
    std::vector<Event> sorted = events_;
    std::ranges::stable_sort(sorted, {}, &Event::at);
    return sorted;
  }

 private:
  std::vector<Event> events_;
};

ChannelMap OneToOne(std::uint16_t channel, std::uint16_t phase) {
  ChannelMap map;
  map.Add(channel, phase);
  return map;
}

double Sec(Duration d) { return ToSeconds(d); }

// -- Purdue Coordination Diagram --

TEST(Pcd, UdotsGoldenCycleGivesTwoArrivalsOnRedAnd585SecondsOfDelay) {
  // UDOT's CyclePcdTests (utahudot/udot-atspm @74359f72): red 07:45:00, green 07:50:00,
  // yellow 07:55:00, end 08:00:00, detector hits at +5 s and +10 s.
  Log log;
  log.Add(0, code::kPhaseEndYellow, 2);
  log.Add(300, code::kPhaseBeginGreen, 2);
  log.Add(600, code::kPhaseBeginYellow, 2);
  log.Add(900, code::kPhaseEndYellow, 2);
  log.Detector(5, 5, 5.5);
  log.Detector(5, 10, 10.5);
  const PcdResult r = Pcd(log.Events(), Span(0, 900), OneToOne(5, 2));
  ASSERT_EQ(r.phases.size(), 1u);
  ASSERT_EQ(r.phases[0].cycles.size(), 1u);
  const ArrivalTotals& t = r.phases[0].cycles[0].totals;
  EXPECT_EQ(t.volume, 2);
  EXPECT_EQ(t.on_red, 2);
  EXPECT_EQ(t.on_green, 0);
  EXPECT_EQ(t.on_yellow, 0);
  EXPECT_EQ(t.delay, seconds(585));
  EXPECT_EQ(t.red_time, seconds(300));
  EXPECT_EQ(t.green_time, seconds(300));
  EXPECT_EQ(t.yellow_time, seconds(300));
  EXPECT_EQ(r.phases[0].total.delay, seconds(585));
  EXPECT_EQ(r.phases[0].total.delay_per_vehicle(), milliseconds(292'500));
  // The same through the report scmctl prints.
  const Report report =
      Compute(Measure::kPcd, log.Events(), Span(0, 900), OneToOne(5, 2), MeasureOptions{});
  const auto& total = report.json["phases"][0]["total"];
  EXPECT_EQ(total["on_red"], 2);
  EXPECT_DOUBLE_EQ(total["delay_s"].get<double>(), 585.0);
  EXPECT_THAT(report.text, HasSubstr("2 arrivals: on green 0.0 %, yellow 0.0 %, red 100.0 %"));
}

TEST(Pcd, ArrivalsOnGreenYellowAndRedByBinAndByPlan) {
  // Two cycles of phase 1 (red 20 s, green 30 s, yellow+red clearance 5 s); channel 3 calls it.
  Log log;
  log.Add(0, code::kPhaseEndYellow, 1);
  for (const double g : {20.0, 75.0}) {
    log.Add(g, code::kPhaseBeginGreen, 1);
    log.Add(g + 30, code::kPhaseBeginYellow, 1);
    log.Add(g + 33, code::kPhaseEndYellow, 1);
  }
  // Cycle 1 [0, 53): 10 on red (delay 10 s), 20 on green (the instant green starts), 51 on
  // yellow. Cycle 2 [53, 108): 60 on red (15 s), 80 on green, 100 on green.
  for (const double t : {10.0, 20.0, 51.0, 60.0, 80.0, 100.0}) log.Detector(3, t, t + 0.5);
  log.Detector(4, 30, 31);  // another channel: not this phase's
  const PcdResult r = Pcd(log.Events(), Span(0, 120), OneToOne(3, 1), seconds(60));
  ASSERT_EQ(r.phases.size(), 1u);
  const PcdPhase& p = r.phases[0];
  ASSERT_EQ(p.cycles.size(), 2u);
  EXPECT_EQ(p.total.volume, 6);
  EXPECT_EQ(p.total.on_green, 3);
  EXPECT_EQ(p.total.on_yellow, 1);
  EXPECT_EQ(p.total.on_red, 2);
  EXPECT_EQ(p.total.delay, seconds(25));
  EXPECT_DOUBLE_EQ(p.total.percent_on_green(), 50.0);
  EXPECT_DOUBLE_EQ(p.total.percent_green_time(), 60.0 / 108.0 * 100.0);
  EXPECT_NEAR(p.total.platoon_ratio(), 50.0 / (60.0 / 108.0 * 100.0), 1e-12);
  EXPECT_EQ(p.cycles[0].arrivals[1].type, Arrival::kGreen);
  EXPECT_EQ(p.cycles[0].arrivals[2].type, Arrival::kYellow);
  // Bins of 60 s by the detector-on's time: [0, 60) has 10, 20, 51; [60, 120) 60, 80, 100.
  ASSERT_EQ(p.bins.size(), 2u);
  EXPECT_EQ(p.bins[0].second.volume, 3);
  EXPECT_EQ(p.bins[0].second.on_red, 1);
  EXPECT_EQ(p.bins[1].second.volume, 3);
  EXPECT_EQ(p.bins[1].second.on_green, 2);
  EXPECT_EQ(p.bins[1].second.delay, seconds(15));
  ASSERT_EQ(p.plans.size(), 1u);
  EXPECT_EQ(p.plans[0].first.plan, 0) << "no 131 in the log: unknown";
  EXPECT_EQ(p.plans[0].second.volume, 6);
}

// -- Purdue Split Failure --

/// Phase 2 served every 60 s: green 30 s from 0, yellow 3 s, red clearance 2 s; channel 2.
Log SplitFailApproach(bool saturated) {
  Log log;
  for (int k = 0; k < 10; ++k) {
    const double g = 60.0 * k;
    log.Service(2, g, 30, 3, 2, saturated ? code::kPhaseMaxOut : code::kPhaseGapOut);
    if (saturated) {
      // A queue that never clears: cars nose to tail over the stop bar through the green
      // (0.3 s gaps), and standing on it from the yellow through the red.
      for (double t = g; t < g + 30; t += 2.3) log.Detector(2, t, t + 2.0);
      log.Detector(2, g + 32.0, g + 59.9);
    } else {
      // Three cars early in the green, nothing in the red.
      for (const double t : {1.0, 3.0, 5.0}) log.Detector(2, g + t, g + t + 0.6);
    }
  }
  log.Service(2, 600, 30, 3, 2);  // the green that closes the last cycle
  return log;
}

TEST(SplitFailure, AnOversaturatedApproachFailsEverySplitAndAnUndersaturatedOneNone) {
  const Window w = Span(0, 600);
  const SplitFailResult over = SplitFailure(SplitFailApproach(true).Events(), w, OneToOne(2, 2));
  ASSERT_EQ(over.phases.size(), 1u);
  const SplitFailPhase& o = over.phases[0];
  ASSERT_EQ(o.cycles.size(), 10u);
  for (const SplitFailCycle& c : o.cycles) {
    EXPECT_GT(c.green_occupancy, kSplitFailThreshold);
    EXPECT_GT(c.red_occupancy, kSplitFailThreshold);
    EXPECT_TRUE(c.failed);
    EXPECT_EQ(c.termination, Termination::kMaxOut);
  }
  EXPECT_EQ(o.total.failures, 10);
  EXPECT_DOUBLE_EQ(o.total.percent_failures(), 100.0);
  EXPECT_EQ(o.bins.size(), 1u);
  EXPECT_EQ(o.bins[0].second.failures, 10);

  const SplitFailResult under = SplitFailure(SplitFailApproach(false).Events(), w, OneToOne(2, 2));
  ASSERT_EQ(under.phases.size(), 1u);
  EXPECT_EQ(under.phases[0].total.cycles, 10);
  EXPECT_EQ(under.phases[0].total.failures, 0);
  EXPECT_NEAR(under.phases[0].total.average_green_occupancy(), 1.8 / 30 * 100, 1e-9);
  EXPECT_DOUBLE_EQ(under.phases[0].total.average_red_occupancy(), 0.0);
}

TEST(SplitFailure, OccupancyMergesChannelsAndFailsOnlyAboveSeventyNinePercent) {
  // Greens of 25 s, red (end of yellow) 3 s after each; 5 s of red looked at.
  // Cycle 1: channel 1 on 0-15, channel 2 on 10-22.5: one call, 22.5 s (90 %), not 27.5 s;
  // red [28, 33) occupied 29-33 (80 %). Cycle 2: 19.75 of 25 s (79 %), 3.95 of 5 s (79 %).
  ChannelMap map;
  map.Add(1, 4);
  map.Add(2, 4);
  Log log;
  log.Service(4, 0, 25, 3, 2);
  log.Service(4, 65, 25, 3, 2);
  log.Service(4, 130, 25, 3, 2);
  log.Detector(1, 0, 15);
  log.Detector(2, 10, 22.5);
  log.Detector(1, 29, 34);
  log.Detector(2, 65, 84.75);
  log.Detector(2, 93, 96.95);
  const SplitFailResult r = SplitFailure(log.Events(), Span(0, 130), map);
  ASSERT_EQ(r.phases.size(), 1u);
  ASSERT_EQ(r.phases[0].cycles.size(), 2u);
  const SplitFailCycle& a = r.phases[0].cycles[0];
  EXPECT_NEAR(a.green_occupancy, 90.0, 1e-9);
  EXPECT_NEAR(a.red_occupancy, 80.0, 1e-9);
  EXPECT_TRUE(a.failed);
  const SplitFailCycle& b = r.phases[0].cycles[1];
  EXPECT_NEAR(b.green_occupancy, 79.0, 1e-9);
  EXPECT_NEAR(b.red_occupancy, 79.0, 1e-9);
  EXPECT_FALSE(b.failed) << "79 % is not above 79 %";
}

TEST(SplitFailure, ADetectorOnBeforeTheLogOrStillOnAtItsEndIsOccupiedToTheWindowsEdge) {
  Log log;
  log.Service(1, 0, 20, 3, 2);
  log.Service(1, 40, 20, 3, 2);
  log.Add(18, code::kDetectorOff, 7);   // was on when the log began
  log.Add(23.5, code::kDetectorOn, 7);  // and again from the red to the window's end
  const SplitFailResult r = SplitFailure(log.Events(), Span(0, 40), OneToOne(7, 1));
  ASSERT_EQ(r.phases.size(), 1u);
  ASSERT_EQ(r.phases[0].cycles.size(), 1u);
  EXPECT_NEAR(r.phases[0].cycles[0].green_occupancy, 90.0, 1e-9);
  EXPECT_NEAR(r.phases[0].cycles[0].red_occupancy, 90.0, 1e-9);
  EXPECT_TRUE(r.phases[0].cycles[0].failed);
}

// -- Purdue Phase Termination --

TEST(PhaseTermination, CountsEachTypeMarksRunsAndKeepsALoneGreenTerminationAsUnknown) {
  Log log;
  double t = 0;
  for (const std::uint16_t c : std::vector<std::uint16_t>{4, 4, 5, 5, 5, 6, 19, 20}) {
    log.Service(1, t, 10, 3, 2, c);
    t += 20;
  }
  // A green cut by a fail-safe: 7 alone.
  log.Add(t, code::kPhaseBeginGreen, 1);
  log.Add(t + 5, code::kPhaseGreenTermination, 1);
  const PhaseTerminationResult r = PhaseTermination(log.Events(), Span(0, 200), 2);
  ASSERT_EQ(r.phases.size(), 1u);
  const PhaseTerminations& p = r.phases[0];
  EXPECT_EQ(p.phase, 1);
  EXPECT_EQ(p.count(Termination::kGapOut), 2);
  EXPECT_EQ(p.count(Termination::kMaxOut), 3);
  EXPECT_EQ(p.count(Termination::kForceOff), 1);
  EXPECT_EQ(p.count(Termination::kTspEarlyForceOff), 1);
  EXPECT_EQ(p.count(Termination::kPreemptionForceOff), 1);
  EXPECT_EQ(p.count(Termination::kUnknown), 1) << "the 7s logged with a 4/5/6 are dropped";
  EXPECT_EQ(p.events.size(), 9u);
  // Consecutive 2: the second gap out, the second and third max out.
  EXPECT_EQ(p.consecutive_counts[static_cast<std::size_t>(Termination::kGapOut)], 1);
  EXPECT_EQ(p.consecutive_counts[static_cast<std::size_t>(Termination::kMaxOut)], 2);
  EXPECT_EQ(p.consecutive_counts[static_cast<std::size_t>(Termination::kForceOff)], 0);
  EXPECT_FALSE(p.events[0].consecutive);
  EXPECT_TRUE(p.events[1].consecutive);
  EXPECT_DOUBLE_EQ(p.percent(Termination::kMaxOut), 3.0 / 8.0 * 100.0);
  EXPECT_DOUBLE_EQ(p.percent(Termination::kUnknown), 0.0);

  EXPECT_THAT(
      [&] { (void)PhaseTermination(log.Events(), Span(0, 200), 0); },
      ::testing::ThrowsMessage<InputError>(HasSubstr("consecutive must be 1 or more, got 0")));
}

// -- Split Monitor --

TEST(SplitMonitor, EachServiceIsGreenPlusYellowPlusRedClearanceWithItsTermination) {
  Log log;
  // Phase 1: greens of 5, 7, 9, 11 s, yellow 3 s, red clearance 2 s: splits 10, 12, 14, 16 s.
  // Phase 2 served in two of the four cycles.
  double t = 0;
  for (int k = 0; k < 4; ++k) {
    log.Service(1, t, 5 + 2 * k, 3, 2, code::kPhaseGapOut);
    t += 10 + 2 * k;
    if (k % 2 == 0) {
      log.Service(2, t, 8, 3, 7);
      t += 18;
    }
  }
  const SplitMonitorResult r = SplitMonitor(log.Events(), Span(0, t));
  ASSERT_EQ(r.phases.size(), 2u);
  const SplitMonitorPhase& p1 = r.phases[0];
  ASSERT_EQ(p1.cycles.size(), 4u);
  EXPECT_EQ(p1.cycles[1].split(), seconds(12));
  EXPECT_EQ(p1.cycles[1].green_time(), seconds(7));
  EXPECT_EQ(p1.cycles[1].yellow_time(), seconds(3));
  EXPECT_EQ(p1.cycles[1].red_clearance_time(), seconds(2));
  EXPECT_EQ(p1.cycles[1].termination, Termination::kGapOut);
  ASSERT_EQ(p1.plans.size(), 1u);
  const SplitPlanStats& s = p1.plans[0];
  EXPECT_EQ(s.cycles, 4);
  EXPECT_EQ(s.average, seconds(13));
  EXPECT_EQ(s.min, seconds(10));
  EXPECT_EQ(s.max, seconds(16));
  EXPECT_EQ(s.p50, seconds(12)) << "rank 2 of 4";
  EXPECT_EQ(s.p85, milliseconds(14'800)) << "rank 3.4: 14 + 0.4 x (16 - 14)";
  EXPECT_DOUBLE_EQ(s.percent_gap_outs, 100.0);
  EXPECT_DOUBLE_EQ(s.percent_skips, 0.0);
  const SplitMonitorPhase& p2 = r.phases[1];
  ASSERT_EQ(p2.cycles.size(), 2u);
  EXPECT_EQ(p2.cycles[0].split(), seconds(18));
  EXPECT_EQ(p2.cycles[0].red_clearance_time(), seconds(7));
  EXPECT_EQ(p2.cycles[0].termination, Termination::kForceOff);
  EXPECT_DOUBLE_EQ(p2.plans[0].percent_skips, 50.0);
  EXPECT_EQ(p2.plans[0].p85, Duration::zero()) << "two services: no percentile (UDOT)";
}

TEST(SplitMonitor, AWalkInsideTheServiceAndAProgrammedSplit) {
  Log log;
  log.Add(0, code::kCoordPatternChange, 3);
  log.Add(0.5, 135, 25);  // split 2 change: 25 s
  log.Service(2, 1, 20, 3, 2);
  log.Add(1, code::kPedBeginWalk, 2);
  log.Add(8, code::kPedBeginClearance, 2);
  log.Add(15, code::kPedBeginSolidDontWalk, 2);
  const SplitMonitorResult r = SplitMonitor(log.Events(), Span(0, 60));
  ASSERT_EQ(r.phases.size(), 1u);
  ASSERT_EQ(r.phases[0].cycles.size(), 1u);
  EXPECT_EQ(r.phases[0].cycles[0].walk, At(1));
  EXPECT_EQ(r.phases[0].cycles[0].walk_time, seconds(14));
  ASSERT_EQ(r.phases[0].plans.size(), 1u);
  EXPECT_EQ(r.phases[0].plans[0].plan.plan, 3);
  EXPECT_EQ(r.phases[0].plans[0].programmed, seconds(25));
}

// -- Yellow and Red Actuations --

TEST(YellowRed, ActuationsAfterTheRedClearanceBeganAreViolationsAndLateOnesSevere) {
  Log log;
  log.Add(0, code::kPhaseBeginGreen, 3);
  log.Add(10, code::kPhaseBeginYellow, 3);
  log.Add(13, code::kPhaseEndYellow, 3);
  log.Add(13, code::kPhaseBeginRedClearance, 3);
  log.Add(15, code::kPhaseEndRedClearance, 3);
  log.Add(60, code::kPhaseBeginGreen, 3);
  // 11 and 13 on yellow (13: the instant the red clearance begins), 14 a violation 1 s into
  // it, 19.5 one 6.5 s into it (severe), 61 after the next green: not this cycle's.
  for (const double t : {9.0, 11.0, 13.0, 14.0, 19.5, 61.0}) log.Detector(6, t, t + 0.5);
  const YellowRedResult r = YellowRedActuations(log.Events(), Span(0, 60), OneToOne(6, 3));
  ASSERT_EQ(r.phases.size(), 1u);
  ASSERT_EQ(r.phases[0].cycles.size(), 1u);
  const YellowRedTotals& t = r.phases[0].total;
  EXPECT_EQ(t.volume, 4);
  EXPECT_EQ(t.on_yellow, 2);
  EXPECT_EQ(t.violations, 2);
  EXPECT_EQ(t.severe, 1);
  EXPECT_EQ(t.violation_time, milliseconds(7'500));
  EXPECT_EQ(t.average_violation_time(), milliseconds(3'750));
  EXPECT_DOUBLE_EQ(t.percent_violations(), 50.0);
}

// -- Pedestrian Delay --

TEST(PedestrianDelay, FromTheFirstPushToTheWalkThatServesIt) {
  Log log;
  log.Add(5, code::kPedDetectorOn, 4);  // first in the window, then a walk: 25 s
  log.Add(30, code::kPedBeginWalk, 4);
  log.Add(37, code::kPedBeginClearance, 4);
  log.Add(50, code::kPedDetectorOn, 4);  // clearance, push (twice), walk: 40 s from the first
  log.Add(50.5, code::kPedDetectorOff, 4);
  log.Add(52, code::kPedDetectorOn, 4);
  log.Add(52.5, code::kPedDetectorOff, 4);
  log.Add(52.5, code::kPedCallRegistered, 4);
  log.Add(90, code::kPedBeginWalk, 4);
  log.Add(92, code::kPedDetectorOn, 4);  // walk, push, clearance: pushed during the walk, 0 s
  log.Add(97, code::kPedBeginClearance, 4);
  log.Add(150, code::kPedBeginWalk, 4);  // a recall's walk (no push), then walk-push-walk
  log.Add(170, code::kPedDetectorOn, 4);
  log.Add(200, code::kPedBeginWalk, 4);
  const PedDelayResult r = PedestrianDelay(log.Events(), Span(0, 3600));
  ASSERT_EQ(r.phases.size(), 1u);
  const PedPhase& p = r.phases[0];
  EXPECT_EQ(p.call_code, code::kPedDetectorOn);
  ASSERT_EQ(p.cycles.size(), 4u);
  EXPECT_EQ(p.cycles[0].delay(), seconds(25));
  EXPECT_EQ(p.cycles[1].delay(), seconds(40));
  EXPECT_EQ(p.cycles[1].call, At(50));
  EXPECT_EQ(p.cycles[2].delay(), seconds(0));
  EXPECT_EQ(p.cycles[3].delay(), seconds(30));
  EXPECT_EQ(p.total.min, seconds(0));
  EXPECT_EQ(p.total.max, seconds(40));
  EXPECT_EQ(p.total.average(), milliseconds(23'750));
  EXPECT_EQ(p.presses, 5);
  EXPECT_EQ(p.requests, 4) << "the second push at 52 s counts once with the first";
  EXPECT_EQ(p.unique_detections, 4) << "52 s is within 15 s of 50 s";
  EXPECT_EQ(p.calls_registered, 1);
  EXPECT_EQ(p.walks, 4);
  ASSERT_EQ(p.bins.size(), 1u);
  EXPECT_EQ(p.bins[0].second.cycles, 4);
}

TEST(PedestrianDelay, AControllerThatLogsOnlyTheRegisteredCallIsReadFromIt) {
  Log log;
  log.Add(10, code::kPedBeginWalk, 2);
  log.Add(17, code::kPedBeginClearance, 2);
  log.Add(40, code::kPedCallRegistered, 2);
  log.Add(70, code::kPedBeginWalk, 2);
  const PedDelayResult r = PedestrianDelay(log.Events(), Span(0, 100));
  ASSERT_EQ(r.phases.size(), 1u);
  EXPECT_EQ(r.phases[0].call_code, code::kPedCallRegistered);
  ASSERT_EQ(r.phases[0].cycles.size(), 1u);
  EXPECT_EQ(r.phases[0].cycles[0].delay(), seconds(30));
}

// -- Preemption Details --

TEST(Preemption, ASequenceWithDelayOneWithoutAndOneCutShortByTheNextCall) {
  Log log;
  // With delay: call 0, entry 3, gate down 4, track clearance 5, dwell 20, input off 50, exit 60.
  log.Add(0, code::kPreemptCallInputOn, 1);
  log.Add(3, code::kPreemptEntryStarted, 1);
  log.Add(4, code::kPreemptGateDown, 1);
  log.Add(5, code::kPreemptBeginTrackClearance, 1);
  log.Add(20, code::kPreemptBeginDwell, 1);
  log.Add(50, code::kPreemptCallInputOff, 1);
  log.Add(60, code::kPreemptBeginExit, 1);
  // Without delay: entry 200, dwell 205, exit 230.
  log.Add(200, code::kPreemptEntryStarted, 1);
  log.Add(205, code::kPreemptBeginDwell, 1);
  log.Add(230, code::kPreemptBeginExit, 1);
  // A call never served.
  log.Add(300, code::kPreemptCallInputOn, 1);
  log.Add(301, code::kPreemptCallInputOff, 1);
  // Entry 400, dwell 410, then the next call before any exit: it ends at that call.
  log.Add(400, code::kPreemptEntryStarted, 1);
  log.Add(410, code::kPreemptBeginDwell, 1);
  log.Add(430, code::kPreemptCallInputOn, 1);
  // Another input's, not these.
  log.Add(10, code::kPreemptEntryStarted, 2);
  const PreemptionResult r = Preemption(log.Events(), Span(0, 3600));
  ASSERT_EQ(r.preempts.size(), 2u);
  const PreemptNumber& p = r.preempts[0];
  EXPECT_EQ(p.number, 1);
  EXPECT_EQ(p.requests, 3);
  EXPECT_EQ(p.services, 3);
  ASSERT_EQ(p.cycles.size(), 3u);
  const PreemptCycle& a = p.cycles[0];
  EXPECT_TRUE(a.has_delay);
  EXPECT_EQ(a.start, At(0));
  EXPECT_EQ(a.end, At(60));
  EXPECT_EQ(a.delay, seconds(3));
  EXPECT_EQ(a.time_to_service, seconds(2)) << "entry to track clearance";
  EXPECT_EQ(a.track_clear_time, seconds(15));
  EXPECT_EQ(a.dwell_time, seconds(40));
  EXPECT_EQ(a.time_to_gate_down, seconds(4));
  EXPECT_THAT(a.input_off, ElementsAre(At(50)));
  const PreemptCycle& b = p.cycles[1];
  EXPECT_FALSE(b.has_delay);
  EXPECT_EQ(b.delay, Duration::zero());
  EXPECT_EQ(b.time_to_service, seconds(5)) << "entry to dwell, no track clearance";
  EXPECT_EQ(b.dwell_time, seconds(25));
  const PreemptCycle& c = p.cycles[2];
  EXPECT_EQ(c.start, At(400));
  EXPECT_EQ(c.end, At(430));
  EXPECT_EQ(c.dwell_time, seconds(20));
  ASSERT_EQ(r.preempts[1].cycles.size(), 1u);
  EXPECT_EQ(r.preempts[1].cycles[0].end, At(10)) << "the log ends: its last record";
}

// -- The edges of a log --

TEST(EdgeCases, ALogStartingMidCycleDropsThePartialServiceButKeepsTheRedToRedCycle) {
  Log log;
  // The window opens during phase 1's yellow: its 8 was before the log.
  log.Add(1, code::kPhaseEndYellow, 1);
  log.Add(1, code::kPhaseBeginRedClearance, 1);
  log.Add(3, code::kPhaseEndRedClearance, 1);
  log.Service(1, 20, 10, 3, 2);
  log.Service(1, 50, 10, 3, 2);
  const Window w = Span(0, 80);
  const SplitMonitorResult sm = SplitMonitor(log.Events(), w);
  ASSERT_EQ(sm.phases.size(), 1u);
  EXPECT_EQ(sm.phases[0].cycles.size(), 2u);
  const PcdResult pcd = Pcd(log.Events(), w, OneToOne(1, 1));
  ASSERT_EQ(pcd.phases.size(), 1u);
  EXPECT_EQ(pcd.phases[0].cycles.size(), 2u) << "9 at 1 s opens the first red-to-red cycle";
  EXPECT_EQ(pcd.phases[0].cycles[0].start, At(1));
}

TEST(EdgeCases, AMissingYellowBreaksTheCyclesThatNeedIt) {
  Log log;
  log.Service(1, 0, 10, 3, 2);
  log.Service(1, 30, 10, 3, 2);
  log.Service(1, 60, 10, 3, 2);
  log.Service(1, 90, 10, 3, 2);
  std::vector<Event> events = log.Events();
  std::erase(events, Event{At(40), code::kPhaseBeginYellow, 1});  // the second yellow lost
  const Window w = Span(0, 120);
  const PcdResult pcd = Pcd(events, w, OneToOne(1, 1));
  ASSERT_EQ(pcd.phases.size(), 1u);
  // Red-to-red cycles start at each 9: 13, 43, 73; 13 -> 43 lost its yellow.
  ASSERT_EQ(pcd.phases[0].cycles.size(), 2u);
  EXPECT_EQ(pcd.phases[0].cycles[0].start, At(43));
  const SplitFailResult sf = SplitFailure(events, w, OneToOne(1, 1));
  EXPECT_EQ(sf.phases[0].cycles.size(), 2u) << "green-to-green 0->30 and 60->90";
  const SplitMonitorResult sm = SplitMonitor(events, w);
  ASSERT_EQ(sm.phases[0].cycles.size(), 4u) << "a service is 1 to 11";
  EXPECT_EQ(sm.phases[0].cycles[1].yellow, std::nullopt);
  EXPECT_EQ(sm.phases[0].cycles[1].yellow_time(), Duration::zero());
}

TEST(EdgeCases, APlanChangeInsideTheWindowSplitsThePlansAndMovesTheDetectorsPhase) {
  Log log;
  log.Add(0, code::kCoordPatternChange, 1);
  log.Add(0, code::kPhaseEndYellow, 1);
  log.Add(0, code::kPhaseEndYellow, 2);
  log.Service(1, 10, 10, 3, 2);
  log.Detector(4, 5, 6);  // plan 1: channel 4 calls phase 1 (an arrival on red)
  log.Add(40, code::kCoordPatternChange, 2);
  log.Service(2, 50, 10, 3, 2);
  log.Detector(4, 45, 46);  // plan 2: channel 4 calls phase 2
  log.Service(1, 70, 10, 3, 2);
  log.Service(2, 90, 10, 3, 2);
  ChannelMap map;
  map.Add(1, 4, 1);
  map.Add(2, 4, 2);
  const Window w = Span(0, 120);
  const std::vector<PlanSpan> plans = PlansIn(log.Events(), w);
  ASSERT_EQ(plans.size(), 2u);
  EXPECT_EQ(plans[0].plan, 1);
  EXPECT_EQ(plans[0].end, At(40));
  EXPECT_EQ(plans[1].plan, 2);
  EXPECT_EQ(plans[1].start, At(40));
  const PcdResult pcd = Pcd(log.Events(), w, map);
  ASSERT_EQ(pcd.phases.size(), 2u);
  EXPECT_EQ(pcd.phases[0].total.volume, 1);
  EXPECT_EQ(pcd.phases[0].total.delay, seconds(5));
  EXPECT_EQ(pcd.phases[1].total.volume, 1);
  EXPECT_EQ(pcd.phases[1].total.delay, seconds(5));
  ASSERT_EQ(pcd.phases[0].plans.size(), 2u);
  EXPECT_EQ(pcd.phases[0].plans[0].second.volume, 1);
  EXPECT_EQ(pcd.phases[0].plans[1].second.volume, 0);
  const SplitMonitorResult sm = SplitMonitor(log.Events(), w);
  ASSERT_EQ(sm.phases[0].plans.size(), 2u);
  EXPECT_EQ(sm.phases[0].plans[0].cycles, 1);
  EXPECT_EQ(sm.phases[0].plans[1].cycles, 1);
}

TEST(EdgeCases, RecordsOutOfOrderAreRefusedNamingTheRecord) {
  std::vector<Event> events{{At(0), code::kPhaseBeginGreen, 1},
                            {At(10), code::kPhaseBeginYellow, 1},
                            {At(5), code::kPhaseGapOut, 1}};
  EXPECT_THAT([&] { (void)Compute(Measure::kSplitMonitor, events, Span(0, 20), {}); },
              ::testing::ThrowsMessage<InputError>(
                  HasSubstr("record 2 (code 4, param 1) at 1795240005.000 s comes after record 1 "
                            "at 1795240010.000 s: the log must be in time order")));
  EXPECT_THAT([&] { (void)Compute(Measure::kPcd, {}, Span(20, 10), {}); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("the window ends")));
}

TEST(EdgeCases, AnEmptyWindowOrAnEmptyLogHasNoPhases) {
  Log log;
  log.Service(1, 0, 10, 3, 2);
  for (std::size_t m = 0; m < MeasureNames().size(); ++m) {
    const auto measure = static_cast<Measure>(m);
    EXPECT_EQ(ParseMeasure(ToString(measure)), measure);
    const Report empty_window = Compute(measure, log.Events(), Span(50, 50), OneToOne(1, 1));
    const Report empty_log = Compute(measure, {}, Span(0, 60), OneToOne(1, 1));
    const char* list = measure == Measure::kPreemption ? "preempts" : "phases";
    EXPECT_TRUE(empty_window.json[list].empty()) << ToString(measure);
    EXPECT_TRUE(empty_log.json[list].empty()) << ToString(measure);
    EXPECT_EQ(empty_log.json["measure"], ToString(measure));
  }
  EXPECT_EQ(ParseMeasure("aog"), std::nullopt);
}

// -- The pieces --

TEST(ChannelMap, APlansOwnEntriesReplaceTheOnesForEveryPlan) {
  ChannelMap map;
  map.Add(1, 1);
  map.Add(2, 2);
  map.Add(3, 1, 3);
  EXPECT_TRUE(map.Calls(0, 1, 1));
  EXPECT_TRUE(map.Calls(2, 1, 1));
  EXPECT_FALSE(map.Calls(3, 1, 1)) << "plan 3 has entries of its own";
  EXPECT_TRUE(map.Calls(3, 1, 3));
  EXPECT_FALSE(map.Calls(0, 1, 2));
}

TEST(Percentile, FollowsUdotsRankInterpolation) {
  using std::chrono::seconds;
  EXPECT_EQ(Percentile({seconds(1), seconds(2)}, 0.85), Duration::zero());
  EXPECT_EQ(Percentile({seconds(30), seconds(10), seconds(20)}, 0.5), seconds(15));
  EXPECT_EQ(Percentile({seconds(10), seconds(20), seconds(30), seconds(40)}, 1.0), seconds(40));
  EXPECT_DOUBLE_EQ(Sec(Percentile({seconds(10), seconds(20), seconds(30)}, 0.85)), 25.5);
}

}  // namespace
}  // namespace autodrive::scm::atspm
