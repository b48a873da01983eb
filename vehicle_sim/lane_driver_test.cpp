// The example driver on the simulator, in-process: it follows lanes, stops at red, goes at
// green, and does not run into the car ahead.
#include "vehicle_sim/lane_driver.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <vector>

#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/layout.h"
#include "vehicle_sim/sensors.h"
#include "vehicle_sim/sim_config.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim {
namespace {

using vehicle_sim::SensorReadings;
using vehicle_sim::SensorSuite;
using vehicle_sim::World;

const maps::Map& SmallTown() {
  static const maps::Map map =
      maps::Build(maps::LoadLayout((test::SourceDir() / "config/maps/small_town.yaml").string()));
  return map;
}

double DistanceToRoad(const maps::Map& map, const Eigen::Vector2d& p) {
  double best = std::numeric_limits<double>::infinity();
  const auto scan = [&](const maps::Polyline& line) {
    for (std::size_t i = 0; i + 1 < line.size(); ++i) {
      const Eigen::Vector2d d = line[i + 1] - line[i];
      const double t = std::clamp((p - line[i]).dot(d) / d.squaredNorm(), 0.0, 1.0);
      best = std::min(best, (line[i] + t * d - p).norm());
    }
  };
  for (const auto& l : map.lanes) scan(l.centreline);
  for (const auto& m : map.movements) scan(m.path);
  return best;
}

// Cars on the small town, each with its driver and sensors, the lights showing `lamps`.
struct Town {
  World world{SmallTown()};
  std::vector<LaneDriver> drivers;
  std::vector<SensorSuite> suites;
  std::vector<std::vector<float>> scans;
  std::map<SignalHeadId, std::int32_t> lamps;
  std::vector<DriverDecision> last;

  void AddCar(const std::string& lane, double along, std::uint64_t seed = 1,
              DriverOptions options = {}) {
    vehicle_sim::SimConfig sim;
    sim.vehicles = {{"nigel_1", vehicle_sim::SpawnConfig{lane, along, {}, {}, {}}, {}, {}, {}}};
    const int i = world.AddVehicle({}, vehicle_sim::SpawnPoses(sim, SmallTown())[0]);
    options.seed = seed;
    drivers.emplace_back(SmallTown(), options);
    suites.emplace_back(vehicle_sim::SensorConfig{}, i, 1);
    scans.emplace_back();
    last.emplace_back();
  }
  void SetAll(std::int32_t lamp) {
    for (const auto& h : SmallTown().signal_heads) lamps[h.id] = lamp;
  }
  // Runs for `seconds`, a driver decision every 50 ms; `each` after every step.
  template <typename F>
  void Run(double seconds, F&& each) {
    std::vector<vehicle_sim::DynamicBox> boxes;
    SensorReadings readings;
    const Duration end = world.time() + FromSeconds(seconds);
    while (world.time() < end) {
      if (world.steps() % 25 == 0) {
        for (std::size_t i = 0; i < drivers.size(); ++i) {
          const auto& s = world.State(static_cast<int>(i));
          last[i] = drivers[i].Step(
              RigidTransform2::FromXyYaw(s.X_MV.translation().x(), s.X_MV.translation().y(),
                                         s.X_MV.yaw()),
              [&](SignalHeadId h) -> std::optional<std::int32_t> {
                const auto it = lamps.find(h);
                if (it == lamps.end()) return std::nullopt;
                return it->second;
              },
              scans[i], world.time());
          world.SetCommand(static_cast<int>(i), {last[i].throttle, last[i].steering});
        }
      }
      world.Step();
      vehicle_sim::VehicleBoxes(world, boxes);
      for (std::size_t i = 0; i < suites.size(); ++i) {
        suites[i].Sample(world, world.Scene(), boxes, readings);
        if (readings.lidar) scans[i] = readings.lidar->ranges;
      }
      each();
    }
  }
};

TEST(LaneDriver, AtGreenEverywhereKeepsDrivingOnTheRoadsOfTheTown) {
  Town town;
  town.SetAll(3);
  town.AddCar("r4c1:W>E:0", 0.2);
  double travelled = 0;
  double worst = 0;
  Eigen::Vector2d last = town.world.State(0).X_MV.translation().head<2>();
  town.Run(90, [&] {
    const Eigen::Vector2d p = town.world.State(0).X_MV.translation().head<2>();
    travelled += (p - last).norm();
    last = p;
    worst = std::max(worst, DistanceToRoad(SmallTown(), p));
  });
  std::printf("90 s at green: %.2f m driven, at most %.3f m from a lane's centre line\n", travelled,
              worst);
  EXPECT_GT(travelled, 8.0);  // 0.6 x 0.26 m/s, less the stop signs
  EXPECT_LT(worst, 0.1);      // on its lane (lanes are 0.3 m wide)
}

TEST(LaneDriver, FollowsItsRouteWhateverItsSeedAndStopsAtItsEnd) {
  // Without a route the choice at the centre crossing is random; with one, every seed turns
  // left onto the route's last lane and stops at its end.
  const maps::Lane* goal = SmallTown().FindLane("r1c2:S>N:0");
  ASSERT_NE(goal, nullptr);
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    Town town;
    town.SetAll(3);
    DriverOptions options;
    options.route = {SmallTown().FindLane("r2c1:W>E:0")->id, goal->id};
    options.stop_at_route_end = true;
    town.AddCar("r2c1:W>E:0", 0.1, seed, options);
    town.Run(30, [] {});
    const auto& s = town.world.State(0);
    const double front_to_end =
        (goal->centreline.back() - s.X_MV.translation().head<2>()).norm() - 0.2297;
    EXPECT_EQ(town.last[0].reason, DriverDecision::Reason::kGoal) << "seed " << seed;
    EXPECT_LT(std::abs(front_to_end), 0.06) << "seed " << seed;
    EXPECT_LT(std::abs(s.v_V_mps.x()), 0.005) << "seed " << seed;
  }
}

