// Lab cars into SUMO and out of it, and where their fronts go, in process: the small town's
// network (exported, no SUMO running) and a scripted SUMO that records what it is told.
#include "traffic/lab_placement.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "traffic/internal/scripted_sumo.h"
#include "traffic/internal/small_town.h"
#include "traffic/network.h"
#include "traffic/sumo_frame.h"

#include "common/test_support.h"
#include "scm/core/city.h"

namespace autodrive::traffic {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

using internal::SmallTown;

MonoTime At(Duration d) { return MonoTime{} + d; }

constexpr double kNigelSumo = 4.452;  // SUMO metres

class LabCarPlacementTest : public ::testing::Test {
 protected:
  LabCarPlacementTest()
      : dir_("traffic_lab_placement_test"),
        network_(SmallTown().map, dir_.path() / "network", 0.25),
        cache_(sumo_),
        placement_(network_, LabCarsConfig{}, kNigelSumo) {
    sumo_.types[network_.files().vehicle_type] = SumoTypeSize{kNigelSumo, 2.45, 3.6, "passenger"};
    // The longest lane that leads into no intersection: a car in its middle is on it.
    lane_ = &SmallTown().map.lanes.front();
    for (const maps::Lane& l : SmallTown().map.lanes) {
      if (l.length_m > lane_->length_m && l.ingress_of == std::nullopt) lane_ = &l;
    }
  }
  // A car `along` metres into the lane, `left` metres left of it, turned `turn` rad off it.
  LabCarPose OnLane(double along, double left = 0.0, double turn = 0.0) const {
    const auto [p, direction] = PointAlong(lane_->centreline, along);
    const Eigen::Vector2d normal(-std::sin(direction), std::cos(direction));
    return LabCarPose{"nigel_1", p + normal * left, direction + turn, 0.0};
  }

  test::TempDir dir_;
  TrafficNetwork network_;
  internal::ScriptedSumo sumo_;
  SumoCache cache_;
  LabCarPlacement placement_;
  const maps::Lane* lane_ = nullptr;
};

TEST_F(LabCarPlacementTest, ACarOnALaneEntersSumoOnceAndLeavesItWhenStaleThenComesBack) {
  const LabCarPose car = OnLane(lane_->length_m / 2);
  placement_.Place({car}, At(seconds(0)), sumo_);
  const std::string edge = network_.EdgeOfLane(lane_->name);
  const std::string type = network_.files().vehicle_type;
  EXPECT_EQ(sumo_.calls, (std::vector<std::string>{"AddRoute r_nigel_1 " + edge,
                                                   "AddVehicle nigel_1 r_nigel_1 " + type + " base",
                                                   "SetSpeedMode nigel_1"}));
  EXPECT_EQ(placement_.placed(), 1);
  EXPECT_TRUE(placement_.IsLab("nigel_1"));
  sumo_.calls.clear();
  placement_.Place({car}, At(milliseconds(500)), sumo_);
  placement_.Place({}, At(milliseconds(1500)), sumo_);
  EXPECT_TRUE(sumo_.calls.empty()) << "heard from 1 s ago: it stays where it was";
  EXPECT_EQ(placement_.placed(), 1);
  placement_.Place({}, At(milliseconds(1550)), sumo_);
  EXPECT_EQ(sumo_.calls, std::vector<std::string>{"Remove nigel_1"});
  EXPECT_EQ(placement_.placed(), 0);
  sumo_.calls.clear();
  placement_.Place({car}, At(seconds(2)), sumo_);
  ASSERT_EQ(sumo_.calls.size(), 3u);
  EXPECT_EQ(sumo_.calls[1], "AddVehicle nigel_1#1 r_nigel_1#1 " + type + " base")
      << "a new SUMO id each time it comes back";
  EXPECT_TRUE(placement_.IsLab("nigel_1#1"));
  EXPECT_TRUE(placement_.IsLab("nigel_1"));
}

TEST_F(LabCarPlacementTest, ACarOffTheRoadStaysOutOfSumo) {
  placement_.Place({LabCarPose{"nigel_1", Eigen::Vector2d(-50.0, -50.0), 0.0, 0.0}}, At(seconds(0)),
                   sumo_);
  EXPECT_TRUE(sumo_.calls.empty());
  EXPECT_EQ(placement_.placed(), 0);
  EXPECT_TRUE(placement_.InSumo().empty());
}

TEST_F(LabCarPlacementTest, ACarOnALaneIsMovedWithItsFrontBesideItsOwnSumoLane) {
  // Off its centreline and turned: SUMO is still given its front beside its own lane, named.
  for (const double left : {0.0, 0.03, -0.05}) {
    for (const double turn : {0.0, 0.3, -0.4}) {
      LabCarPlacement placement(network_, LabCarsConfig{}, kNigelSumo);
      const LabCarPose car = OnLane(lane_->length_m / 2, left, turn);
      placement.Place({car}, At(seconds(0)), sumo_);
      const std::vector<LabCarPose>& in = placement.InSumo();
      ASSERT_EQ(in.size(), 1u);
      placement.claims().Update(in, [](MovementId) { return true; });
      sumo_.moves.clear();
      placement.Move(SumoTime{}, cache_);
      ASSERT_EQ(sumo_.moves.size(), 1u);
      const internal::ScriptedSumo::Move& m = sumo_.moves.front();
      const maps::SumoLaneRef& sumo_lane = network_.files().lane_pieces.at(lane_->id).front();
      EXPECT_EQ(m.edge, sumo_lane.edge) << left << " " << turn;
      EXPECT_EQ(m.lane, sumo_lane.index);
      EXPECT_FALSE(m.keep_route);
      EXPECT_NEAR(m.angle_deg, SumoAngleFromYaw(car.yaw_rad), 1e-9);
      const Eigen::Vector2d at(m.x / network_.scale(), m.y / network_.scale());
      const PolylinePoint q = NearestOnPolyline(lane_->centreline, at);
      EXPECT_LE(q.distance_m, lane_->width_m / 2) << "beside its lane";
      // Its front: body centre ahead of the origin, and half the car.
      const Eigen::Vector2d heading(std::cos(car.yaw_rad), std::sin(car.yaw_rad));
      const Eigen::Vector2d front =
          car.position + heading * (0.07077 + kNigelSumo / network_.scale() / 2);
      EXPECT_NEAR(q.along_m, NearestOnPolyline(lane_->centreline, front).along_m, 1e-6);
    }
  }
}

TEST_F(LabCarPlacementTest, SumoEndingALabCarsTripIsAMissAndItGoesInAgain) {
  placement_.Place({OnLane(lane_->length_m / 2)}, At(seconds(0)), sumo_);
  EXPECT_FALSE(placement_.Arrived("bg_3", SumoTime{}));
  EXPECT_TRUE(placement_.Arrived("nigel_1", SumoTime{}));
  EXPECT_EQ(placement_.misses(), 1);
  sumo_.calls.clear();
  placement_.Place({OnLane(lane_->length_m / 2)}, At(milliseconds(50)), sumo_);
  ASSERT_EQ(sumo_.calls.size(), 3u);
  EXPECT_EQ(sumo_.calls[0].rfind("AddRoute r_nigel_1#1 ", 0), 0u) << sumo_.calls[0];
}

}  // namespace
}  // namespace autodrive::traffic
