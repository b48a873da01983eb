// The parking planner on the Parking School's occupancy grid, its paths checked against the map's
// own obstacle polygons (not the planner's circles) and against the bicycle model's limits.
#include "examples/parking/hybrid_astar.h"

#include <gtest/gtest.h>

#include <cmath>

#include "common/test_support.h"
#include "examples/parking/tracker.h"
#include "maps/builder.h"
#include "maps/layout.h"
#include "maps/occupancy.h"

namespace autodrive::examples {
namespace {

const maps::Map& ParkingSchool() {
  static const maps::Map map = maps::Build(
      maps::LoadLayout((test::SourceDir() / "config/maps/parking_school.yaml").string()));
  return map;
}

// Points over the car's body at rear-axle pose X (its outline and inside, every 1 cm or so).
std::vector<Eigen::Vector2d> BodyPoints(const RigidTransform2& X, const HybridAStarParams& p) {
  std::vector<Eigen::Vector2d> out;
  for (int i = 0; i <= 32; ++i) {
    for (int j = 0; j <= 18; ++j) {
      out.push_back(X * Eigen::Vector2d(p.centre_ahead_m + (i / 32.0 - 0.5) * p.length_m,
                                        (j / 18.0 - 0.5) * p.width_m));
    }
  }
  return out;
}

// Even-odd rule: whether q lies inside polygon `poly`.
bool Inside(const maps::Polyline& poly, const Eigen::Vector2d& q) {
  bool in = false;
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Eigen::Vector2d& a = poly[i];
    const Eigen::Vector2d& b = poly[j];
    if ((a.y() > q.y()) != (b.y() > q.y()) &&
        q.x() < (b.x() - a.x()) * (q.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      in = !in;
    }
  }
  return in;
}

// Whether the body at X overlaps one of the map's obstacles (its footprint polygons).
bool Touches(const maps::Map& map, const RigidTransform2& X, const HybridAStarParams& p) {
  for (const Eigen::Vector2d& q : BodyPoints(X, p)) {
    for (const maps::Obstacle& o : map.obstacles) {
      if (Inside(o.footprint, q)) return true;
    }
  }
  return false;
}

void ExpectDrivable(const PlanResult& plan, const HybridAStarParams& p) {
  const double max_curvature = std::tan(p.steering_limit_rad) / p.wheelbase_m;
  for (std::size_t i = 0; i < plan.path.size(); ++i) {
    const RigidTransform2& X = plan.path[i].X_MV;
    ASSERT_FALSE(Touches(ParkingSchool(), X, p)) << "pose " << i << " touches an obstacle";
    if (i == 0) continue;
    const RigidTransform2& W = plan.path[i - 1].X_MV;
    const double ds = (X.translation() - W.translation()).norm();
    EXPECT_NEAR(ds, p.step_m, 1e-3) << "pose " << i;
    // Turning no sharper than full lock, and moving along the heading in its gear.
    EXPECT_LE(std::abs(WrapAngle(X.yaw() - W.yaw())), max_curvature * p.step_m + 1e-6);
    const Eigen::Vector2d along = (X.translation() - W.translation()) * plan.path[i].gear;
    const double mid = W.yaw() + WrapAngle(X.yaw() - W.yaw()) / 2;
    EXPECT_GT(along.dot(Eigen::Vector2d(std::cos(mid), std::sin(mid))), 0.99 * ds) << "pose " << i;
  }
}

TEST(HybridAStar, BacksIntoTheBayPastTheBoxesWithOneGearChange) {
  const HybridAStarParams p;
  const HybridAStar planner(maps::MakeOccupancyGrid(ParkingSchool(), 0.025, false), p);
  const RigidTransform2 start = RigidTransform2::FromXyYaw(0.6, 2.0, 0.0);
  const RigidTransform2 goal = RigidTransform2::FromXyYaw(3.6, 2.0, std::numbers::pi);  // nose out
  const PlanResult plan = planner.Plan(start, goal);
  ASSERT_FALSE(plan.path.empty()) << plan.failure;
  EXPECT_GE(plan.gear_changes, 1) << "facing the other way in a bay takes a reverse";
  EXPECT_EQ(plan.path.back().gear, -1) << "it backs in";
  const RigidTransform2& end = plan.path.back().X_MV;
  EXPECT_LE((end.translation() - goal.translation()).norm(), p.goal_tolerance_m);
  EXPECT_LE(std::abs(WrapAngle(end.yaw() - goal.yaw())), p.goal_tolerance_rad);
  ExpectDrivable(plan, p);
  EXPECT_GT(plan.length_m, 3.0);
}

TEST(HybridAStar, DrivesForwardRoundTheMiddleBoxWhenThatIsEnough) {
  const HybridAStarParams p;
  const HybridAStar planner(maps::MakeOccupancyGrid(ParkingSchool(), 0.025, false), p);
  const PlanResult plan = planner.Plan(RigidTransform2::FromXyYaw(0.6, 2.0, 0.0),
                                       RigidTransform2::FromXyYaw(3.5, 2.0, 0.0));
  ASSERT_FALSE(plan.path.empty()) << plan.failure;
  EXPECT_EQ(plan.gear_changes, 0);
  ExpectDrivable(plan, p);
  // The middle box stands on the straight line: the path goes round it.
  EXPECT_GT(plan.length_m, 2.9 + 0.05);
}

TEST(HybridAStar, ABodyOnABoxIsNotFreeAndAGoalInsideOneIsRefused) {
  const HybridAStarParams p;
  const HybridAStar planner(maps::MakeOccupancyGrid(ParkingSchool(), 0.025, false), p);
  // The box at (1, 1): the car's centre on it, then 0.4 m clear of it.
  EXPECT_FALSE(planner.Free(RigidTransform2::FromXyYaw(1.0 - p.centre_ahead_m, 1.0, 0.0)));
  EXPECT_FALSE(planner.BodyClear(RigidTransform2::FromXyYaw(1.0 - p.centre_ahead_m, 1.0, 0.0)));
  EXPECT_TRUE(
      Touches(ParkingSchool(), RigidTransform2::FromXyYaw(1.0 - p.centre_ahead_m, 1.0, 0.0), p))
      << "the test's own check sees the overlap too";
  EXPECT_TRUE(planner.Free(RigidTransform2::FromXyYaw(1.0 - p.centre_ahead_m, 1.45, 0.0)));
  EXPECT_FALSE(planner.Free(RigidTransform2::FromXyYaw(-0.5, 1.0, 0.0))) << "outside the map";
  const PlanResult plan = planner.Plan(RigidTransform2::FromXyYaw(0.6, 2.0, 0.0),
                                       RigidTransform2::FromXyYaw(1.0, 1.0, 0.0));
  EXPECT_TRUE(plan.path.empty());
  EXPECT_EQ(plan.failure, "the goal pose is not clear of the obstacles");
}

// A car that stopped just short of an obstacle it saw (within its margin, its body clear) can
// still plan away from it: near its start only the body must be clear.
TEST(HybridAStar, PlansAwayFromAnObstacleSeenWithinItsMargin) {
  const HybridAStarParams p;
  HybridAStar planner(maps::MakeOccupancyGrid(ParkingSchool(), 0.025, false), p);
  const RigidTransform2 start = RigidTransform2::FromXyYaw(0.6, 2.0, 0.0);
  const double front = 0.6 + p.centre_ahead_m + p.length_m / 2;
  planner.AddObstacles({Eigen::Vector2d(front + 0.05, 2.0)}, 0.01);  // 4 cm from the bumper
  EXPECT_FALSE(planner.Free(start)) << "within the margin";
  EXPECT_TRUE(planner.BodyClear(start)) << "the body itself clear";
  const PlanResult plan =
      planner.Plan(start, RigidTransform2::FromXyYaw(3.6, 2.0, std::numbers::pi));
  ASSERT_FALSE(plan.path.empty()) << plan.failure;
  ExpectDrivable(plan, p);
}

// The tracker drives a kinematic bicycle (speed 0.3 m/s per unit of throttle, the twin's Nigel
// near its cruise) along the planned path, both gears, and stops within the case study's 5 cm
// and 5 degrees of the goal without touching anything.
TEST(PathTracker, DrivesAKinematicCarAlongThePlanIntoTheBay) {
  const HybridAStarParams p;
  const HybridAStar planner(maps::MakeOccupancyGrid(ParkingSchool(), 0.025, false), p);
  const RigidTransform2 goal = RigidTransform2::FromXyYaw(3.6, 2.0, std::numbers::pi);
  RigidTransform2 X = RigidTransform2::FromXyYaw(0.6, 2.0, 0.0);
  const PlanResult plan = planner.Plan(X, goal);
  ASSERT_FALSE(plan.path.empty()) << plan.failure;
  PathTracker tracker;
  tracker.SetPath(plan.path);
  ASSERT_EQ(tracker.segments(), 2U);
  const double dt = 0.02;
  double speed = 0.0;
  bool done = false;
  int backwards = 0;
  for (int k = 0; k < 10'000 && !done; ++k) {
    const TrackCommand c = tracker.Step(X, std::abs(speed));
    done = c.done;
    // First-order speed response (0.1 s), steering at once.
    speed += (0.3 * c.throttle - speed) * dt / 0.1;
    if (speed < 0) ++backwards;
    const double delta = c.steering * p.steering_limit_rad;
    const double yaw = X.yaw() + speed * std::tan(delta) / p.wheelbase_m * dt;
    X = RigidTransform2::FromXyYaw(X.translation().x() + speed * std::cos(X.yaw()) * dt,
                                   X.translation().y() + speed * std::sin(X.yaw()) * dt, yaw);
    ASSERT_FALSE(Touches(ParkingSchool(), X, p)) << "step " << k;
  }
  ASSERT_TRUE(done) << "not at the goal: " << X.translation().transpose() << " " << X.yaw();
  EXPECT_GT(backwards, 0) << "it backed in";
  EXPECT_LE((X.translation() - goal.translation()).norm(), 0.05);
  EXPECT_LE(std::abs(WrapAngle(X.yaw() - goal.yaw())), 0.0873);
}

}  // namespace
}  // namespace autodrive::examples