TEST(LaneDriver, FaultsOnPurposeRunTheRedLightAndLeaveTheLane) {
  Town town;
  town.SetAll(1);
  DriverOptions options;
  options.ignore_lights = true;
  options.lateral_offset_m = 0.2;
  town.AddCar("r2c1:W>E:0", 0.1, 1, options);
  double worst = 0;
  town.Run(12, [&] {
    worst = std::max(worst,
                     DistanceToRoad(SmallTown(), town.world.State(0).X_MV.translation().head<2>()));
  });
  // Through the red light at the centre crossing (x 2.5), 0.2 m left of the lanes' centres
  // (on the opposite lane, whose centre is 0.3 m away: about 0.1 m from it).
  EXPECT_GT(town.world.State(0).X_MV.translation().x(), 2.6);
  EXPECT_GT(worst, 0.05);
}

TEST(LaneDriver, StopsAtTheLineOnRedAndGoesOnGreen) {
  Town town;
  town.SetAll(1);
  town.AddCar("r2c1:W>E:0", 0.1);  // towards the signalised centre crossing, from the west
  const maps::Lane* lane = nullptr;
  for (const auto& l : SmallTown().lanes) {
    if (l.name == "r2c1:W>E:0") lane = &l;
  }
  ASSERT_TRUE(lane != nullptr && lane->stop_line.has_value());
  const Eigen::Vector2d line = 0.5 * (lane->stop_line->left + lane->stop_line->right);
  town.Run(15, [] {});
  const auto& s = town.world.State(0);
  const double front = s.X_MV.translation().x() + 0.2297;
  std::printf("at red: the car's front %.3f m before the stop line, speed %.4f m/s\n",
              line.x() - front, s.v_V_mps.x());
  EXPECT_EQ(town.last[0].reason, DriverDecision::Reason::kRedLight);
  EXPECT_GT(line.x() - front, 0.0);
  EXPECT_LT(line.x() - front, 0.1);
  EXPECT_LT(std::abs(s.v_V_mps.x()), 0.005);
  town.SetAll(3);
  town.Run(5, [] {});
  EXPECT_GT(town.world.State(0).X_MV.translation().x() + 0.2297, line.x() + 0.2);  // through
}

// The car's rear axle where the driver stops it at `lane`'s stop line.
RigidTransform2 AtStopLine(const maps::Lane& lane, const DriverOptions& options) {
  const Eigen::Vector2d line = 0.5 * (lane.stop_line->left + lane.stop_line->right);
  const Eigen::Vector2d heading =
      (lane.centreline.back() - lane.centreline[lane.centreline.size() - 2]).normalized();
  const Eigen::Vector2d rear = line - heading * (options.front_overhang_m + options.stop_gap_m);
  return RigidTransform2::FromXyYaw(rear.x(), rear.y(), std::atan2(heading.y(), heading.x()));
}

