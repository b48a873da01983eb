#include "scm/core/fleet.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/dds/conversions.h"
#include "common/test_support.h"
#include "maps/map_io.h"

namespace autodrive::scm {
namespace {

using maps::Map;
using std::chrono::milliseconds;
using std::chrono::seconds;

Map LoadShipped(const std::string& name) {
  return maps::LoadMapOrLayout((test::SourceDir() / "config/maps" / (name + ".yaml")).string());
}

// The pose on `line` at arc length `s` from its start (clamped to the line), heading along it.
RigidTransform2 PoseAlong(const maps::Polyline& line, double s) {
  double walked = 0.0;
  for (std::size_t i = 1; i < line.size(); ++i) {
    const Eigen::Vector2d d = line[i] - line[i - 1];
    const double length = d.norm();
    if (walked + length >= s || i + 1 == line.size()) {
      const double t = std::clamp((s - walked) / length, 0.0, 1.0);
      const Eigen::Vector2d p = line[i - 1] + t * d;
      return RigidTransform2::FromXyYaw(p.x(), p.y(), std::atan2(d.y(), d.x()));
    }
    walked += length;
  }
  ADD_FAILURE() << "line too short";
  return {};
}

double Length(const maps::Polyline& line) {
  double s = 0.0;
  for (std::size_t i = 1; i < line.size(); ++i) s += (line[i] - line[i - 1]).norm();
  return s;
}

// The pose on `lane` `d` metres before its end (its stop line), heading along it.
RigidTransform2 BeforeStopLine(const maps::Lane& lane, double d) {
  return PoseAlong(lane.centreline, Length(lane.centreline) - d);
}

// The pose `left_m` to the left of X (in X's frame), same heading.
RigidTransform2 Shifted(const RigidTransform2& X, double left_m) {
  return X * RigidTransform2::FromXyYaw(0.0, left_m, 0.0);
}

RigidTransform2 Reversed(const RigidTransform2& X) {
  return X * RigidTransform2::FromXyYaw(0.0, 0.0, kPi);
}

VehicleObservation Obs(std::uint32_t vehicle, const RigidTransform2& X_MV, Time t,
                       PoseSource source = PoseSource::kEye) {
  VehicleObservation o;
  o.vehicle = VehicleId(vehicle);
  o.source = source;
  o.observed = t;
  o.X_MV = X_MV.ToRigidTransform3();
  return o;
}

class FleetTest : public ::testing::Test {
 protected:
  FleetTest() : map_(LoadShipped("driving_school")), fleet_(map_) {}

  const maps::Intersection& crossing() const { return map_.intersections.at(0); }
  const maps::Approach& approach(std::size_t i) const { return crossing().approaches.at(i); }
  const maps::Lane& ingress(std::size_t i) const { return map_.lane(approach(i).ingress.at(0)); }
  const maps::Lane& egress(std::size_t i) const { return map_.lane(approach(i).egress.at(0)); }

