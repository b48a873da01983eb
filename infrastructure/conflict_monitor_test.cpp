#include "infrastructure/conflict_monitor.h"

#include <gtest/gtest.h>

#include <map>
#include <set>

#include "common/test_support.h"
#include "maps/map_io.h"

namespace autodrive::infrastructure {
namespace {

// Simulated time as a plain variable: both timelines are the simulated time.
void AdvanceSim(SimClock& clock, MonoTime t) { clock.AdvanceTo(Time(t.time_since_epoch())); }

using namespace std::chrono_literals;

// A pair of approaches by side letter ("EN") -> the conflicting movement pairs between their
// heads, each as ("E>S", "N>E"): a movement from the first side, one from the second.
using ConflictTable = std::map<std::string, std::set<std::pair<std::string, std::string>>>;

const maps::Map& LoadShipped(const std::string& name) {
  static std::map<std::string, maps::Map> maps;
  auto it = maps.find(name);
  if (it == maps.end()) {
    it =
        maps.emplace(name, maps::LoadMapOrLayout(
                               (test::SourceDir() / "config" / "maps" / (name + ".yaml")).string()))
            .first;
  }
  return it->second;
}

const maps::Intersection& Named(const maps::Map& map, const std::string& name) {
  for (const auto& x : map.intersections) {
    if (x.name == name) return x;
  }
  throw std::runtime_error("no intersection " + name);
}

char SideOf(const maps::Map& map, SignalHeadId head) {
  const maps::SignalHead& h = map.signal_heads.at(head.value() - 1);
  const maps::Intersection& x = map.intersection(h.intersection);
  for (const auto& a : x.approaches) {
    if (a.id == h.approach) return maps::SideLetter(a.side);
  }
  throw std::runtime_error("head without approach");
}

// "E>S" from "r2c2:E>S:0>0".
std::string Short(const maps::Map& map, MovementId m) {
  const std::string& name = map.movement(m).name;
  return name.substr(name.find(':') + 1, 3);
}

ConflictTable Table(const maps::Map& map, const std::vector<HeadConflict>& conflicts) {
  static const std::string kOrder = "ENWS";
  ConflictTable table;
  for (const auto& c : conflicts) {
    char a = SideOf(map, c.a);
    char b = SideOf(map, c.b);
    const bool swap = kOrder.find(a) > kOrder.find(b);
    if (swap) std::swap(a, b);
    auto& pairs = table[std::string{a, b}];
    for (const auto& [ma, mb] : c.movements) {
      pairs.insert(swap ? std::pair{Short(map, mb), Short(map, ma)}
                        : std::pair{Short(map, ma), Short(map, mb)});
    }
  }
  return table;
}

// The four-way with one lane per direction, by hand (maps/builder_test.cpp derives its 30
// movement conflicts; here they are grouped by the approaches of the two movements). Every pair
// of heads conflicts: a left turn crosses the opposing through and merges with it, so even
// opposing heads may never show go together.
const ConflictTable kFourWay = {
    {"EN", {{"E>S", "N>E"}, {"E>S", "N>S"}, {"E>W", "N>E"}, {"E>W", "N>S"}, {"E>W", "N>W"}}},
    {"EW", {{"E>N", "W>N"}, {"E>S", "W>E"}, {"E>S", "W>N"}, {"E>S", "W>S"}, {"E>W", "W>N"}}},
    {"ES", {{"E>N", "S>N"}, {"E>S", "S>N"}, {"E>S", "S>W"}, {"E>W", "S>N"}, {"E>W", "S>W"}}},
    {"NW", {{"N>E", "W>E"}, {"N>E", "W>N"}, {"N>S", "W>E"}, {"N>S", "W>N"}, {"N>S", "W>S"}}},
    {"NS", {{"N>E", "S>E"}, {"N>E", "S>N"}, {"N>E", "S>W"}, {"N>S", "S>W"}, {"N>W", "S>W"}}},
    {"WS", {{"W>E", "S>E"}, {"W>E", "S>N"}, {"W>E", "S>W"}, {"W>N", "S>N"}, {"W>N", "S>W"}}},
};

TEST(HeadConflicts, DrivingSchoolCrossingMatchesTheHandWrittenTable) {
  const maps::Map& map = LoadShipped("driving_school");
  const auto& x = Named(map, "driving_school_crossing");
  ASSERT_EQ(x.signal_heads.size(), 4u);
  const auto conflicts = ComputeHeadConflicts(map, x.id);
  EXPECT_EQ(conflicts.size(), 6u);
  EXPECT_EQ(Table(map, conflicts), kFourWay);
}

TEST(HeadConflicts, SmallTownCentreMatchesTheFourWayTable) {
  const maps::Map& map = LoadShipped("small_town");
  const auto& x = Named(map, "centre");
  EXPECT_EQ(Table(map, ComputeHeadConflicts(map, x.id)), kFourWay);
}

TEST(HeadConflicts, SmallTownNorthTeeMatchesTheHandWrittenTable) {
  // The T has arms W, E and S. Its six movements conflict in six pairs: E's left crosses W's
  // through and merges with W's right into S; the throughs merge with S's turns into W and E;
  // S's left crosses W's through and E's left.
  const maps::Map& map = LoadShipped("small_town");
  const auto& x = Named(map, "north_t");
  ASSERT_EQ(x.signal_heads.size(), 3u);
  const ConflictTable expected = {
      {"EW", {{"E>S", "W>E"}, {"E>S", "W>S"}}},
      {"ES", {{"E>S", "S>W"}, {"E>W", "S>W"}}},
      {"WS", {{"W>E", "S>E"}, {"W>E", "S>W"}}},
  };
  EXPECT_EQ(Table(map, ComputeHeadConflicts(map, x.id)), expected);
}

TEST(HeadConflicts, UnknownIntersectionIsRefused) {
  const maps::Map& map = LoadShipped("driving_school");
  EXPECT_EQ(test::ErrorMessage([&] { (void)ComputeHeadConflicts(map, IntersectionId(9)); }),
            "map driving_school has no intersection 9");
}

// A hand-built intersection: heads 1 and 2 on approaches 1 and 2, one movement each, which
// conflict only when `conflict` is true. The geometry stays out of it.
maps::Map TwoHeadMap(bool conflict) {
  maps::Map map;
  map.name = "two_heads";
  for (std::uint32_t i = 1; i <= 2; ++i) {
    maps::Movement m;
    m.id = MovementId(i);
    m.name = "m" + std::to_string(i);
    m.intersection = IntersectionId(1);
    m.from_approach = ApproachId(i);
    map.movements.push_back(m);
    maps::SignalHead h;
    h.id = SignalHeadId(i);
    h.intersection = IntersectionId(1);
    h.approach = ApproachId(i);
    map.signal_heads.push_back(h);
  }
  maps::Intersection x;
  x.id = IntersectionId(1);
  x.name = "x";
  x.movements = {MovementId(1), MovementId(2)};
  x.signal_heads = {SignalHeadId(1), SignalHeadId(2)};
  if (conflict) x.conflicts = {{MovementId(1), MovementId(2)}};
  map.intersections.push_back(x);
  return map;
}

const SignalHeadId kHead1(1);
const SignalHeadId kHead2(2);
const Lamps kRed = LampsFor(Aspect::kRed);
const Lamps kYellow = LampsFor(Aspect::kYellow);
const Lamps kGreen = LampsFor(Aspect::kGreen);

// Observes both heads and updates, as the host does every tick.
std::optional<MonitorLatch> Tick(ConflictMonitor& monitor, MonoTime now, const Lamps& a,
                                 const Lamps& b) {
  monitor.Observe(kHead1, a, now);
  monitor.Observe(kHead2, b, now);
  return monitor.Update(now);
}

TEST(ConflictMonitor, LatchesWhenTwoConflictingHeadsShowGoForThePersistenceAndNotBefore) {
  const maps::Map map = TwoHeadMap(true);
  ConflictMonitor monitor(map, IntersectionId(1), {}, 300ms);
  ASSERT_EQ(monitor.conflicts().size(), 1u);
  SimClock clock;
  const MonoTime t0 = MonoFromSeconds(10);
  AdvanceSim(clock, t0);
  // Head 1 green from t0; head 2 yellow from t0 + 100 ms; ticks at 50 Hz.
  std::optional<MonitorLatch> latch;
  while (!latch && clock.Monotonic() < t0 + 2s) {
    const bool two_go = clock.Monotonic() >= t0 + 100ms;
    latch = Tick(monitor, clock.Monotonic(), kGreen, two_go ? kYellow : kRed);
    if (!latch) AdvanceSim(clock, clock.Monotonic() + 20ms);
  }
  ASSERT_TRUE(latch.has_value());
  EXPECT_EQ(latch->since, t0 + 100ms);
  EXPECT_EQ(latch->at, t0 + 400ms) << "the first tick at which the overlap reached 300 ms";
  EXPECT_EQ(latch->a, kHead1);
  EXPECT_EQ(latch->b, kHead2);
  EXPECT_EQ(latch->message,
            "signal_1 showed green and signal_2 showed yellow together for 0.30 s; their "
            "movements conflict (m1 with m2)");
  EXPECT_TRUE(monitor.latched());
}

TEST(ConflictMonitor, OneTickShortOfThePersistenceDoesNotLatch) {
  const maps::Map map = TwoHeadMap(true);
  ConflictMonitor monitor(map, IntersectionId(1), {}, 300ms);
  const MonoTime t0 = MonoFromSeconds(1);
  EXPECT_FALSE(Tick(monitor, t0, kGreen, kGreen));
  EXPECT_FALSE(Tick(monitor, t0 + 299ms, kGreen, kGreen));
  EXPECT_FALSE(monitor.latched());
  EXPECT_TRUE(Tick(monitor, t0 + 300ms, kGreen, kGreen));
}

TEST(ConflictMonitor, ABreakInGoStartsTheCountAgain) {
  const maps::Map map = TwoHeadMap(true);
  ConflictMonitor monitor(map, IntersectionId(1), {}, 300ms);
  const MonoTime t0 = MonoFromSeconds(1);
  EXPECT_FALSE(Tick(monitor, t0, kGreen, kGreen));
  EXPECT_FALSE(Tick(monitor, t0 + 200ms, kGreen, kGreen));
  EXPECT_FALSE(Tick(monitor, t0 + 220ms, kGreen, kRed));  // a switching transient
  EXPECT_FALSE(Tick(monitor, t0 + 240ms, kGreen, kGreen));
  EXPECT_FALSE(Tick(monitor, t0 + 520ms, kGreen, kGreen));
  EXPECT_TRUE(Tick(monitor, t0 + 540ms, kGreen, kGreen));
}

TEST(ConflictMonitor, HeadsThatDoNotConflictMayShowGoTogether) {
  const maps::Map map = TwoHeadMap(false);
  ConflictMonitor monitor(map, IntersectionId(1), {}, 300ms);
  EXPECT_TRUE(monitor.conflicts().empty());
  for (int i = 0; i < 100; ++i) {
    EXPECT_FALSE(Tick(monitor, MonoFromSeconds(0.1 * i), kGreen, kGreen));
  }
}

TEST(ConflictMonitor, RedAgainstGreenAndUnknownLampsDoNotLatch) {
  const maps::Map map = TwoHeadMap(true);
  ConflictMonitor monitor(map, IntersectionId(1), {}, 300ms);
  for (int i = 0; i < 50; ++i) {
    EXPECT_FALSE(Tick(monitor, MonoFromSeconds(0.1 * i), kGreen, kRed));
  }
  for (int i = 50; i < 100; ++i) {
    const MonoTime now = MonoFromSeconds(0.1 * i);
    monitor.Observe(kHead1, kGreen, now);
    monitor.Observe(kHead2, std::nullopt, now);  // offline
    EXPECT_FALSE(monitor.Update(now));
  }
}

TEST(ConflictMonitor, AStuckGreenLampUnderARedIsSeen) {
  // The monitor senses lamps, not commands: red with the green lamp stuck on shows go.
  const maps::Map map = TwoHeadMap(true);
  ConflictMonitor monitor(map, IntersectionId(1), {}, 300ms);
  Lamps red_and_green = kRed;
  red_and_green.green = true;
  EXPECT_FALSE(Tick(monitor, MonoFromSeconds(1), red_and_green, kGreen));
  const auto latch = Tick(monitor, MonoFromSeconds(1.3), red_and_green, kGreen);
  ASSERT_TRUE(latch.has_value());
  EXPECT_EQ(latch->lamps_a, red_and_green);
}

TEST(ConflictMonitor, StaysLatchedUntilResetAndReportsTheLatchOnce) {
  const maps::Map map = TwoHeadMap(true);
  ConflictMonitor monitor(map, IntersectionId(1), {}, 300ms);
  EXPECT_FALSE(Tick(monitor, MonoFromSeconds(1), kGreen, kGreen));
  EXPECT_TRUE(Tick(monitor, MonoFromSeconds(2), kGreen, kGreen));
  EXPECT_FALSE(Tick(monitor, MonoFromSeconds(3), kRed, kRed)) << "reported once";
  EXPECT_TRUE(monitor.latched()) << "the conflict ended, the latch stays";
  EXPECT_TRUE(monitor.Reset());
  EXPECT_FALSE(monitor.latched());
  EXPECT_FALSE(monitor.Reset());
  EXPECT_FALSE(Tick(monitor, MonoFromSeconds(4), kRed, kRed));
}

TEST(ConflictMonitor, NextLatchIsWhenTheOverlapReachesThePersistence) {
  const maps::Map map = TwoHeadMap(true);
  ConflictMonitor monitor(map, IntersectionId(1), {}, 300ms);
  const MonoTime t0 = MonoFromSeconds(1);
  EXPECT_FALSE(Tick(monitor, t0, kGreen, kRed));
  EXPECT_EQ(monitor.NextLatch(), std::nullopt) << "only one head shows go";
  EXPECT_FALSE(Tick(monitor, t0 + 50ms, kGreen, kYellow));
  EXPECT_EQ(monitor.NextLatch(), t0 + 350ms);
  EXPECT_FALSE(Tick(monitor, t0 + 349ms, kGreen, kYellow));
  EXPECT_TRUE(Tick(monitor, *monitor.NextLatch(), kGreen, kYellow)) << "latches exactly then";
  EXPECT_EQ(monitor.NextLatch(), std::nullopt) << "latched";
}

TEST(ConflictMonitor, AfterATimeBaseRestartTheOverlapIsCountedOnTheNewTimeline) {
  const maps::Map map = TwoHeadMap(true);
  ConflictMonitor monitor(map, IntersectionId(1), {}, 300ms);
  // Both show go from 1000 s; then the simulated clock restarts at 5 s with the lamps as they
  // were. Without a restart the overlap would seem to start in the future and never latch.
  EXPECT_FALSE(Tick(monitor, MonoFromSeconds(1000), kGreen, kGreen));
  monitor.RestartTimers();
  const MonoTime t1 = MonoFromSeconds(5);
  EXPECT_FALSE(Tick(monitor, t1, kGreen, kGreen));
  EXPECT_FALSE(Tick(monitor, t1 + 299ms, kGreen, kGreen));
  EXPECT_TRUE(Tick(monitor, t1 + 300ms, kGreen, kGreen));
  // A latch survives a restart.
  monitor.RestartTimers();
  EXPECT_TRUE(monitor.latched());
}

TEST(ConflictMonitor, WatchesOnlyTheHostedHeads) {
  const maps::Map& map = LoadShipped("driving_school");
  const auto& x = Named(map, "driving_school_crossing");
  ConflictMonitor monitor(map, x.id, {x.signal_heads[0], x.signal_heads[2]}, 300ms);
  EXPECT_EQ(monitor.heads().size(), 2u);
  EXPECT_EQ(monitor.conflicts().size(), 1u);
  EXPECT_EQ(monitor.device_id(), "mmu_driving_school_crossing");
  EXPECT_EQ(test::ErrorMessage([&] { ConflictMonitor(map, x.id, {SignalHeadId(77)}, 300ms); }),
            "signal head 77 is not a head of intersection driving_school_crossing");
}

}  // namespace
}  // namespace autodrive::infrastructure