TEST(LaneDriver, AtAStopSignWaitsWhileSomethingIsInTheBoxThenGoes) {
  // The car stands at the stop line of a stop-controlled T-junction.
  const maps::Map& map = SmallTown();
  const maps::Lane* lane = nullptr;
  for (const auto& l : map.lanes) {
    if (l.stop_line && l.ingress_of &&
        map.intersection(*l.ingress_of).control == maps::Control::kStop) {
      lane = &l;
      break;
    }
  }
  ASSERT_NE(lane, nullptr);
  const DriverOptions options;
  const RigidTransform2 X_MV = AtStopLine(*lane, options);
  const auto no_lamps = [](SignalHeadId) -> std::optional<std::int32_t> { return std::nullopt; };
  // A scan with one return straight ahead, `r` from the LIDAR (all else: nothing).
  const auto scan = [](double r) {
    std::vector<float> s(360, std::numeric_limits<float>::infinity());
    if (r > 0) s[0] = static_cast<float>(r);
    return s;
  };
  // Something 0.4 m into the box (a car crossing it): it waits, however long.
  const double to_box = options.front_overhang_m + options.stop_gap_m - options.lidar_x_m;
  LaneDriver driver(map, options);
  DriverDecision d;
  for (int i = 0; i <= 100; ++i) {
    d = driver.Step(X_MV, no_lamps, scan(to_box + 0.4), FromSeconds(0.05 * i));
  }
  EXPECT_EQ(d.reason, DriverDecision::Reason::kStopSign) << "5 s with the box taken";
  EXPECT_EQ(d.throttle, 0.0);
  // The box clears (the return now beyond it, 1.5 m on): it goes.
  for (int i = 101; i <= 110; ++i) {
    d = driver.Step(X_MV, no_lamps, scan(to_box + 1.5), FromSeconds(0.05 * i));
  }
  EXPECT_GT(d.throttle, 0.0) << "the box is clear";
  // A fresh driver with the box clear goes after its stop (1 s), not before.
  LaneDriver fresh(map, options);
  d = fresh.Step(X_MV, no_lamps, scan(0), FromSeconds(0));
  EXPECT_EQ(d.reason, DriverDecision::Reason::kStopSign);
  for (int i = 1; i <= 25; ++i) d = fresh.Step(X_MV, no_lamps, scan(0), FromSeconds(0.05 * i));
  EXPECT_GT(d.throttle, 0.0);
}

TEST(LaneDriver, AFlashingRedIsAStopSignWhileItFlashes) {
  // The car stands at the stop line of the small town's signalised centre, from the west; the
  // head facing it flashes red (red and dark in turn every 0.5 s), or says so (wire 4).
  const maps::Map& map = SmallTown();
  const maps::Lane* lane = map.FindLane("r2c1:W>E:0");
  ASSERT_TRUE(lane != nullptr && lane->stop_line && lane->ingress_of);
  const DriverOptions options;
  const RigidTransform2 X_MV = AtStopLine(*lane, options);
  const std::vector<float> clear(360, std::numeric_limits<float>::infinity());
  const auto flashing = [](double t) {
    return [t](SignalHeadId) -> std::optional<std::int32_t> {
      return static_cast<int>(std::floor(t / 0.5)) % 2 == 0 ? 1 : 0;
    };
  };
  // Flashing: a full stop (a second), then on with the box clear.
  LaneDriver driver(map, options);
  DriverDecision d;
  for (int i = 0; i <= 15; ++i) {
    d = driver.Step(X_MV, flashing(0.05 * i), clear, FromSeconds(0.05 * i));
  }
  EXPECT_EQ(d.reason, DriverDecision::Reason::kStopSign) << "0.75 s: still stopping";
  EXPECT_EQ(d.throttle, 0.0);
  for (int i = 16; i <= 30; ++i) {
    d = driver.Step(X_MV, flashing(0.05 * i), clear, FromSeconds(0.05 * i));
  }
  EXPECT_GT(d.throttle, 0.0) << "after its stop it goes through the flashing red";
  // Flashing turns to steady red before it went: held as at any red.
  LaneDriver held(map, options);
  for (int i = 0; i <= 10; ++i)
    (void)held.Step(X_MV, flashing(0.05 * i), clear, FromSeconds(0.05 * i));
  const auto red = [](SignalHeadId) -> std::optional<std::int32_t> { return 1; };
  for (int i = 11; i <= 60; ++i) d = held.Step(X_MV, red, clear, FromSeconds(0.05 * i));
  EXPECT_EQ(d.reason, DriverDecision::Reason::kRedLight);
  EXPECT_EQ(d.throttle, 0.0);
  // A steady red never passes for a flashing one, however long it stands.
  LaneDriver steady(map, options);
  for (int i = 0; i <= 100; ++i) d = steady.Step(X_MV, red, clear, FromSeconds(0.05 * i));
  EXPECT_EQ(d.reason, DriverDecision::Reason::kRedLight);
  // Wire 4 (flashing red, as a head may say it): the same stop-sign rule.
  LaneDriver told(map, options);
  const auto four = [](SignalHeadId) -> std::optional<std::int32_t> { return 4; };
  d = told.Step(X_MV, four, clear, FromSeconds(0));
  EXPECT_EQ(d.reason, DriverDecision::Reason::kStopSign);
  for (int i = 1; i <= 25; ++i) d = told.Step(X_MV, four, clear, FromSeconds(0.05 * i));
  EXPECT_GT(d.throttle, 0.0);
}