  Map map_;
  FleetRegistry fleet_;
  Time t0_ = Time(seconds(1000));
};

TEST_F(FleetTest, VehicleOnAnIngressLaneHasItsLaneApproachAndDistanceToTheStopLine) {
  ASSERT_EQ(crossing().approaches.size(), 4u);
  for (std::size_t a = 0; a < 4; ++a) {
    for (const double d : {0.0, 0.05, 0.3, 0.8}) {
      SCOPED_TRACE(ingress(a).name + " at " + std::to_string(d) + " m");
      const VehicleLocation loc = fleet_.Locate(BeforeStopLine(ingress(a), d));
      EXPECT_EQ(loc.lane, ingress(a).id);
      EXPECT_EQ(loc.intersection, crossing().id);
      EXPECT_EQ(loc.approach, approach(a).id);
      EXPECT_FALSE(loc.movement.has_value());
      ASSERT_TRUE(loc.distance_to_stop_line_m.has_value());
      EXPECT_NEAR(*loc.distance_to_stop_line_m, d, 0.01);
    }
  }
}

TEST_F(FleetTest, AnOffsetOrSlightlyTurnedVehicleStaysOnItsLane) {
  const RigidTransform2 X = BeforeStopLine(ingress(1), 0.5);
  for (const double left : {-0.15, 0.1}) {
    for (const double yaw : {-0.9, 0.0, 0.9}) {
      const RigidTransform2 X_MV = Shifted(X, left) * RigidTransform2::FromXyYaw(0, 0, yaw);
      const VehicleLocation loc = fleet_.Locate(X_MV);
      EXPECT_EQ(loc.lane, ingress(1).id) << "left " << left << " yaw " << yaw;
      ASSERT_TRUE(loc.distance_to_stop_line_m.has_value());
      EXPECT_NEAR(*loc.distance_to_stop_line_m, 0.5, 0.01);
    }
  }
}

TEST_F(FleetTest, CarPastTheRoadCentreHeadingItsOwnWayIsOnItsOwnLaneNotTheOpposingOne) {
  // 0.16 m left of its lane's centreline: 0.14 m from the opposing lane's, which is nearer.
  const maps::Lane& own = ingress(0);
  const maps::Lane& opposing = egress(0);
  const RigidTransform2 X_MV = Shifted(BeforeStopLine(own, 0.5), 0.16);
  const Eigen::Vector2d p = X_MV.translation();
  const auto nearest = maps::MapIndex(map_).NearestLane(p);
  ASSERT_TRUE(nearest.has_value());
  ASSERT_EQ(nearest->lane, opposing.id) << "the test must put the car nearer the opposing lane";

  const VehicleLocation loc = fleet_.Locate(X_MV);
  EXPECT_EQ(loc.lane, own.id);
  EXPECT_EQ(loc.approach, approach(0).id);
  ASSERT_TRUE(loc.distance_to_stop_line_m.has_value());
  EXPECT_NEAR(*loc.distance_to_stop_line_m, 0.5, 0.01);
}

TEST_F(FleetTest, CarDrivingTheOpposingLaneItsWayIsOnThatLane) {
  // On the egress lane of the same road, heading away from the intersection.
  const maps::Lane& lane = egress(0);
  const VehicleLocation loc = fleet_.Locate(PoseAlong(lane.centreline, 0.4));
  EXPECT_EQ(loc.lane, lane.id);
  EXPECT_FALSE(loc.intersection.has_value());  // egress lanes lead away from it
  EXPECT_FALSE(loc.approach.has_value());
  EXPECT_FALSE(loc.distance_to_stop_line_m.has_value());
}

TEST_F(FleetTest, WrongWayCarIsNotPutOnTheLaneItFaces) {
  // On the egress lane's centreline but facing the intersection: the ingress lane is 0.3 m
  // away (beyond its reach), the egress lane runs the other way.
  const VehicleLocation loc = fleet_.Locate(Reversed(PoseAlong(egress(0).centreline, 0.4)));
  EXPECT_EQ(loc, VehicleLocation{});
}

TEST_F(FleetTest, VehicleInTheBoxIsOnTheMovementItFollows) {
  for (const MovementId id : crossing().movements) {
    const maps::Movement& mv = map_.movement(id);
    SCOPED_TRACE(mv.name);
    const double s = 0.6 * Length(mv.path);
    const VehicleLocation loc = fleet_.Locate(PoseAlong(mv.path, s));
    EXPECT_EQ(loc.intersection, crossing().id);
    EXPECT_EQ(loc.lane, mv.from);
    EXPECT_EQ(loc.approach, mv.from_approach);
    EXPECT_EQ(loc.movement, mv.id);
    ASSERT_TRUE(loc.distance_to_stop_line_m.has_value());
    EXPECT_NEAR(*loc.distance_to_stop_line_m, -s, 0.01);
  }
}

TEST_F(FleetTest, VehicleInTheBoxAwayFromEveryPathIsInTheIntersectionOnly) {
  // Near a corner of the box: 0.28 m from the right turn's arc, 0.3 m from the straight paths.
  const Eigen::Vector2d c = crossing().centre;
  const VehicleLocation loc =
      fleet_.Locate(RigidTransform2::FromXyYaw(c.x() + 0.45, c.y() + 0.45, 0.0));
  EXPECT_EQ(loc.intersection, crossing().id);
  EXPECT_FALSE(loc.lane.has_value());
  EXPECT_FALSE(loc.movement.has_value());
}

TEST_F(FleetTest, VehicleOffTheRoadsIsNowhere) {
  EXPECT_EQ(fleet_.Locate(RigidTransform2::FromXyYaw(3.5, 3.5, 0.0)), VehicleLocation{});
  EXPECT_EQ(fleet_.Locate(RigidTransform2::FromXyYaw(-4.0, 20.0, 0.0)), VehicleLocation{});
}

TEST_F(FleetTest, StaleObservationsDisappear) {
  ASSERT_TRUE(fleet_.Observe(Obs(1, BeforeStopLine(ingress(0), 0.3), t0_)));
  ASSERT_TRUE(fleet_.Observe(Obs(2, BeforeStopLine(ingress(1), 0.3), t0_ + milliseconds(800))));
  EXPECT_EQ(fleet_.Vehicles(t0_ + milliseconds(1000)).size(), 2u);
  const auto later = fleet_.Vehicles(t0_ + milliseconds(1001));
  ASSERT_EQ(later.size(), 1u);
  EXPECT_EQ(later[0].observation.vehicle, VehicleId(2));
  EXPECT_EQ(fleet_.State(t0_ + milliseconds(1900))->vehicles._length, 0u);
  // Far in the past of the observation (a clock that went back) is not fresh either.
  EXPECT_TRUE(fleet_.Vehicles(t0_ - seconds(5)).empty());
  EXPECT_EQ(fleet_.DropStale(t0_ + milliseconds(1001)), 1u);
  EXPECT_EQ(fleet_.DropStale(t0_ + milliseconds(1001)), 0u);
  EXPECT_EQ(fleet_.Vehicles(t0_ + milliseconds(1001)).size(), 1u);
}

TEST_F(FleetTest, PrefersGroundTruthOverEyeOverOdometryWhenFresh) {
  const RigidTransform2 X = BeforeStopLine(ingress(0), 0.5);
  fleet_.Observe(Obs(4, Shifted(X, 0.02), t0_, PoseSource::kOdometry));
  fleet_.Observe(Obs(4, Shifted(X, 0.01), t0_ + milliseconds(500), PoseSource::kEye));
  fleet_.Observe(Obs(4, X, t0_ + milliseconds(900), PoseSource::kSimGroundTruth));
  const auto source_at = [&](Time now) {
    const auto v = fleet_.Vehicles(now);
    EXPECT_EQ(v.size(), 1u);
    return v.empty() ? PoseSource{} : v[0].observation.source;
  };
  EXPECT_EQ(source_at(t0_ + milliseconds(900)), PoseSource::kSimGroundTruth);
  fleet_.Observe(Obs(4, X, t0_ + milliseconds(950), PoseSource::kOdometry));
  EXPECT_EQ(source_at(t0_ + milliseconds(1000)), PoseSource::kSimGroundTruth);
  EXPECT_EQ(source_at(t0_ + milliseconds(1950)), PoseSource::kOdometry);  // the others stale
  fleet_.Observe(Obs(4, X, t0_ + milliseconds(1960), PoseSource::kEye));
  EXPECT_EQ(source_at(t0_ + milliseconds(1960)), PoseSource::kEye);
}

TEST_F(FleetTest, AVehicleWhoseHeadingIsUnknownIsPutOnTheNearestLane) {
  // A parked car seen only through its ips position: the yaw in the pose means nothing (here
  // it faces the wrong way), so only the position places it.
  const RigidTransform2 X = BeforeStopLine(ingress(1), 0.4);
  VehicleObservation o = Obs(6, Reversed(X), t0_, PoseSource::kIps);
  o.heading_known = false;
  ASSERT_TRUE(fleet_.Observe(o));
  auto v = fleet_.Vehicles(t0_);
  ASSERT_EQ(v.size(), 1u);
  EXPECT_EQ(v[0].location.lane, ingress(1).id);
  EXPECT_EQ(v[0].location.approach, approach(1).id);
  EXPECT_NEAR(*v[0].location.distance_to_stop_line_m, 0.4, 0.01);
  // With its heading taken for true it faces the wrong way and is on no lane.
  o.heading_known = true;
  o.observed = t0_ + milliseconds(10);
  ASSERT_TRUE(fleet_.Observe(o));
  v = fleet_.Vehicles(t0_ + milliseconds(10));
  ASSERT_EQ(v.size(), 1u);
  EXPECT_NE(v[0].location.lane, ingress(1).id);
}

TEST_F(FleetTest, IpsRanksBelowTheEyeAndAboveOdometry) {
  const RigidTransform2 X = BeforeStopLine(ingress(0), 0.5);
  fleet_.Observe(Obs(4, X, t0_, PoseSource::kOdometry));
  fleet_.Observe(Obs(4, X, t0_, PoseSource::kIps));
  auto v = fleet_.Vehicles(t0_);
  ASSERT_EQ(v.size(), 1u);
  EXPECT_EQ(v[0].observation.source, PoseSource::kIps);
  fleet_.Observe(Obs(4, X, t0_, PoseSource::kEye));
  v = fleet_.Vehicles(t0_);
  EXPECT_EQ(v[0].observation.source, PoseSource::kEye);
  const FleetStateMessage m = fleet_.State(t0_);
  EXPECT_EQ(dds::Elements(m->vehicles)[0].source, autodrive_msgs_msg_TrackedVehicle_Constants_EYE);
}

TEST_F(FleetTest, StateIntoReusesTheMessageAsVehiclesComeAndGo) {
  FleetStateMessage m;
  fleet_.Observe(Obs(1, BeforeStopLine(ingress(0), 0.5), t0_));
  fleet_.Observe(Obs(2, BeforeStopLine(ingress(1), 0.5), t0_));
  fleet_.StateInto(t0_, m);
  ASSERT_EQ(m->vehicles._length, 2u);
  const auto* buffer = m->vehicles._buffer;
  const char* name = dds::Elements(m->vehicles)[1].vehicle_id;
  fleet_.StateInto(t0_ + milliseconds(5), m);
  EXPECT_EQ(m->vehicles._buffer, buffer) << "same capacity: same buffer";
  EXPECT_EQ(dds::Elements(m->vehicles)[1].vehicle_id, name) << "same name: not copied again";
  // Vehicle 1 goes stale; vehicle 2 stays.
  fleet_.Observe(Obs(2, BeforeStopLine(ingress(1), 0.4), t0_ + seconds(1)));
  fleet_.StateInto(t0_ + seconds(1) + milliseconds(100), m);
  ASSERT_EQ(m->vehicles._length, 1u);
  EXPECT_EQ(dds::View(dds::Elements(m->vehicles)[0].vehicle_id), "nigel_2");
  EXPECT_EQ(dds::View(dds::Elements(m->vehicles)[0].map_lane_id), ingress(1).name);
}

TEST_F(FleetTest, OutOfOrderObservationsAreIgnoredButAClockRestartIsNot) {
  const RigidTransform2 a = BeforeStopLine(ingress(0), 0.5);
  const RigidTransform2 b = BeforeStopLine(ingress(0), 0.2);
  EXPECT_TRUE(fleet_.Observe(Obs(1, a, t0_)));
  EXPECT_FALSE(fleet_.Observe(Obs(1, b, t0_ - milliseconds(100))));
  auto v = fleet_.Vehicles(t0_);
  ASSERT_EQ(v.size(), 1u);
  EXPECT_NEAR(*v[0].location.distance_to_stop_line_m, 0.5, 0.01);
  // A simulation restarted from time 0.
  EXPECT_TRUE(fleet_.Observe(Obs(1, b, Time(seconds(1)))));
  v = fleet_.Vehicles(Time(seconds(1)));
  ASSERT_EQ(v.size(), 1u);
  EXPECT_NEAR(*v[0].location.distance_to_stop_line_m, 0.2, 0.01);
}

TEST_F(FleetTest, StateMessageCarriesEveryFieldSortedByVehicle) {
  VehicleObservation o = Obs(9, BeforeStopLine(ingress(2), 0.25), t0_, PoseSource::kEye);
  o.X_MV = RigidTransform3(o.X_MV.translation() + Eigen::Vector3d(0, 0, 0.01), o.X_MV.rotation());
  o.speed_mps = 0.4;
  o.tag = TagId(42);
  for (std::size_t i = 0; i < 36; i += 7) o.pose_covariance[i] = 1e-4;
  fleet_.Observe(o);
  fleet_.Observe(Obs(2, PoseAlong(egress(3).centreline, 0.3), t0_, PoseSource::kOdometry));
  fleet_.Observe(Obs(5, RigidTransform2::FromXyYaw(3.5, 3.5, 0.0), t0_));

  const Time now = t0_ + milliseconds(20);
  const FleetStateMessage m = fleet_.State(now);
  EXPECT_EQ(dds::FromMsg(m->header.stamp), now);
  EXPECT_EQ(dds::View(m->header.frame_id), "map");
  const auto v = dds::Elements(m->vehicles);
  ASSERT_EQ(v.size(), 3u);
  EXPECT_EQ(dds::View(v[0].vehicle_id), "nigel_2");
  EXPECT_EQ(dds::View(v[1].vehicle_id), "nigel_5");
  EXPECT_EQ(dds::View(v[2].vehicle_id), "nigel_9");

  EXPECT_EQ(v[0].source, autodrive_msgs_msg_TrackedVehicle_Constants_ODOMETRY);
  EXPECT_EQ(dds::View(v[0].map_lane_id), egress(3).name);
  EXPECT_EQ(v[0].intersection_id, 0u);
  EXPECT_EQ(v[0].tag_id, 0u);

  EXPECT_EQ(dds::View(v[1].map_lane_id), "");  // off the road network
  EXPECT_EQ(v[1].intersection_id, 0u);
  EXPECT_EQ(v[1].approach_id, 0u);
  EXPECT_EQ(v[1].distance_to_stop_line_m, 0.0);

  const auto& n9 = v[2];
  EXPECT_EQ(n9.source, autodrive_msgs_msg_TrackedVehicle_Constants_EYE);
  EXPECT_EQ(n9.tag_id, 42u);
  EXPECT_EQ(dds::FromMsg(n9.observed), t0_);
  EXPECT_TRUE(dds::FromMsg(n9.pose.pose).IsNearlyEqualTo(o.X_MV, 1e-12));
  for (std::size_t i = 0; i < 36; ++i) EXPECT_EQ(n9.pose.covariance[i], o.pose_covariance[i]);
  EXPECT_EQ(n9.twist.twist.linear.x, 0.4);
  EXPECT_EQ(dds::View(n9.map_lane_id), ingress(2).name);
  EXPECT_EQ(n9.intersection_id, crossing().id.value());
  EXPECT_EQ(n9.approach_id, approach(2).id.value());
  EXPECT_NEAR(n9.distance_to_stop_line_m, 0.25, 0.01);
}

TEST_F(FleetTest, DetectorZoneIsOccupiedExactlyWhenAFreshCarIsInItsRange) {
  const maps::Lane& lane = ingress(3);
  const DetectorZone zone{lane.id, 0.0, 0.4};
  const auto occupied_with_car_at = [&](const RigidTransform2& X, Time now) {
    FleetRegistry fleet(map_);
    fleet.Observe(Obs(1, X, t0_));
    return fleet.Occupied(zone, now);
  };
  EXPECT_TRUE(occupied_with_car_at(BeforeStopLine(lane, 0.39), t0_));
  EXPECT_FALSE(occupied_with_car_at(BeforeStopLine(lane, 0.41), t0_));
  EXPECT_TRUE(occupied_with_car_at(BeforeStopLine(lane, 0.01), t0_));
  // Just past the line, in the box on a movement from this lane: distance is negative.
  const maps::Movement& mv = map_.movement(lane.movements_out.at(0));
  EXPECT_FALSE(occupied_with_car_at(PoseAlong(mv.path, 0.02), t0_));
  // Another lane's car at the same distance.
  EXPECT_FALSE(occupied_with_car_at(BeforeStopLine(ingress(0), 0.2), t0_));
  // Stale.
  EXPECT_FALSE(occupied_with_car_at(BeforeStopLine(lane, 0.2), t0_ + milliseconds(1001)));
  EXPECT_TRUE(occupied_with_car_at(BeforeStopLine(lane, 0.2), t0_ + milliseconds(1000)));

  // A zone straddling the line sees the car just past it.
  FleetRegistry fleet(map_);
  fleet.Observe(Obs(1, PoseAlong(mv.path, 0.05), t0_));
  EXPECT_TRUE(fleet.Occupied({lane.id, -0.1, 0.1}, t0_));
  EXPECT_FALSE(fleet.Occupied({lane.id, -0.04, 0.1}, t0_));
}

TEST_F(FleetTest, DetectorZoneMustBeAnIngressLaneAndARange) {
  EXPECT_EQ(test::ErrorMessage([&] {
              (void)fleet_.Occupied({LaneId(999), 0, 1}, t0_);
            }),
            "detector zone on LaneId(999), which is not in map \"driving_school\" (it has " +
                std::to_string(map_.lanes.size()) + " lanes)");
  EXPECT_EQ(test::ErrorMessage([&] {
              (void)fleet_.Occupied({egress(0).id, 0, 1}, t0_);
            }),
            "detector zone on lane " + egress(0).name +
                ", which is not an ingress lane of an intersection (no stop line to measure "
                "from)");
  EXPECT_EQ(test::ErrorMessage([&] {
              (void)fleet_.Occupied({ingress(0).id, 0.5, 0.1}, t0_);
            }),
            "detector zone on lane " + ingress(0).name + " has an empty range [0.5, 0.1] m");
}

TEST_F(FleetTest, RefusesBadObservationsAndParameters) {
  VehicleObservation o = Obs(3, BeforeStopLine(ingress(0), 0.3), t0_);
  o.speed_mps = std::nan("");
  EXPECT_EQ(test::ErrorMessage([&] { fleet_.Observe(o); }),
            "an observation of nigel_3 has speed nan");
  o.speed_mps = 0;
  o.pose_covariance[35] = INFINITY;
  EXPECT_EQ(test::ErrorMessage([&] { fleet_.Observe(o); }),
            "an observation of nigel_3 has covariance[35] = inf");
  o.pose_covariance[35] = 0;
  o.source = static_cast<PoseSource>(4);
  EXPECT_EQ(test::ErrorMessage([&] { fleet_.Observe(o); }),
            "an observation of nigel_3 has an unknown source 4 (expected 1 eye, 2 sim ground "
            "truth, 3 odometry or 5 ips)");

  FleetRegistryParams params;
  params.staleness = Duration::zero();
  EXPECT_EQ(test::ErrorMessage([&] { FleetRegistry fleet(map_, params); }),
            "staleness_s must be > 0, got 0");
  params = {};
  params.max_heading_error_rad = 4;
  EXPECT_EQ(test::ErrorMessage([&] { FleetRegistry fleet(map_, params); }),
            "max_heading_error_rad must be in [0, pi], got 4");
}

TEST(FleetRegistryParams, RoundTripsThroughYamlAndRefusesBadValuesWithTheirKey) {
  FleetRegistryParams params;
  params.staleness = milliseconds(250);
  params.lane_margin_m = 0.08;
  params.max_heading_error_rad = 0.5;
  EXPECT_EQ(config::LoadString<FleetRegistryParams>(config::SaveString(params)), params);
  const std::string error = test::ErrorMessage<ConfigError>(
      [] { (void)config::LoadString<FleetRegistryParams>("staleness_s: -1\n", "fleet.yaml"); });
  EXPECT_NE(error.find("fleet.yaml:1:1"), std::string::npos) << error;
  EXPECT_NE(error.find("staleness_s must be > 0, got -1"), std::string::npos) << error;
}

// ---- Background traffic (SUMO's vehicles) ------------------------------------------------

// A background car of length `length_m` whose centre is at `X`, on the lane or movement `name`.
TrafficObservation Car(std::string_view id, std::string_view name, const RigidTransform2& X,
                       double length_m = 0.2) {
  return TrafficObservation{id, name, X.translation(), length_m};
}

TEST_F(FleetTest, BackgroundCarWhoseFootprintReachesIntoTheZoneOccupiesIt) {
  const maps::Lane& lane = ingress(3);
  const DetectorZone zone{lane.id, 0.0, 0.4};
  const maps::Movement& mv = map_.movement(lane.movements_out.at(0));
  // Its centre's distance to the stop line -> occupied, for a 0.2 m car (0.1 m either side).
  const auto occupied_with_car = [&](std::string_view name, const RigidTransform2& X) {
    FleetRegistry fleet(map_);
    const TrafficObservation car = Car("veh0", name, X);
    const TrafficUpdate u = fleet.ObserveTraffic(t0_, std::span(&car, 1));
    EXPECT_EQ(u.recorded, 1u);
    return fleet.Occupied(zone, t0_);
  };
  EXPECT_TRUE(occupied_with_car(lane.name, BeforeStopLine(lane, 0.2)));
  EXPECT_TRUE(occupied_with_car(lane.name, BeforeStopLine(lane, 0.49))) << "its front is in";
  EXPECT_FALSE(occupied_with_car(lane.name, BeforeStopLine(lane, 0.51)));
  EXPECT_TRUE(occupied_with_car(lane.name, BeforeStopLine(lane, 0.01)));
  // Past the line on a movement from this lane: its back is still over the zone ...
  EXPECT_TRUE(occupied_with_car(mv.name, PoseAlong(mv.path, 0.09)));
  // ... until it has left it.
  EXPECT_FALSE(occupied_with_car(mv.name, PoseAlong(mv.path, 0.11)));
  // On another lane at the same distance, and on the egress lane of the same road.
  EXPECT_FALSE(occupied_with_car(ingress(0).name, BeforeStopLine(ingress(0), 0.2)));
  EXPECT_FALSE(occupied_with_car(egress(3).name, PoseAlong(egress(3).centreline, 0.2)));
}

TEST_F(FleetTest, BackgroundCarsAreNotPartOfTheFleetButAreCountedOnTheirApproach) {
  const std::vector<TrafficObservation> cars = {
      Car("a", ingress(0).name, BeforeStopLine(ingress(0), 0.3)),
      Car("b", ingress(0).name, BeforeStopLine(ingress(0), 0.7)),
      Car("c", map_.movement(ingress(2).movements_out.at(0)).name,
          PoseAlong(map_.movement(ingress(2).movements_out.at(0)).path, 0.2)),
      Car("d", egress(1).name, PoseAlong(egress(1).centreline, 0.3)),  // leaving: no approach
  };
  const TrafficUpdate u = fleet_.ObserveTraffic(t0_, cars);
  EXPECT_EQ(u.recorded, 4u);
  fleet_.Observe(Obs(1, BeforeStopLine(ingress(0), 0.5), t0_));
  EXPECT_EQ(fleet_.BackgroundVehicles(t0_), 4u);
  ASSERT_EQ(fleet_.Vehicles(t0_).size(), 1u) << "the fleet is the lab's";
  EXPECT_EQ(fleet_.State(t0_)->vehicles._length, 1u);
  const std::vector<ApproachCount> counts = fleet_.ApproachCounts(crossing().id, t0_);
  ASSERT_EQ(counts.size(), 4u);
  EXPECT_EQ(counts[0], (ApproachCount{approach(0).id, 1, 2}));
  EXPECT_EQ(counts[1], (ApproachCount{approach(1).id, 0, 0}));
  EXPECT_EQ(counts[2], (ApproachCount{approach(2).id, 0, 1}));
  EXPECT_EQ(counts[3], (ApproachCount{approach(3).id, 0, 0}));
  EXPECT_TRUE(fleet_.ApproachCounts(IntersectionId(99), t0_).empty());
}

TEST_F(FleetTest, BackgroundCarNotRefreshedWithinTheStalenessStopsCounting) {
  const maps::Lane& lane = ingress(1);
  const DetectorZone zone{lane.id, 0.0, 0.6};
  const TrafficObservation parked = Car("parked", lane.name, BeforeStopLine(lane, 0.3));
  const TrafficObservation other = Car("other", ingress(0).name, BeforeStopLine(ingress(0), 0.3));
  ASSERT_EQ(fleet_.ObserveTraffic(t0_, std::span(&parked, 1)).recorded, 1u);
  EXPECT_TRUE(fleet_.Occupied(zone, t0_ + milliseconds(1000)));
  EXPECT_FALSE(fleet_.Occupied(zone, t0_ + milliseconds(1001)));
  EXPECT_EQ(fleet_.BackgroundVehicles(t0_ + milliseconds(1001)), 0u);
  // Messages keep coming without it: it stays until it is stale, then it is forgotten.
  EXPECT_EQ(fleet_.ObserveTraffic(t0_ + milliseconds(500), std::span(&other, 1)).dropped, 0u);
  EXPECT_TRUE(fleet_.Occupied(zone, t0_ + milliseconds(500)));
  EXPECT_EQ(fleet_.BackgroundVehicles(t0_ + milliseconds(500)), 2u);
  const TrafficUpdate later = fleet_.ObserveTraffic(t0_ + milliseconds(1100), std::span(&other, 1));
  EXPECT_EQ(later.dropped, 1u);
  EXPECT_FALSE(fleet_.Occupied(zone, t0_ + milliseconds(1100)));
  EXPECT_EQ(fleet_.BackgroundVehicles(t0_ + milliseconds(1100)), 1u);
  // DropStale forgets the rest.
  EXPECT_EQ(fleet_.DropStale(t0_ + seconds(5)), 1u);
  EXPECT_EQ(fleet_.BackgroundVehicles(t0_ + milliseconds(1100)), 0u);
}

TEST_F(FleetTest, BackgroundObjectsElsewhereOutOfOrderOrMalformedAreNotRecorded) {
  const RigidTransform2 X = BeforeStopLine(ingress(0), 0.3);
  const std::string long_id(FleetRegistry::kMaxTrafficIdBytes + 1, 'x');
  const std::vector<TrafficObservation> batch = {
      Car("ok", ingress(0).name, X),
      Car("nowhere", "", X),              // on no lane
      Car("other_map", "r9c9:W>E:0", X),  // another district's lane
      Car("", ingress(0).name, X),        // no id
      Car(long_id, ingress(0).name, X),   // id too long
      TrafficObservation{"nan", ingress(0).name, Eigen::Vector2d(std::nan(""), 1.0), 0.2},
      Car("negative", ingress(0).name, X, -0.1),
      Car("inf", ingress(0).name, X, INFINITY),
  };
  const TrafficUpdate u = fleet_.ObserveTraffic(t0_, batch);
  EXPECT_EQ(u.recorded, 1u);
  EXPECT_EQ(u.elsewhere, 2u);
  EXPECT_EQ(u.refused, 5u);
  EXPECT_EQ(fleet_.BackgroundVehicles(t0_), 1u);
  // An older message of the same car (out of order) changes nothing.
  const TrafficObservation moved = Car("ok", ingress(1).name, BeforeStopLine(ingress(1), 0.3));
  EXPECT_EQ(fleet_.ObserveTraffic(t0_ - milliseconds(100), std::span(&moved, 1)).ignored, 1u);
  EXPECT_TRUE(fleet_.Occupied({ingress(0).id, 0.0, 0.6}, t0_));
  EXPECT_FALSE(fleet_.Occupied({ingress(1).id, 0.0, 0.6}, t0_));
  // A restarted simulation (a stamp far in the past) replaces it.
  EXPECT_EQ(fleet_.ObserveTraffic(Time(seconds(1)), std::span(&moved, 1)).recorded, 1u);
  EXPECT_TRUE(fleet_.Occupied({ingress(1).id, 0.0, 0.6}, Time(seconds(1))));
  EXPECT_FALSE(fleet_.Occupied({ingress(0).id, 0.0, 0.6}, Time(seconds(1))));
  // Driving off this map (onto another district's lane): forgotten at once.
  const TrafficObservation gone = Car("ok", "r9c9:W>E:0", X);
  EXPECT_EQ(fleet_.ObserveTraffic(Time(seconds(1)), std::span(&gone, 1)).elsewhere, 1u);
  EXPECT_EQ(fleet_.BackgroundVehicles(Time(seconds(1))), 0u);
  EXPECT_FALSE(fleet_.Occupied({ingress(1).id, 0.0, 0.6}, Time(seconds(1))));
}

TEST(FleetTraffic, NewVehiclesBeyondTheCapacityAreRefused) {
  const Map map = LoadShipped("driving_school");
  FleetRegistry fleet(map);
  const maps::Lane& lane = map.lane(map.intersections[0].approaches[0].ingress[0]);
  std::vector<std::string> ids;
  for (std::size_t i = 0; i < FleetRegistry::kMaxTrafficVehicles + 10; ++i) {
    ids.push_back("v" + std::to_string(i));
  }
  std::vector<TrafficObservation> batch;
  for (const auto& id : ids) batch.push_back(Car(id, lane.name, BeforeStopLine(lane, 0.3)));
  const Time t(seconds(100));
  const TrafficUpdate u = fleet.ObserveTraffic(t, batch);
  EXPECT_EQ(u.recorded, FleetRegistry::kMaxTrafficVehicles);
  EXPECT_EQ(u.refused, 10u);
  EXPECT_EQ(fleet.BackgroundVehicles(t), FleetRegistry::kMaxTrafficVehicles);
  // Known vehicles are still refreshed.
  EXPECT_EQ(fleet.ObserveTraffic(t + milliseconds(100), std::span(batch.data(), 5)).recorded, 5u);
}

TEST(FleetSmallTown, LaneBetweenTwoIntersectionsIsOnTheApproachOfTheOneItEnters) {
  // r2c1:E>W:0 leaves "centre" by its west approach and enters "west_t" by its east approach.
  const Map town = LoadShipped("small_town");
  const FleetRegistry fleet(town);
  const maps::Lane* lane = nullptr;
  for (const auto& l : town.lanes) {
    if (l.name == "r2c1:E>W:0") lane = &l;
  }
  ASSERT_NE(lane, nullptr);
  ASSERT_TRUE(lane->ingress_of.has_value());
  ASSERT_TRUE(lane->egress_of.has_value());
  const maps::Intersection& west_t = town.intersection(*lane->ingress_of);
  ASSERT_EQ(west_t.name, "west_t");
  const VehicleLocation loc = fleet.Locate(BeforeStopLine(*lane, 0.3));
  EXPECT_EQ(loc.lane, lane->id);
  EXPECT_EQ(loc.intersection, west_t.id);
  EXPECT_EQ(loc.approach, ApproachId(1));  // east
  EXPECT_NEAR(*loc.distance_to_stop_line_m, 0.3, 0.01);
  EXPECT_EQ(lane->ingress_approach, ApproachId(1));
  // The intersection it leaves, by its west approach.
  ASSERT_EQ(town.intersection(*lane->egress_of).name, "centre");
  EXPECT_EQ(lane->egress_approach, ApproachId(3));

  // A background car there counts on west_t's east approach, and not on the centre's.
  FleetRegistry traffic(town);
  const TrafficObservation car = Car("flow.1", lane->name, BeforeStopLine(*lane, 0.3));
  ASSERT_EQ(traffic.ObserveTraffic(Time(seconds(10)), std::span(&car, 1)).recorded, 1u);
  EXPECT_TRUE(traffic.Occupied({lane->id, 0.0, 0.4}, Time(seconds(10))));
  std::size_t on_west_t = 0;
  for (const auto& c : traffic.ApproachCounts(west_t.id, Time(seconds(10)))) {
    on_west_t += c.background;
    if (c.background > 0) {
      EXPECT_EQ(c.approach, ApproachId(1));
    }
  }
  EXPECT_EQ(on_west_t, 1u);
  for (const auto& c : traffic.ApproachCounts(*lane->egress_of, Time(seconds(10)))) {
    EXPECT_EQ(c.background, 0u) << "approach " << c.approach;
  }
}

// Cross-check against the map's own geometry: random points near every lane of both shipped
// maps, offset sideways and turned by less than the heading limit, come back on that lane with
// the arc length the point was made from.
TEST(FleetCrossCheck, RandomPointsNearLanesAreLocatedOnThem) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> side(-0.12, 0.12), turn(-0.9, 0.9);
  for (const std::string name : {"driving_school", "small_town"}) {
    const Map map = LoadShipped(name);
    const FleetRegistry fleet(map);
    int checked = 0;
    for (const auto& lane : map.lanes) {
      const double length = Length(lane.centreline);
      std::uniform_real_distribution<double> along(0.05, length - 0.05);
      for (int k = 0; k < 5 * test::SoakFactor(); ++k) {
        const double s = along(rng);
        const RigidTransform2 X = Shifted(PoseAlong(lane.centreline, s), side(rng)) *
                                  RigidTransform2::FromXyYaw(0, 0, turn(rng));
        const VehicleLocation loc = fleet.Locate(X);
        ASSERT_EQ(loc.lane, lane.id) << name << " " << lane.name << " at " << s << ": " << X;
        if (lane.ingress_of) {
          ASSERT_TRUE(loc.distance_to_stop_line_m.has_value());
          // Sideways offsets on a curve shift the nearest point along it a little.
          EXPECT_NEAR(*loc.distance_to_stop_line_m, length - s, 0.03) << lane.name;
        }
        ++checked;
      }
    }
    EXPECT_GT(checked, 100);
  }
}

// Cross-check of the placing of background cars (on coarse copies of the lines) against the
// map's own lines: a car of no length made at arc length s along an ingress lane or a movement
// of both shipped maps is within 2 mm of the distance to the stop line the map gives.
TEST(FleetCrossCheck, BackgroundCarsAreWhereTheMapsLinesPutThem) {
  std::mt19937 rng(11);
  for (const std::string name : {"driving_school", "small_town"}) {
    const Map map = LoadShipped(name);
    FleetRegistry fleet(map);
    const Time t(seconds(100));
    int checked = 0;
    const auto check = [&](const std::string& place, const maps::Polyline& line, LaneId lane,
                           bool movement) {
      const double length = Length(line);
      std::uniform_real_distribution<double> along(0.0, length);
      for (int k = 0; k < 5 * test::SoakFactor(); ++k) {
        const double s = along(rng);
        const double d = movement ? -s : length - s;
        const TrafficObservation car{"car", place, PoseAlong(line, s).translation(), 0.0};
        ASSERT_EQ(fleet.ObserveTraffic(t, std::span(&car, 1)).recorded, 1u);
        EXPECT_TRUE(fleet.Occupied({lane, d - 0.002, d + 0.002}, t)) << place << " at " << s;
        EXPECT_FALSE(fleet.Occupied({lane, d + 0.004, d + 0.05}, t)) << place << " at " << s;
        EXPECT_FALSE(fleet.Occupied({lane, d - 0.05, d - 0.004}, t)) << place << " at " << s;
        ++checked;
      }
    };
    for (const auto& lane : map.lanes) {
      if (lane.ingress_of) check(lane.name, lane.centreline, lane.id, false);
    }
    for (const auto& mv : map.movements) check(mv.name, mv.path, mv.from, true);
    EXPECT_GE(checked, 80);  // the Driving School's 4 ingress lanes and 12 movements, 5 each
  }
}

}  // namespace
}  // namespace autodrive::scm
