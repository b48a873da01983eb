// The lab cars' claims on the small town's map: what SUMO's vehicles must not start while a lab
// car approaches an intersection, crosses its box and leaves it.
#include "traffic/lab_claims.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>

#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/layout.h"

namespace autodrive::traffic {
namespace {

const maps::Map& SmallTown() {
  static const maps::Map map =
      maps::Build(maps::LoadLayout((test::SourceDir() / "config/maps/small_town.yaml").string()));
  return map;
}

const maps::Lane& LaneNamed(const std::string& name) {
  for (const maps::Lane& l : SmallTown().lanes) {
    if (l.name == name) return l;
  }
  throw std::runtime_error("no lane " + name);
}

const maps::Movement& MovementNamed(const std::string& name) {
  for (const maps::Movement& m : SmallTown().movements) {
    if (m.name == name) return m;
  }
  throw std::runtime_error("no movement " + name);
}

// A car whose body's front is `to_line` before the end of `lane` (negative: past it), on it.
LabCarPose OnLane(const maps::Lane& lane, double to_line, const LabCarClaims::Options& o) {
  const Eigen::Vector2d end = lane.centreline.back();
  const Eigen::Vector2d before = lane.centreline[lane.centreline.size() - 2];
  const Eigen::Vector2d heading = (end - before).normalized();
  const double front = o.body_centre_ahead_m + o.length_m / 2;  // rear axle to front
  LabCarPose pose;
  pose.name = "nigel_1";
  pose.position = end - heading * (to_line + front);
  pose.yaw_rad = std::atan2(heading.y(), heading.x());
  return pose;
}

// A car whose body's centre is at arc length `s` of movement m's path, along it.
LabCarPose OnPath(const maps::Movement& m, double s, const LabCarClaims::Options& o) {
  const maps::Polyline& p = m.path;
  for (std::size_t i = 0; i + 1 < p.size(); ++i) {
    const double n = (p[i + 1] - p[i]).norm();
    if (s <= n || i + 2 == p.size()) {
      const Eigen::Vector2d d = (p[i + 1] - p[i]).normalized();
      LabCarPose pose;
      pose.name = "nigel_1";
      pose.position = p[i] + d * std::min(s, n) - d * o.body_centre_ahead_m;
      pose.yaw_rad = std::atan2(d.y(), d.x());
      return pose;
    }
    s -= n;
  }
  return {};
}

std::set<std::string> Names(const std::vector<MovementId>& held) {
  std::set<std::string> names;
  for (const MovementId m : held) names.insert(SmallTown().movement(m).name);
  return names;
}

std::set<std::string> FoesOf(const std::vector<MovementId>& of) {
  std::set<std::string> names;
  for (const maps::Intersection& x : SmallTown().intersections) {
    for (const auto& [a, b] : x.conflicts) {
      for (const MovementId m : of) {
        if (a == m) names.insert(SmallTown().movement(b).name);
        if (b == m) names.insert(SmallTown().movement(a).name);
      }
    }
  }
  return names;
}

// From the west into the signalised centre, straight over it, and out to the east.
TEST(LabCarClaims, ACarHoldsWhatConflictsWithItsWayFromTheLineUntilItsRearIsOutOfTheBox) {
  const maps::Map& map = SmallTown();
  const maps::MapIndex index(map);
  const LabCarClaims::Options options;
  LabCarClaims claims(map, index, options);
  const maps::Lane& in = LaneNamed("r2c1:W>E:0");
  ASSERT_TRUE(in.ingress_of.has_value());
  const auto green = [](MovementId) { return true; };
  const auto red = [](MovementId) { return false; };

  // Far from the line: nothing.
  claims.Update({OnLane(in, 0.8, options)}, green);
  EXPECT_TRUE(claims.held().empty());
  EXPECT_FALSE(claims.Approaching("nigel_1").has_value());

  // Near it, at red: nothing (it stops); at green: whatever conflicts with any way it may
  // take, but not those ways (a SUMO car ahead of it on its lane may go).
  claims.Update({OnLane(in, 0.2, options)}, red);
  EXPECT_TRUE(claims.held().empty());
  claims.Update({OnLane(in, 0.2, options)}, green);
  EXPECT_EQ(claims.Approaching("nigel_1"), in.id);
  const std::set<std::string> foes = FoesOf(in.movements_out);
  ASSERT_FALSE(foes.empty());
  EXPECT_EQ(Names(claims.held()), foes);

  // Over the line, in the box, on the straight movement: its lane's movements and what
  // conflicts with the movements it may be on (whatever the light now shows). Near the line
  // the three paths from its lane still run together; half a metre in, only the straight one
  // is under it.
  const maps::Movement& straight = MovementNamed("r2c2:W>E:0>0");
  ASSERT_EQ(straight.from, in.id);
  std::set<std::string> expected = FoesOf({straight.id});
  for (const MovementId m : in.movements_out) expected.insert(map.movement(m).name);
  for (const double s : {0.05, 0.3, 0.5}) {
    claims.Update({OnPath(straight, s, options)}, red);
    EXPECT_EQ(claims.InBox("nigel_1"), in.ingress_of) << s;
    const std::set<std::string> held = Names(claims.held());
    EXPECT_TRUE(std::includes(held.begin(), held.end(), expected.begin(), expected.end()))
        << "at " << s << " m into the box";
  }
  EXPECT_EQ(Names(claims.held()), expected) << "half a metre into the box";

  // Its rear on the lane out: nothing.
  const maps::Lane& out = map.lane(straight.to);
  LabCarPose leaving = OnLane(out, out.length_m, options);  // front at the lane's start...
  leaving.position += Eigen::Vector2d(std::cos(leaving.yaw_rad), std::sin(leaving.yaw_rad)) *
                      (options.length_m + 0.05);  // ... moved on until the rear is past it
  claims.Update({leaving}, green);
  EXPECT_FALSE(claims.InBox("nigel_1").has_value());
  EXPECT_TRUE(claims.held().empty());
}

// A car off every path in the box (15 cm right of the straight one, on its way east) holds
// what any way out of its lane may need; SUMO is to have it on the nearest path that runs its
// way.
TEST(LabCarClaims, ACarOffEveryPathIsUnderTheNearestThatRunsItsWay) {
  const maps::Map& map = SmallTown();
  const maps::MapIndex index(map);
  const LabCarClaims::Options options;
  LabCarClaims claims(map, index, options);
  const maps::Lane& in = LaneNamed("r2c1:W>E:0");
  const maps::Movement& straight = MovementNamed("r2c2:W>E:0>0");
  const auto red = [](MovementId) { return false; };
  for (const double s : {0.05, 0.2, 0.4}) claims.Update({OnPath(straight, s, options)}, red);
  ASSERT_EQ(claims.InBox("nigel_1"), in.ingress_of);
  LabCarPose off = OnPath(straight, 0.7, options);
  off.position += Eigen::Vector2d(std::sin(off.yaw_rad), -std::cos(off.yaw_rad)) * 0.15;
  claims.Update({off}, red);
  EXPECT_EQ(claims.InBox("nigel_1"), in.ingress_of);
  const auto under = claims.Under("nigel_1");
  ASSERT_TRUE(under.has_value());
  EXPECT_EQ(under->first, straight.id);
  EXPECT_NEAR(under->second, 0.7 / straight.length_m, 0.05);
  std::set<std::string> expected = FoesOf(in.movements_out);
  for (const MovementId m : in.movements_out) expected.insert(map.movement(m).name);
  EXPECT_EQ(Names(claims.held()), expected);
}

// A car seen first inside a box (a spawn there, or back in SUMO after a while off the road)
// claims the movements whose paths it is on, and what conflicts with them.
TEST(LabCarClaims, ACarFirstSeenInABoxHoldsTheMovementsItIsOnAndTheirFoes) {
  const maps::Map& map = SmallTown();
  const maps::MapIndex index(map);
  const LabCarClaims::Options options;
  LabCarClaims claims(map, index, options);
  const maps::Movement& straight = MovementNamed("r2c2:W>E:0>0");
  claims.Update({OnPath(straight, 0.3, options)}, [](MovementId) { return false; });
  EXPECT_EQ(claims.InBox("nigel_1"), straight.intersection);
  const std::set<std::string> held = Names(claims.held());
  EXPECT_EQ(held.count(straight.name), 1u);
  for (const std::string& foe : FoesOf({straight.id})) EXPECT_EQ(held.count(foe), 1u) << foe;
  // A car that is no longer listed is forgotten.
  claims.Update({}, [](MovementId) { return true; });
  EXPECT_TRUE(claims.held().empty());
  EXPECT_FALSE(claims.InBox("nigel_1").has_value());
}

}  // namespace
}  // namespace autodrive::traffic