TEST(LaneDriver, AFollowingCarKeepsItsDistanceFromAStoppedOne) {
  Town town;
  town.SetAll(1);
  town.AddCar("r2c1:W>E:0", 0.5);     // stops at the red light
  town.AddCar("r2c1:W>E:0", 0.0, 2);  // starts 0.5 m behind it and follows
  double closest = std::numeric_limits<double>::infinity();
  town.Run(30, [&] {
    closest = std::min(
        closest,
        (town.world.State(0).X_MV.translation() - town.world.State(1).X_MV.translation()).norm());
  });
  std::printf("closest approach of the rear axles: %.3f m (bodies 0.318 m long)\n", closest);
  EXPECT_GT(closest, 0.318 + 0.05);
  EXPECT_LT(std::abs(town.world.State(1).v_V_mps.x()), 0.01);  // it waits behind
}

// The next stop line is seen as far ahead as the route is planned (`plan_ahead_m`), with the
// movement the route takes through it, and an indication is asked for that movement.
TEST(LaneDriver, SeesTheNextStopLineAsFarAheadAsItPlansAndAsksForItsMovement) {
  const maps::Map& map = SmallTown();
  // r3c0:N>S:0 (1 m), r4c0:N>E:0 (1.021 m), r4c1:W>E:0 (1 m, to south_t's stop line).
  const maps::Lane& start = *map.FindLane("r3c0:N>S:0");
  const maps::Lane& ingress = *map.FindLane("r4c1:W>E:0");
  const maps::Lane& out = *map.FindLane("r4c3:W>E:0");
  DriverOptions options;
  options.route = {start.id, map.FindLane("r4c0:N>E:0")->id, ingress.id, out.id};
  const Eigen::Vector2d p = start.centreline.front();
  const Eigen::Vector2d d = (start.centreline[1] - start.centreline[0]).normalized();
  const RigidTransform2 X_MV = RigidTransform2::FromXyYaw(p.x(), p.y(), std::atan2(d.y(), d.x()));
  const SignalLookup red = [](const maps::Lane&, const maps::Movement*) {
    return std::optional<SignalIndication>(
        SignalIndication{SignalIndication::State::kRed, 10.0, 20.0, 20.0});
  };
  {
    LaneDriver driver(map, options);  // 2 m: the line is 3 m ahead of the rear axle
    (void)driver.Step(X_MV, red, {}, Duration{});
    EXPECT_FALSE(driver.NextStopLine().has_value());
  }
  options.plan_ahead_m = 4.0;
  LaneDriver driver(map, options);
  (void)driver.Step(X_MV, red, {}, Duration{});
  const std::optional<StopLineAhead> ahead = driver.NextStopLine();
  ASSERT_TRUE(ahead.has_value());
  EXPECT_EQ(ahead->ingress, &ingress);
  EXPECT_EQ(ahead->intersection->name, "south_t");
  ASSERT_NE(ahead->movement, nullptr);
  EXPECT_EQ(ahead->egress, &out) << "the route's movement: straight on";
  EXPECT_NEAR(ahead->to_line_m, 1.0 + 1.021 + 1.0 - options.front_overhang_m, 0.01);
}

}  // namespace
}  // namespace autodrive::vehicle_sim
