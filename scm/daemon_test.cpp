// The daemon in-process, pass by pass, on clocks the test controls: a wall clock stepped by
// +-5 s during a yellow and a red clearance, a simulated clock that restarts, the loop's
// allocations in steady state (with 5,000 background vehicles too), the ips fleet source, SUMO's
// background traffic on actuated detectors, and requests that come while SPaT is due. Real DDS
// (its own partition) and a real SQLite database in the test's temporary folder.
#include "scm/daemon.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <new>
#include <set>

#include "autodrive_msgs/msg/Event.h"
#include "autodrive_msgs/msg/ProcessEntry.h"
#include "autodrive_msgs/msg/ProcessTable.h"
#include "autodrive_msgs/msg/SignalGroupState.h"
#include "autodrive_msgs/msg/TrafficObject.h"

#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/test_support.h"
#include "scm/benchmarks/bench_support.h"
#include "scm/store/store.h"

// Counts the C++ allocations of this process while `g_count_allocations` is set.
namespace {
std::atomic<bool> g_count_allocations{false};
std::atomic<std::uint64_t> g_allocations{0};
}  // namespace

// GCC cannot see that these replace the global operators as a pair.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t n) {
  if (g_count_allocations.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
#pragma GCC diagnostic pop

namespace autodrive::scm {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

/// A test's own folder and DDS partition.
class DaemonTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    partition_ = fmt::format("scm_daemon_{}_{}", ::getpid(), info->name());
    dir_ = std::filesystem::temp_directory_path() / partition_;
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    participant_ = std::make_unique<dds::Participant>(dds::ParticipantOptions{{}, partition_, {}});
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  /// The Driving School city without waiting for lights (no light host in these tests), written
  /// into the test's folder with its map path made absolute. `actuated`: its actuated plan
  /// (evening) all day.
  std::filesystem::path DrivingSchoolWithoutLights(const std::string& extra = "",
                                                   bool actuated = false) const {
    std::string text = config::ReadFile(test::SourceDir() / "config/cities/driving_school.yaml");
    const std::string map =
        (test::SourceDir() / "config/maps/driving_school.yaml").lexically_normal().string();
    text.replace(text.find("map: ../maps/driving_school.yaml"), 32, "map: " + map);
    if (actuated) {
      const std::string schedule =
          "      - {at: \"06:00\", plan: day}\n      - {at: \"19:00\", plan: evening}\n";
      const auto at = text.find(schedule);
      EXPECT_NE(at, std::string::npos) << "the Driving School's schedule changed";
      if (at != std::string::npos) {
        text.replace(at, schedule.size(), "      - {at: \"00:00\", plan: evening}\n");
      }
    }
    text += "\ndevices: {wait_for_lights: false}\n" + extra;
    const auto path = dir_ / "city.yaml";
    std::ofstream(path) << text;
    return path;
  }
  ScmOptions Options(const std::filesystem::path& city) const {
    ScmOptions o;
    o.config_path = city;
    o.db_path = (dir_ / "scm.db").string();
    o.config_root = test::SourceDir();
    return o;
  }

  std::string partition_;
  std::filesystem::path dir_;
  std::unique_ptr<dds::Participant> participant_;
};

/// Time sources the test owns: the monotonic clock moves when the test says, and the wall
/// clock is it plus an offset the test steps.
struct TestTime {
  std::atomic<std::int64_t> mono_ns{5'000'000'000};
  std::atomic<std::int64_t> offset_ns{1'795'000'000'000'000'000};
  WallTimeSources Sources() {
    return {[this] { return Time(Duration(mono_ns.load() + offset_ns.load())); },
            [this] { return MonoTime(Duration(mono_ns.load())); }};
  }
  MonoTime mono() const { return MonoTime(Duration(mono_ns.load())); }
  /// Moves the monotonic clock to `t` (never back).
  void AdvanceTo(MonoTime t) {
    mono_ns = std::max(mono_ns.load(), static_cast<std::int64_t>(t.time_since_epoch().count()));
  }
};

TEST_F(DaemonTest, WallClockStepsDuringAYellowAndARedClearanceChangeNeitherAndSpatStaysTrue) {
  TestTime time;
  WallClock clock(time.Sources());
  Scm scm(Options(DrivingSchoolWithoutLights()), clock, *participant_);
  dds::Reader<msg::Spat> spat(*participant_, dds::topics::Spat().name, dds::Qos::Stream(64));
  const auto& x = scm.runtime().intersections().at(0);
  const Duration yellow = x.model->groups[0].timing.yellow;
  const Duration red_clearance = x.model->groups[0].timing.red_clearance;
  ASSERT_EQ(yellow, seconds(3));
  ASSERT_EQ(red_clearance, seconds(7));

  std::optional<MonoTime> yellow_at, red_at, next_green_at;
  std::size_t yellow_group = 0;
  bool stepped_forward = false;
  bool stepped_back = false;
  int spat_checked = 0;
  std::uint64_t spats = scm.counters().spat_published;
  // Pass by pass, jumping the monotonic clock to each deadline the loop would wake at.
  for (int pass = 0; pass < 20'000 && !next_green_at; ++pass) {
    time.AdvanceTo(std::min(scm.next_deadline(), time.mono() + milliseconds(100)));
    if (yellow_at && !stepped_forward && time.mono() >= *yellow_at + seconds(1)) {
      time.offset_ns += 5'000'000'000;  // NTP steps the wall clock 5 s forwards mid-yellow
      stepped_forward = true;
    }
    if (red_at && !stepped_back && time.mono() >= *red_at + milliseconds(500)) {
      time.offset_ns -= 5'000'000'000;  // and 5 s back during the red clearance
      stepped_back = true;
    }
    const MonoTime pass_mono = time.mono();
    const Time pass_wire = Time(Duration(time.mono_ns.load() + time.offset_ns.load()));
    scm.Pass();
    const auto& aspects = scm.runtime().intersections().at(0).last_aspects;
    const auto stage = scm.runtime().intersections().at(0).controller->stage();
    if (!yellow_at && stage == Stage::kYellow) {
      yellow_at = pass_mono;
      yellow_group =
          static_cast<std::size_t>(std::ranges::find(aspects, Aspect::kYellow) - aspects.begin());
    }
    if (yellow_at && !red_at && stage == Stage::kRedClearance) red_at = pass_mono;
    if (red_at && !next_green_at && stage == Stage::kGreen) next_green_at = pass_mono;
    // Every SPaT of this pass: its stamp is this pass's wire time, and each group's min_end is
    // that stamp plus exactly the control time left, whatever the wall clock did.
    if (scm.counters().spat_published == spats) continue;
    spats = scm.counters().spat_published;
    ASSERT_TRUE(spat.WaitForData(seconds(10)));
    auto got = spat.TakeAll();
    ASSERT_EQ(got.size(), 1u);
    const auto& m = *got.back();
    ASSERT_EQ(dds::FromMsg(m.header.stamp), pass_wire);
    const auto& g = dds::Elements(dds::Elements(m.intersections)[0].signal_groups)[yellow_group];
    if (stage == Stage::kYellow && yellow_at) {
      EXPECT_EQ(g.event_state, autodrive_msgs_msg_SignalGroupState_Constants_PROTECTED_CLEARANCE);
      EXPECT_EQ(dds::FromMsg(g.min_end_time) - dds::FromMsg(m.header.stamp),
                *yellow_at + yellow - pass_mono);
      ++spat_checked;
    }
    if (stage == Stage::kRedClearance && red_at) {
      EXPECT_EQ(g.event_state, autodrive_msgs_msg_SignalGroupState_Constants_STOP_AND_REMAIN);
      // The red of the group that just ended lasts at least the clearance, then a phase.
      EXPECT_GE(dds::FromMsg(g.min_end_time) - dds::FromMsg(m.header.stamp),
                *red_at + red_clearance - pass_mono);
      ++spat_checked;
    }
  }
  ASSERT_TRUE(yellow_at && red_at && next_green_at) << "no full clearance seen";
  EXPECT_TRUE(stepped_forward && stepped_back);
  EXPECT_EQ(*red_at - *yellow_at, yellow) << "the yellow lasted its configured time";
  EXPECT_EQ(*next_green_at - *red_at, red_clearance) << "the red clearance lasted its time";
  EXPECT_EQ(clock.steps(), 2u);
  EXPECT_GE(spat_checked, 40) << "SPaT at 10 Hz through 5 s of clearance";
}

TEST_F(DaemonTest, ASimulatorRestartIsANewSessionNotAFreeze) {
  SimClock clock;
  clock.AdvanceTo(TimeFromSeconds(1000));
  Scm scm(Options(DrivingSchoolWithoutLights()), clock, *participant_);
  auto run_until_green = [&](double limit_s) {
    const MonoTime end = clock.Monotonic() + FromSeconds(limit_s);
    while (clock.Monotonic() < end) {
      const MonoTime next = std::clamp(scm.next_deadline(), clock.Monotonic() + milliseconds(1),
                                       clock.Monotonic() + milliseconds(100));
      clock.AdvanceTo(Time(next.time_since_epoch()));
      scm.Pass();
      if (scm.runtime().intersections()[0].controller->stage() == Stage::kGreen) return true;
    }
    return false;
  };
  ASSERT_TRUE(run_until_green(30));
  clock.AdvanceTo(TimeFromSeconds(3));  // the simulation restarted
  scm.Pass();
  EXPECT_EQ(scm.counters().clock_sessions, 1u);
  EXPECT_EQ(scm.runtime().intersections()[0].controller->stage(), Stage::kStartupFlash)
      << "the intersection restarts through the start-up sequence";
  ASSERT_TRUE(run_until_green(30)) << "and runs again on the restarted clock (no freeze)";
}

TEST_F(DaemonTest, SteadyStatePassesAllocateNothing) {
  TestTime time;
  WallClock clock(time.Sources());
  Scm scm(Options(DrivingSchoolWithoutLights()), clock, *participant_);
  // A subscriber, so that SPaT and the fleet state are really sent.
  dds::Reader<msg::Spat> spat(*participant_, dds::topics::Spat().name, dds::Qos::Stream(1));
  auto pass_to = [&](MonoTime t) {
    time.AdvanceTo(t);
    scm.Pass();
  };
  // Warm up: through the start-up sequence and a whole cycle, so that every message has its
  // shape and every buffer its capacity.
  const MonoTime warm = time.mono() + seconds(120);
  while (time.mono() < warm) pass_to(std::min(scm.next_deadline(), time.mono() + milliseconds(20)));
  (void)spat.TakeAll();
  const std::uint64_t spats_before = scm.counters().spat_published;
  const std::uint64_t steps_before = scm.counters().controller_steps;
  g_allocations = 0;
  g_count_allocations = true;
  const MonoTime end = time.mono() + seconds(60);  // a full cycle and more: every phase change
  int passes = 0;
  while (time.mono() < end) {
    pass_to(std::min(scm.next_deadline(), time.mono() + milliseconds(20)));
    ++passes;
  }
  g_count_allocations = false;
  EXPECT_EQ(g_allocations.load(), 0u) << "allocations in " << passes << " passes";
  EXPECT_GE(scm.counters().spat_published - spats_before, 590u);
  EXPECT_GT(scm.counters().controller_steps, steps_before) << "the phases did change";
}

/// The centre of a background car `before_m` before the end of `lane`'s centreline.
Eigen::Vector2d BeforeEnd(const maps::Lane& lane, double before_m) {
  double left = before_m;
  for (std::size_t i = lane.centreline.size() - 1; i > 0; --i) {
    const Eigen::Vector2d a = lane.centreline[i - 1];
    const Eigen::Vector2d b = lane.centreline[i];
    const double length = (b - a).norm();
    if (left <= length) return b + (a - b) * (left / length);
    left -= length;
  }
  return lane.centreline.front();
}

/// Fills `m` as autodrive-traffic would: `cars` (id, then lane name and centre) of 0.25 x
/// 0.12 m, stamped `stamp`.
void FillTraffic(
    dds::Message<msg::TrafficObjects>& m, Time stamp,
    const std::vector<std::pair<std::string, std::pair<std::string, Eigen::Vector2d>>>& cars) {
  m->header.stamp = dds::ToMsg(stamp);
  dds::UpdateString(m->header.frame_id, "map");
  // In place: ResizeSequence would drop the elements' strings with the old buffer (a leak
  // LeakSanitizer found in CI's sanitizer leg).
  dds::SetLengthKeepingCapacity(m->objects, static_cast<std::uint32_t>(cars.size()));
  for (std::size_t i = 0; i < cars.size(); ++i) {
    auto& o = dds::Elements(m->objects)[i];
    dds::UpdateString(o.object_id, cars[i].first);
    o.object_class = autodrive_msgs_msg_TrafficObject_Constants_CAR;
    o.pose.position.x = cars[i].second.second.x();
    o.pose.position.y = cars[i].second.second.y();
    o.pose.orientation.w = 1.0;
    o.size.x = 0.25;
    o.size.y = 0.12;
    o.size.z = 0.1;
    dds::UpdateString(o.map_lane_id, cars[i].second.first);
  }
}

TEST_F(DaemonTest, BackgroundCarsCallTheirPhaseOnlyFromItsZoneAndOnlyWhileFresh) {
  TestTime time;
  WallClock clock(time.Sources());
  Scm scm(Options(DrivingSchoolWithoutLights("", /*actuated=*/true)), clock, *participant_);
  const auto& map = scm.city().map;
  const maps::Intersection& crossing = map.intersections.at(0);
  // Groups 1..4 serve east, north, west and south (the approaches' order in the map).
  const auto ingress = [&](std::size_t a) -> const maps::Lane& {
    return map.lane(crossing.approaches.at(a).ingress.at(0));
  };
  const auto egress = [&](std::size_t a) -> const maps::Lane& {
    return map.lane(crossing.approaches.at(a).egress.at(0));
  };
  const auto& x = scm.runtime().intersections().at(0);
  ASSERT_EQ(x.controller->plan().type, PlanType::kActuated);
  ASSERT_EQ(x.controller->plan().detectors.size(), 4u);
  const auto aspect = [&](std::size_t g) { return x.last_aspects.at(g); };
  dds::Writer<msg::TrafficObjects> traffic(*participant_, dds::topics::Traffic());
  ASSERT_TRUE(traffic.WaitForReaders(1, seconds(10)));
  dds::Message<msg::TrafficObjects> m;
  using Cars = std::vector<std::pair<std::string, std::pair<std::string, Eigen::Vector2d>>>;
  // Passes for `d` of test time, publishing `cars` every 100 ms as autodrive-traffic does (each
  // acknowledged, so in the SCM's reader before the next pass); stops early when `until` holds.
  MonoTime last_message{};
  const auto run = [&](Duration d, const Cars& cars, const std::function<bool()>& until = {}) {
    const MonoTime end = time.mono() + d;
    MonoTime next_message = time.mono();
    while (time.mono() < end) {
      if (time.mono() >= next_message) {
        FillTraffic(m, clock.Read().wire, cars);
        traffic.Write(m);
        EXPECT_TRUE(traffic.WaitForAcks(seconds(10)));
        last_message = time.mono();
        next_message += milliseconds(100);
      }
      time.AdvanceTo(std::min({scm.next_deadline(), time.mono() + milliseconds(20), next_message}));
      scm.Pass();
      if (until && until()) break;
    }
  };

  // Through the start-up sequence to the first phase (east) resting in green: no calls.
  run(seconds(30), {}, [&] { return x.controller->stage() == Stage::kGreen; });
  ASSERT_EQ(aspect(0), Aspect::kGreen);

  // Cars elsewhere: on the south approach's egress lane, on the south ingress lane upstream of
  // the detector (0.6 m from the line; the car reaches 0.75 .. 1.0 m), and on another map's
  // lane. None calls: east rests in green.
  const std::uint64_t observed = scm.counters().fleet_observations;
  run(seconds(20), Cars{{"leaving", {egress(3).name, BeforeEnd(egress(3), 0.5)}},
                        {"upstream", {ingress(3).name, BeforeEnd(ingress(3), 0.875)}},
                        {"elsewhere", {"r9c9:W>E:0", Eigen::Vector2d(0.5, 0.5)}}});
  EXPECT_EQ(aspect(0), Aspect::kGreen) << "no call from a car outside every zone";
  EXPECT_EQ(aspect(3), Aspect::kRed);
  EXPECT_GE(scm.counters().fleet_observations - observed, 2u * 150u)
      << "the SCM took the cars on its map from 200 messages";

  // A car standing in the south zone calls south: east gaps out, south gets green.
  const Cars waiting_south{{"south", {ingress(3).name, BeforeEnd(ingress(3), 0.3)}}};
  const MonoTime called = time.mono();
  run(seconds(15), waiting_south, [&] { return aspect(3) == Aspect::kGreen; });
  ASSERT_EQ(aspect(3), Aspect::kGreen) << "the background car's call was served";
  EXPECT_LT(time.mono() - called, seconds(11)) << "yellow 3 s and red clearance 7 s after it";
  const MonoTime south_green = time.mono();

  // A car on east's zone too: south is extended while its car is refreshed (beyond its min
  // green, 5 s, and its extension, 2 s) ...
  Cars both = waiting_south;
  both.push_back({"east", {ingress(0).name, BeforeEnd(ingress(0), 0.2)}});
  run(seconds(8), both);
  EXPECT_EQ(aspect(3), Aspect::kGreen) << "extended by its own call";
  // Stepped on every pass while the call lasts, the loop still sleeps until its next tick.
  EXPECT_GT(scm.next_deadline(), time.mono()) << "the loop would spin";
  // ... and gaps out once it is no longer refreshed: it stays counted while fresh (1 s), then
  // the extension (2 s) runs out, well before max green (15 s).
  const MonoTime last_south = last_message;  // the last message with it
  const Cars only_east{{"east", {ingress(0).name, BeforeEnd(ingress(0), 0.2)}}};
  run(seconds(6), only_east, [&] { return aspect(3) != Aspect::kGreen; });
  ASSERT_EQ(aspect(3), Aspect::kYellow) << "the stale car stopped calling";
  EXPECT_GE(time.mono() - last_south, milliseconds(2500))
      << "not before staleness (1 s) and extension (2 s)";
  EXPECT_LT(time.mono() - south_green, seconds(15)) << "before max green";
  // East is served next (its car calls it).
  run(seconds(10), only_east, [&] { return aspect(0) == Aspect::kGreen; });
  EXPECT_EQ(aspect(0), Aspect::kGreen);

  // The detector channels (one per group, its zones together) are in the high-resolution log:
  // on (82) and off (81) alternating per channel from off, south's (4) on once its car stood in
  // the zone and off once it went stale, east's (1) on since.
  scm.FlushPersistence();
  HiresQuery q;
  q.intersection = x.model->id;
  q.until = clock.Read().wire + seconds(1);
  std::map<std::uint16_t, std::vector<std::pair<std::uint16_t, MonoTime>>> channels;
  const MonoTime mono_now = time.mono();
  const Time wire_now = clock.Read().wire;
  for (const HiresRecord& r :
       Store(Options(DrivingSchoolWithoutLights("", /*actuated=*/true)).db_path).Hires(q)) {
    if (r.code == hires::kDetectorOn || r.code == hires::kDetectorOff) {
      channels[r.param].push_back({r.code, mono_now - (wire_now - r.time)});
    }
  }
  EXPECT_EQ(channels.size(), 2u) << "south and east only";
  for (const auto& [channel, changes] : channels) {
    for (std::size_t i = 0; i < changes.size(); ++i) {
      EXPECT_EQ(changes[i].first, i % 2 == 0 ? hires::kDetectorOn : hires::kDetectorOff)
          << "channel " << channel << " change " << i;
    }
  }
  ASSERT_EQ(channels[4].size(), 2u) << "south: on, then off";
  EXPECT_GE(channels[4][0].second, called - milliseconds(1));
  EXPECT_LE(channels[4][0].second, south_green);
  EXPECT_GE(channels[4][1].second, last_south);
  ASSERT_EQ(channels[1].size(), 1u) << "east: on";
}

TEST_F(DaemonTest, FiveThousandBackgroundCarsCostTheLoopNoAllocationInSteadyState) {
  TestTime time;
  WallClock clock(time.Sources());
  Scm scm(Options(DrivingSchoolWithoutLights("", /*actuated=*/true)), clock, *participant_);
  const auto& map = scm.city().map;
  dds::Writer<msg::TrafficObjects> traffic(*participant_, dds::topics::Traffic());
  ASSERT_TRUE(traffic.WaitForReaders(1, seconds(10)));
  // 5,000 cars spread over every lane of the map in turn, some on the crossing's detectors (so
  // its groups are called and extended, and stepped on every pass). The sanitizer legs of CI
  // take a share of them (test::Cases): the same code paths, at a fifth of the instrumented
  // (de)serialisation, which took 80 to 90 s there.
  const auto count = static_cast<std::size_t>(std::min(5000, test::Cases(5000)));
  std::vector<std::pair<std::string, std::pair<std::string, Eigen::Vector2d>>> cars;
  for (std::size_t i = 0; i < count; ++i) {
    const maps::Lane& lane = map.lanes[i % map.lanes.size()];
    cars.push_back({fmt::format("flow_{}.{}", i % 37, i),
                    {lane.name, BeforeEnd(lane, 0.05 + 0.9 * static_cast<double>(i % 11) / 10)}});
  }
  dds::Message<msg::TrafficObjects> m;
  MonoTime next_message = time.mono();
  auto pass_to = [&](MonoTime t) {
    if (time.mono() >= next_message) {
      // The same cars again (new stamp): what SUMO sends while they drive on.
      m->header.stamp = dds::ToMsg(clock.Read().wire);
      traffic.Write(m);
      EXPECT_TRUE(traffic.WaitForAcks(seconds(10)));
      next_message += milliseconds(100);
    }
    time.AdvanceTo(std::min(t, next_message));
    scm.Pass();
  };
  FillTraffic(m, clock.Read().wire, cars);
  const MonoTime warm = time.mono() + seconds(60);
  while (time.mono() < warm) pass_to(std::min(scm.next_deadline(), time.mono() + milliseconds(20)));
  const std::uint64_t observed = scm.counters().fleet_observations;
  g_allocations = 0;
  g_count_allocations = true;
  const MonoTime end = time.mono() + seconds(20);
  int passes = 0;
  while (time.mono() < end) {
    pass_to(std::min(scm.next_deadline(), time.mono() + milliseconds(20)));
    ++passes;
  }
  g_count_allocations = false;
  EXPECT_EQ(g_allocations.load(), 0u) << "allocations in " << passes << " passes";
  EXPECT_GE(scm.counters().fleet_observations - observed, count * 190u)
      << "the SCM took the 200 messages of " << count << " cars";
}

TEST_F(DaemonTest, IpsPositionsFeedTheFleetAndAParkedCarGetsItsLane) {
  TestTime time;
  WallClock clock(time.Sources());
  Scm scm(Options(DrivingSchoolWithoutLights()), clock, *participant_);
  dds::Reader<msg::FleetState> fleet(*participant_, dds::topics::Fleet().name,
                                     dds::Qos::Stream(16));
  const auto& map = scm.city().map;
  const auto& lane = map.lane(map.intersections[0].approaches[0].ingress[0]);
  // A car parked 0.4 m before the stop line: its ips says the same point again and again.
  const Eigen::Vector2d at =
      lane.centreline[lane.centreline.size() - 2] +
      0.6 * (lane.centreline.back() - lane.centreline[lane.centreline.size() - 2]);
  dds::Writer<msg::Point> ips(*participant_, dds::topics::Ips(VehicleId(1)));
  ASSERT_TRUE(ips.WaitForReaders(1, seconds(10)));
  std::optional<dds::Message<msg::FleetState>> seen;
  for (int i = 0; i < 200 && !seen; ++i) {
    ips.Write(msg::Point{at.x(), at.y(), 0.0});
    time.AdvanceTo(time.mono() + milliseconds(100));
    scm.Pass();
    fleet.WaitForData(milliseconds(50));
    for (auto& m : fleet.TakeAll()) {
      if (m->vehicles._length == 1) seen = std::move(m);
    }
  }
  ASSERT_TRUE(seen) << "nigel_1 never appeared in the fleet state";
  const auto& v = dds::Elements((*seen)->vehicles)[0];
  EXPECT_EQ(dds::View(v.vehicle_id), "nigel_1");
  EXPECT_EQ(v.source, autodrive_msgs_msg_TrackedVehicle_Constants_IPS);
  EXPECT_EQ(dds::View(v.map_lane_id), lane.name) << "a car that never moved has its lane";
  EXPECT_EQ(v.intersection_id, map.intersections[0].id.value());
}

// The ips message has no time: the fleet takes the one its writer stamped, as long as that
// is not in the future and at most a second old (hosts' clocks agree that well), and the time
// it arrived otherwise.
TEST_F(DaemonTest, AnIpsPositionIsObservedWhenItsWriterWroteItUnlessTheClocksDisagree) {
  TestTime time;
  time.offset_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                       std::chrono::system_clock::now().time_since_epoch())
                       .count() -
                   time.mono_ns.load();
  WallClock clock(time.Sources());
  Scm scm(Options(DrivingSchoolWithoutLights()), clock, *participant_);
  dds::Reader<msg::FleetState> fleet(*participant_, dds::topics::Fleet().name,
                                     dds::Qos::Stream(64));
  dds::Writer<msg::Point> ips(*participant_, dds::topics::Ips(VehicleId(1)));
  ASSERT_TRUE(ips.WaitForReaders(1, seconds(10)));
  double x = 0.5;
  // nigel_1's observed time in the fleet after a position written with stamp `written`.
  const auto observed_after = [&](Time written) -> std::optional<Time> {
    x += 0.05;  // a new position each time, so that it is a new observation
    const msg::Point p{x, 0.3, 0.0};
    const auto ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(written.time_since_epoch());
    EXPECT_EQ(dds_write_ts(ips.handle(), &p, ns.count()), DDS_RETCODE_OK);
    for (int i = 0; i < 100; ++i) {
      time.AdvanceTo(time.mono() + milliseconds(20));
      scm.Pass();
      fleet.WaitForData(milliseconds(50));
      for (auto& m : fleet.TakeAll()) {
        for (const auto& v : dds::Elements(m->vehicles)) {
          if (dds::View(v.vehicle_id) == "nigel_1" && std::abs(v.pose.pose.position.x - x) < 1e-9) {
            return dds::FromMsg(v.observed);
          }
        }
      }
    }
    return std::nullopt;
  };
  const auto wire_now = [&] { return clock.Read().wire; };
  const auto near = [](Time a, Time b) {
    return a - b < milliseconds(1) && b - a < milliseconds(1);
  };

  const Time recent = wire_now() - milliseconds(300);
  const std::optional<Time> a = observed_after(recent);
  ASSERT_TRUE(a) << "the position never reached the fleet";
  EXPECT_TRUE(near(*a, recent)) << "a position written 0.3 s ago is observed when it was written";

  const Time old = wire_now() - seconds(5);
  const Time before_old = wire_now();
  const std::optional<Time> b = observed_after(old);
  ASSERT_TRUE(b);
  EXPECT_GE(*b, before_old) << "a stamp 5 s old is taken as the clocks disagreeing: arrival time";

  const Time ahead = wire_now() + seconds(3);
  const Time before_ahead = wire_now();
  const std::optional<Time> c = observed_after(ahead);
  ASSERT_TRUE(c);
  EXPECT_GE(*c, before_ahead);
  EXPECT_LT(*c, ahead) << "a stamp in the future is not believed";
}

TEST_F(DaemonTest, AnEventsIdIsItsRowInTheLogAndTheCountGoesOnAfterARestart) {
  TestTime time;
  WallClock clock(time.Sources());
  const std::filesystem::path city = DrivingSchoolWithoutLights();
  dds::Reader<msg::Event> live(*participant_, dds::topics::Events().name,
                               dds::Qos::LatchedState(100));
  // The live ids of the events called `code`, in the order they came.
  std::vector<std::uint64_t> started;
  const auto take = [&] {
    for (auto& m : live.TakeAll()) {
      if (dds::View(m->code) == "scm_started") started.push_back(m->event_id);
    }
  };
  for (int run = 0; run < 2; ++run) {
    Scm scm(Options(city), clock, *participant_);  // the second one after the first has gone
    scm.Pass();
    scm.FlushPersistence();
    take();
  }
  ASSERT_EQ(started.size(), 2u);
  EXPECT_GT(started[1], started[0]) << "a restarted SCM does not number its events from 1 again";
  std::vector<std::uint64_t> logged;
  for (const EventRecord& e : Store(Options(city).db_path).Events({})) {
    if (e.code == "scm_started") logged.push_back(static_cast<std::uint64_t>(e.id));
  }
  EXPECT_EQ(logged, started) << "the same ids live and in the log";
}

TEST_F(DaemonTest, TheControllersHighResolutionEventsReachTheLogOnTheWallClock) {
  TestTime time;
  WallClock clock(time.Sources());
  const std::filesystem::path city = DrivingSchoolWithoutLights();
  const Time start = clock.Read().wire;
  {
    Scm scm(Options(city), clock, *participant_);
    const MonoTime end = time.mono() + seconds(90);  // the start-up and a whole 72 s cycle
    while (time.mono() < end) {
      time.AdvanceTo(std::min(scm.next_deadline(), time.mono() + milliseconds(100)));
      scm.Pass();
    }
    scm.FlushPersistence();
  }
  const Store store(Options(city).db_path);
  const IntersectionId id = LoadCity(city).intersections.front().id;
  HiresQuery q;
  q.intersection = id;
  q.since = start;
  q.until = start + seconds(90);
  const std::vector<HiresRecord> log = store.Hires(q);
  ASSERT_FALSE(log.empty());
  EXPECT_EQ(log.front(),
            (HiresRecord{id, start, hires::kUnitFlashStatusChange, hires::kFlashStartup}))
      << "the start-up flash, when the SCM started";
  // Each phase served in full: green, force off (fixed time), yellow, red clearance, in that
  // order, 8 s green, 3 s yellow and 7 s red clearance apart on the wall clock.
  int full = 0;
  for (std::size_t i = 0; i < log.size(); ++i) {
    if (log[i].code != hires::kPhaseBeginGreen) continue;
    std::vector<std::uint16_t> codes;
    std::map<std::uint16_t, Time> at;
    for (std::size_t j = i; j < log.size(); ++j) {
      if (log[j].param != log[i].param || log[j].code > hires::kPhaseInactive) continue;
      if (j > i && log[j].code == hires::kPhaseBeginGreen) break;
      codes.push_back(log[j].code);
      at.emplace(log[j].code, log[j].time);
    }
    if (!at.contains(hires::kPhaseInactive) || at[hires::kPhaseBeginYellow] - at[1] != seconds(8))
      continue;  // the first, shortened by the start-up, or cut by the end of the run
    ++full;
    EXPECT_EQ(codes, (std::vector<std::uint16_t>{1, 2, 3, 6, 7, 8, 9, 10, 11, 12}));
    EXPECT_EQ(at[hires::kPhaseEndYellow] - at[hires::kPhaseBeginYellow], seconds(3));
    EXPECT_EQ(at[hires::kPhaseEndRedClearance] - at[hires::kPhaseBeginRedClearance], seconds(7));
  }
  EXPECT_GE(full, 3);
}

// A launcher's table as `autodrive-city` writes it: the lights running, the SCM (pid 900)
// killed by SIGKILL at `died` and being started again.
void FillTable(Time died, dds::Message<msg::ProcessTable>& m) {
  m->header.stamp = dds::ToMsg(died + milliseconds(60));
  dds::SetString(m->city, "driving_school");
  dds::SetString(m->host, "lab-pc");
  m->session_id = 42;
  m->period_ms = 1000;
  m->state = autodrive_msgs_msg_ProcessTable_Constants_RUNNING;
  dds::ResizeSequence(m->processes, 2);
  msg::ProcessEntry& lights = m->processes._buffer[0];
  dds::SetString(lights.name, "lights");
  lights.state = autodrive_msgs_msg_ProcessEntry_Constants_RUNNING;
  lights.pid = 800;
  lights.starts = 1;
  lights.since = dds::ToMsg(died - seconds(60));
  msg::ProcessEntry& scm = m->processes._buffer[1];
  dds::SetString(scm.name, "scm");
  scm.state = autodrive_msgs_msg_ProcessEntry_Constants_STARTING;
  scm.pid = 901;
  scm.starts = 2;
  scm.since = dds::ToMsg(died + milliseconds(50));
  scm.exits = 1;
  scm.exit_code = 137;
  scm.exit_signal = 9;
  scm.exit_pid = 900;
  scm.exited_at = dds::ToMsg(died);
}

TEST_F(DaemonTest, AKilledScmsDeathIsLoggedOnceByTheNextOneStampedWhenItDied) {
  TestTime time;
  WallClock clock(time.Sources());
  const std::filesystem::path city = DrivingSchoolWithoutLights();
  dds::Reader<msg::Event> live(*participant_, dds::topics::Events().name,
                               dds::Qos::LatchedState(100));
  std::vector<dds::Message<msg::Event>> seen;
  // The events with `code` this test saw live.
  const auto live_with_code = [&](std::string_view code) {
    for (auto& m : live.TakeAll()) seen.push_back(std::move(m));
    std::vector<const msg::Event*> out;
    for (const auto& m : seen) {
      if (dds::View(m->code) == code) out.push_back(&*m);
    }
    return out;
  };
  std::int64_t last_id_before = 0;
  {
    // The SCM that runs first: its events are numbered from the log's start.
    Scm first(Options(city), clock, *participant_);
    first.Pass();
    first.FlushPersistence();
    last_id_before = Store(Options(city).db_path).LastEventId();
    ASSERT_GT(last_id_before, 0);
  }  // killed (its successor does not know how it ended)
  const Time died = SystemNow() - seconds(5);
  dds::Writer<msg::ProcessTable> launcher(*participant_, dds::topics::Processes());
  dds::Message<msg::ProcessTable> table;
  FillTable(died, table);
  launcher.Write(table);  // before the next SCM runs: it finds the table (transient-local)

  const auto run_until = [&](Scm& scm, const std::function<bool()>& done) {
    const auto until = std::chrono::steady_clock::now() + seconds(30);
    while (!done() && std::chrono::steady_clock::now() < until) {
      time.AdvanceTo(time.mono() + milliseconds(20));
      scm.Pass();
      live.WaitForData(milliseconds(20));
    }
    return done();
  };
  {
    Scm second(Options(city), clock, *participant_);
    ASSERT_TRUE(run_until(second, [&] { return !live_with_code("process_exited").empty(); }))
        << "the second SCM never logged the first one's death";
    const msg::Event& exited = *live_with_code("process_exited").front();
    EXPECT_EQ(exited.severity, autodrive_msgs_msg_Event_Constants_ALARM);
    EXPECT_TRUE(exited.active);
    EXPECT_EQ(dds::View(exited.device_id), "process/scm");
    EXPECT_EQ(dds::FromMsg(exited.header.stamp), died) << "stamped when it died";
    EXPECT_THAT(std::string(dds::View(exited.message)),
                ::testing::HasSubstr("killed by signal 9 (SIGKILL)"));
    // Numbered on from the log: the same id live and in the log, none used twice.
    EXPECT_GT(static_cast<std::int64_t>(exited.event_id), last_id_before);
    second.FlushPersistence();
    bool in_log = false;
    for (const EventRecord& e : Store(Options(city).db_path).Events({})) {
      if (e.code != "process_exited") continue;
      in_log = true;
      EXPECT_EQ(static_cast<std::uint64_t>(e.id), exited.event_id);
      EXPECT_EQ(e.time, died);
    }
    EXPECT_TRUE(in_log);
    // Ready: the launcher says it runs again.
    table->processes._buffer[1].state = autodrive_msgs_msg_ProcessEntry_Constants_RUNNING;
    table->processes._buffer[1].since = dds::ToMsg(died + seconds(1));
    launcher.Write(table);
    ASSERT_TRUE(run_until(second, [&] { return !live_with_code("process_restarted").empty(); }));
    EXPECT_EQ(dds::FromMsg(live_with_code("process_restarted").front()->header.stamp),
              died + seconds(1));
    second.FlushPersistence();
  }
  // A third SCM reads the same table (and the launcher writes it again): nothing twice.
  {
    Scm third(Options(city), clock, *participant_);
    launcher.Write(table);
    ASSERT_TRUE(launcher.WaitForAcks(seconds(10)));
    for (int i = 0; i < 25; ++i) {
      time.AdvanceTo(time.mono() + milliseconds(20));
      third.Pass();
    }
    third.FlushPersistence();
  }
  int exits = 0, returns = 0;
  for (const EventRecord& e : Store(Options(city).db_path).Events({})) {
    exits += e.code == "process_exited" ? 1 : 0;
    returns += e.code == "process_restarted" ? 1 : 0;
  }
  EXPECT_EQ(exits, 1);
  EXPECT_EQ(returns, 1);
}

TEST_F(DaemonTest, RequestsWaitingWhenSpatIsDueAreAnsweredFirstButOnlyAFew) {
  // 3 x 3 intersections: SPaT is filled in slices (4 intersections each here, 128 by default),
  // and the loop looks for waiting requests between them.
  TestTime time;
  WallClock clock(time.Sources());
  ScmOptions options = Options(bench::WriteGridCity(3, dir_, "lab"));
  options.config_root = dir_;
  options.spat_slice = 4;
  Scm scm(options, clock, *participant_);
  ASSERT_GT(scm.runtime().intersections().size(), options.spat_slice);
  dds::Reader<msg::OperatorReply> replies(*participant_, dds::topics::OperatorReplies().name,
                                          dds::Qos::Stream(64));
  dds::Writer<msg::OperatorRequest> requests(*participant_, dds::topics::OperatorRequests());
  ASSERT_TRUE(requests.WaitForReaders(1, seconds(10)));
  // Pass at every deadline until a SPaT goes out: the next is due 100 ms later.
  std::uint64_t spats = scm.counters().spat_published;
  for (int i = 0; i < 100 && scm.counters().spat_published == spats; ++i) {
    time.AdvanceTo(std::min(scm.next_deadline(), time.mono() + milliseconds(20)));
    scm.Pass();
  }
  ASSERT_GT(scm.counters().spat_published, spats);
  const MonoTime spat_due = time.mono() + milliseconds(100);
  time.AdvanceTo(spat_due - milliseconds(1));
  scm.Pass();
  spats = scm.counters().spat_published;
  const std::uint64_t handled = scm.counters().operator_requests;

  // Ten requests arrive (acknowledged: they are in the SCM's reader) as SPaT comes due.
  for (std::uint64_t k = 1; k <= 10; ++k) {
    dds::Message<msg::OperatorRequest> m;
    dds::SetString(m->client_id, "waiting");
    m->request_id = k;
    dds::SetString(m->command, "status");
    requests.Write(m);
  }
  ASSERT_TRUE(requests.WaitForAcks(seconds(10)));
  time.AdvanceTo(spat_due);
  scm.Pass();
  EXPECT_EQ(scm.counters().spat_published, spats) << "SPaT gave way to the waiting requests";
  EXPECT_EQ(scm.counters().operator_requests, handled) << "SPaT's deadline had come";
  scm.Pass();  // at the same instant
  EXPECT_EQ(scm.counters().operator_requests, handled + 4) << "four answered before SPaT";
  EXPECT_EQ(scm.counters().spat_published, spats + 1)
      << "then SPaT, without giving way again (a flood cannot hold it back)";
  scm.Pass();
  EXPECT_EQ(scm.counters().operator_requests, handled + 10) << "and the rest after it";
  std::set<std::uint64_t> answered;
  const auto until = std::chrono::steady_clock::now() + seconds(10);
  while (answered.size() < 10 && std::chrono::steady_clock::now() < until) {
    replies.WaitForData(milliseconds(100));
    for (auto& r : replies.TakeAll()) {
      if (dds::View(r->client_id) == "waiting") answered.insert(r->request_id);
    }
  }
  EXPECT_EQ(answered.size(), 10u);
}

}  // namespace
}  // namespace autodrive::scm
