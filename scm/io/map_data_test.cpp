#include "scm/io/map_data.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "common/test_support.h"
#include "maps/map_io.h"
#include "maps/mesh.h"

namespace autodrive::scm {
namespace {

using maps::Map;

Map LoadShipped(const std::string& name) {
  return maps::LoadMapOrLayout((test::SourceDir() / "config/maps" / (name + ".yaml")).string());
}

// One signal group per approach of every signalised intersection: the movements from that
// approach and the head that faces it; ids 1, 2, ... in approach order.
SignalGroupAssignment GroupPerApproach(const Map& map) {
  SignalGroupAssignment out;
  for (const auto& x : map.intersections) {
    if (x.control != maps::Control::kSignal) continue;
    auto& groups = out[x.id];
    for (const auto& a : x.approaches) {
      SignalGroupInfo g;
      g.id = SignalGroupId(static_cast<std::uint32_t>(groups.size() + 1));
      g.name = std::string(ApproachName(a.side)) + "_approach";
      for (const MovementId m : x.movements) {
        if (map.movement(m).from_approach == a.id) g.movements.push_back(m);
      }
      for (const SignalHeadId h : x.signal_heads) {
        if (map.signal_heads[h.value() - 1].approach == a.id) g.heads.push_back(h);
      }
      groups.push_back(g);
    }
  }
  return out;
}

Eigen::Vector2d Xy(const msg::Point& p) { return {p.x, p.y}; }

class MapDataTest : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    map_ = LoadShipped(GetParam());
    groups_ = GroupPerApproach(map_);
    message_ = BuildMapData(map_, "test_city", groups_, 7);
  }
  Map map_;
  SignalGroupAssignment groups_;
  MapDataMessage message_;
};

TEST_P(MapDataTest, HasEveryIntersectionApproachLaneAndMovementOfTheMap) {
  EXPECT_EQ(dds::View(message_->header.frame_id), "map");
  EXPECT_EQ(dds::View(message_->city), "test_city");
  EXPECT_EQ(dds::View(message_->map_name), map_.name);
  EXPECT_EQ(message_->revision, 7u);
  const auto xs = dds::Elements(message_->intersections);
  ASSERT_EQ(xs.size(), map_.intersections.size());
  for (std::size_t i = 0; i < xs.size(); ++i) {
    const auto& m = xs[i];
    const maps::Intersection& x = map_.intersections[i];
    SCOPED_TRACE(x.name);
    EXPECT_EQ(m.intersection_id, x.id.value());
    EXPECT_EQ(dds::View(m.name), x.name);
    EXPECT_EQ(m.revision, 7u);
    EXPECT_DOUBLE_EQ(m.ref_point.x, x.centre.x());
    EXPECT_DOUBLE_EQ(m.ref_point.y, x.centre.y());
    EXPECT_DOUBLE_EQ(m.ref_point.z, maps::TerrainHeight(map_, x.centre.x(), x.centre.y()));
    const std::uint8_t control = x.control == maps::Control::kSignal
                                     ? autodrive_msgs_msg_MapIntersection_Constants_SIGNALISED
                                 : x.control == maps::Control::kStop
                                     ? autodrive_msgs_msg_MapIntersection_Constants_STOP_CONTROLLED
                                     : autodrive_msgs_msg_MapIntersection_Constants_UNCONTROLLED;
    EXPECT_EQ(m.control, control);

    ASSERT_EQ(dds::Elements(m.approaches).size(), x.approaches.size());
    std::size_t ingress = 0, egress = 0;
    for (std::size_t k = 0; k < x.approaches.size(); ++k) {
      const auto& a = dds::Elements(m.approaches)[k];
      EXPECT_EQ(a.approach_id, x.approaches[k].id.value());
      EXPECT_EQ(dds::View(a.name), ApproachName(x.approaches[k].side));
      EXPECT_DOUBLE_EQ(a.heading_rad, x.approaches[k].ingress_heading_rad);
      ingress += x.approaches[k].ingress.size();
      egress += x.approaches[k].egress.size();
    }
    std::size_t in_msg = 0, out_msg = 0, connections = 0;
    for (const auto& lane : dds::Elements(m.lanes)) {
      if (lane.direction == autodrive_msgs_msg_MapLane_Constants_INGRESS) ++in_msg;
      if (lane.direction == autodrive_msgs_msg_MapLane_Constants_EGRESS) ++out_msg;
      connections += lane.connections._length;
    }
    EXPECT_EQ(in_msg, ingress);
    EXPECT_EQ(out_msg, egress);
    EXPECT_EQ(connections, x.movements.size());
  }
}

TEST_P(MapDataTest, LaneIdsAreUniqueFromOneAndNameTheMapsLanes) {
  for (const auto& x : dds::Elements(message_->intersections)) {
    std::set<std::uint32_t> ids;
    for (const auto& lane : dds::Elements(x.lanes)) {
      EXPECT_TRUE(ids.insert(lane.lane_id).second) << "lane id " << lane.lane_id << " twice";
      const maps::Lane* map_lane = nullptr;
      for (const auto& l : map_.lanes) {
        if (l.name == dds::View(lane.map_lane_id)) map_lane = &l;
      }
      ASSERT_NE(map_lane, nullptr) << dds::View(lane.map_lane_id);
      const bool ingress = lane.direction == autodrive_msgs_msg_MapLane_Constants_INGRESS;
      EXPECT_EQ(ingress ? map_lane->ingress_of : map_lane->egress_of,
                IntersectionId(x.intersection_id));
      // The approach that lists the lane in the map's intersection, which is also the lane's
      // own ingress or egress approach (a lane between two intersections has one of each).
      std::uint32_t approach = 0;
      for (const auto& a : map_.intersection(IntersectionId(x.intersection_id)).approaches) {
        const auto& list = ingress ? a.ingress : a.egress;
        if (std::find(list.begin(), list.end(), map_lane->id) != list.end()) {
          approach = a.id.value();
        }
      }
      EXPECT_EQ(lane.approach_id, approach) << map_lane->name;
      const auto own = ingress ? map_lane->ingress_approach : map_lane->egress_approach;
      EXPECT_EQ(own, ApproachId(approach)) << map_lane->name;
      EXPECT_FLOAT_EQ(lane.width_m, static_cast<float>(map_lane->width_m));
      const auto c = dds::Elements(lane.centreline);
      ASSERT_GE(c.size(), 2u);
      EXPECT_EQ(Xy(c.front()), map_lane->centreline.front());
      EXPECT_EQ(Xy(c.back()), map_lane->centreline.back());
    }
    ASSERT_FALSE(ids.empty());
    EXPECT_EQ(*ids.begin(), 1u);
    EXPECT_EQ(*ids.rbegin(), ids.size());
  }
}

TEST_P(MapDataTest, IngressLanesOfControlledIntersectionsEndAtTheirStopLines) {
  for (const auto& x : dds::Elements(message_->intersections)) {
    for (const auto& lane : dds::Elements(x.lanes)) {
      const bool ingress = lane.direction == autodrive_msgs_msg_MapLane_Constants_INGRESS;
      if (!ingress || x.control == autodrive_msgs_msg_MapIntersection_Constants_UNCONTROLLED) {
        EXPECT_FALSE(lane.has_stop_line) << dds::View(lane.map_lane_id);
        continue;
      }
      ASSERT_TRUE(lane.has_stop_line) << dds::View(lane.map_lane_id);
      const Eigen::Vector2d left = Xy(lane.stop_line_left);
      const Eigen::Vector2d right = Xy(lane.stop_line_right);
      const Eigen::Vector2d end = Xy(dds::Elements(lane.centreline).back());
      EXPECT_NEAR(((left + right) / 2 - end).norm(), 0.0, 1e-12);
      EXPECT_NEAR((left - right).norm(), lane.width_m, 1e-6);
      // Left is on the left of the direction of travel.
      const auto c = dds::Elements(lane.centreline);
      const Eigen::Vector2d d = end - Xy(c[c.size() - 2]);
      EXPECT_GT(d.x() * (left - end).y() - d.y() * (left - end).x(), 0.0);
    }
  }
}

TEST_P(MapDataTest, ConnectionsCarryTheAssignedSignalGroupAndJoinTheirLanes) {
  for (const auto& x : dds::Elements(message_->intersections)) {
    const IntersectionId xid(x.intersection_id);
    std::map<std::uint32_t, const msg::MapLane*> by_id;
    for (const auto& lane : dds::Elements(x.lanes)) by_id[lane.lane_id] = &lane;
    for (const auto& lane : dds::Elements(x.lanes)) {
      for (const auto& c : dds::Elements(lane.connections)) {
        const maps::Movement& mv = map_.movement(MovementId(c.movement_id));
        SCOPED_TRACE(mv.name);
        EXPECT_EQ(mv.intersection, xid);
        EXPECT_EQ(map_.lane(mv.from).name, dds::View(lane.map_lane_id));
        ASSERT_TRUE(by_id.count(c.connecting_lane_id));
        const msg::MapLane& to = *by_id.at(c.connecting_lane_id);
        EXPECT_EQ(to.direction, autodrive_msgs_msg_MapLane_Constants_EGRESS);
        EXPECT_EQ(map_.lane(mv.to).name, dds::View(to.map_lane_id));
        const std::uint8_t maneuver =
            mv.turn == maps::Turn::kStraight ? autodrive_msgs_msg_MapLane_Constants_STRAIGHT
            : mv.turn == maps::Turn::kLeft   ? autodrive_msgs_msg_MapLane_Constants_LEFT
                                             : autodrive_msgs_msg_MapLane_Constants_RIGHT;
        EXPECT_EQ(c.maneuver, maneuver);

        std::uint32_t expected_group = 0;
        if (const auto g = groups_.find(xid); g != groups_.end()) {
          for (const auto& group : g->second) {
            for (const MovementId m : group.movements) {
              if (m == mv.id) expected_group = group.id.value();
            }
          }
        }
        EXPECT_EQ(c.signal_group, expected_group);
        if (x.control == autodrive_msgs_msg_MapIntersection_Constants_SIGNALISED) {
          EXPECT_NE(c.signal_group, 0u);
        }

        const auto path = dds::Elements(c.path);
        ASSERT_GE(path.size(), 2u);
        EXPECT_EQ(Xy(path.front()), Xy(dds::Elements(lane.centreline).back()));
        EXPECT_EQ(Xy(path.back()), Xy(dds::Elements(to.centreline).front()));
      }
    }
  }
}

TEST_P(MapDataTest, SignalGroupsListTheirMovementsAndHeads) {
  for (const auto& x : dds::Elements(message_->intersections)) {
    const auto groups = dds::Elements(x.signal_groups);
    const auto it = groups_.find(IntersectionId(x.intersection_id));
    if (it == groups_.end()) {
      EXPECT_TRUE(groups.empty());
      continue;
    }
    ASSERT_EQ(groups.size(), it->second.size());
    for (std::size_t i = 0; i < groups.size(); ++i) {
      const SignalGroupInfo& want = it->second[i];
      EXPECT_EQ(groups[i].signal_group, want.id.value());
      EXPECT_EQ(dds::View(groups[i].name), want.name);
      const auto movements = dds::Elements(groups[i].movement_ids);
      ASSERT_EQ(movements.size(), want.movements.size());
      for (std::size_t k = 0; k < movements.size(); ++k) {
        EXPECT_EQ(movements[k], want.movements[k].value());
      }
      const auto heads = dds::Elements(groups[i].signal_heads);
      ASSERT_EQ(heads.size(), want.heads.size());
      ASSERT_FALSE(heads.empty());
      for (std::size_t k = 0; k < heads.size(); ++k) {
        EXPECT_EQ(dds::View(heads[k]), SignalHeadName(want.heads[k]));
      }
    }
  }
}

TEST_P(MapDataTest, PolylinesAreDecimatedButStayOnTheMapsLines) {
  std::size_t map_points = 0, msg_points = 0;
  for (const auto& x : dds::Elements(message_->intersections)) {
    for (const auto& lane : dds::Elements(x.lanes)) {
      const auto c = dds::Elements(lane.centreline);
      msg_points += c.size();
      for (const auto& l : map_.lanes) {
        if (l.name == dds::View(lane.map_lane_id)) map_points += l.centreline.size();
      }
      for (std::size_t i = 1; i < c.size(); ++i) {
        const double step = (Xy(c[i]) - Xy(c[i - 1])).norm();
        EXPECT_GT(step, kMapPointSpacingM / 2 - 1e-3);
        EXPECT_LT(step, kMapPointSpacingM * 1.5 + 1e-9);
      }
    }
  }
  EXPECT_LT(msg_points * 2, map_points);
}

INSTANTIATE_TEST_SUITE_P(ShippedMaps, MapDataTest,
                         ::testing::Values("driving_school", "small_town"));

TEST(MapData, TerraceIntersectionsAreAtTheirHeight) {
  const Map town = LoadShipped("small_town");
  const auto m = BuildMapData(town, "town", GroupPerApproach(town), 1);
  bool found = false;
  for (const auto& x : dds::Elements(m->intersections)) {
    if (dds::View(x.name) != "north_t") continue;
    found = true;
    EXPECT_DOUBLE_EQ(x.ref_point.z, 0.05);
  }
  EXPECT_TRUE(found);
}

TEST(MapData, OnlyTheListedIntersectionsWhenAListIsGiven) {
  const Map town = LoadShipped("small_town");
  const auto names = [](const MapDataMessage& m) {
    std::vector<std::string> out;
    for (const auto& x : dds::Elements(m->intersections)) out.emplace_back(dds::View(x.name));
    return out;
  };
  EXPECT_EQ(names(BuildMapData(town, "town", GroupPerApproach(town), 1)).size(),
            town.intersections.size());
  std::vector<IntersectionId> only;
  for (const auto& x : town.intersections) {
    if (x.name == "centre" || x.name == "west_t") only.push_back(x.id);
  }
  ASSERT_EQ(only.size(), 2u);
  auto listed = names(BuildMapData(town, "town", GroupPerApproach(town), 1, only));
  std::ranges::sort(listed);
  EXPECT_EQ(listed, (std::vector<std::string>{"centre", "west_t"}));
}

TEST(MapData, UnsignalisedIntersectionsHaveNoGroupsAndGroupZero) {
  const Map town = LoadShipped("small_town");
  const auto m = BuildMapData(town, "town", {}, 1);
  for (const auto& x : dds::Elements(m->intersections)) {
    EXPECT_TRUE(dds::Elements(x.signal_groups).empty());
    for (const auto& lane : dds::Elements(x.lanes)) {
      for (const auto& c : dds::Elements(lane.connections)) EXPECT_EQ(c.signal_group, 0u);
    }
  }
}

TEST(MapData, RefusesAssignmentsThatDoNotFitTheMap) {
  const Map town = LoadShipped("small_town");
  const auto good = GroupPerApproach(town);
  const IntersectionId centre = [&] {
    for (const auto& x : town.intersections) {
      if (x.name == "centre") return x.id;
    }
    return IntersectionId(0);
  }();
  const IntersectionId west = [&] {
    for (const auto& x : town.intersections) {
      if (x.name == "west_t") return x.id;
    }
    return IntersectionId(0);
  }();
  const auto message = [&](const SignalGroupAssignment& groups) {
    return test::ErrorMessage([&] { (void)BuildMapData(town, "town", groups, 1); });
  };

  SignalGroupAssignment bad = good;
  bad[IntersectionId(99)] = {SignalGroupInfo{SignalGroupId(1), "x", {}, {}}};
  EXPECT_EQ(message(bad),
            "signal groups are given for IntersectionId(99), which is not in map \"small_town\" "
            "(it has 5 intersections)");

  bad = good;
  bad[west] = {SignalGroupInfo{SignalGroupId(1), "x", {}, {}}};
  EXPECT_EQ(message(bad), "signal groups are given for IntersectionId(" +
                              std::to_string(west.value()) +
                              ") (\"west_t\"), which is stop-controlled, not signalised");

  bad = good;
  bad[centre][0].id = SignalGroupId(0);
  EXPECT_EQ(message(bad),
            "signal group 0 (\"east_approach\") of \"centre\": a signal group id "
            "must not be 0 (0 means none)");

  bad = good;
  bad[centre][1].id = bad[centre][0].id;
  EXPECT_EQ(message(bad),
            "signal group 1 (\"north_approach\") of \"centre\": the id is used twice");

  bad = good;
  const MovementId moved = bad[centre][0].movements[0];
  bad[centre][1].movements.push_back(moved);
  EXPECT_EQ(message(bad), "signal group 2 (\"north_approach\") of \"centre\": MovementId(" +
                              std::to_string(moved.value()) + ") (" + town.movement(moved).name +
                              ") is already in signal group 1");

  bad = good;
  const MovementId foreign = town.intersection(west).movements[0];
  bad[centre][0].movements.push_back(foreign);
  EXPECT_EQ(message(bad), "signal group 1 (\"east_approach\") of \"centre\": MovementId(" +
                              std::to_string(foreign.value()) +
                              ") is not a movement of this intersection");

  bad = good;
  bad[centre][0].heads.push_back(SignalHeadId(77));
  EXPECT_EQ(message(bad),
            "signal group 1 (\"east_approach\") of \"centre\": signal_77 is not a "
            "signal head of this intersection");

  bad = good;
  bad[centre][1].heads.push_back(bad[centre][0].heads[0]);
  EXPECT_EQ(message(bad), "signal group 2 (\"north_approach\") of \"centre\": " +
                              SignalHeadName(bad[centre][0].heads[0]) +
                              " already shows signal group 1");
}

TEST(Decimate, ResamplesAtEqualStepsKeepingBothEnds) {
  maps::Polyline line;
  for (int i = 0; i <= 50; ++i) line.emplace_back(0.02 * i, 0.0);  // 1 m at 2 cm
  const maps::Polyline out = Decimate(line, 0.05);
  ASSERT_EQ(out.size(), 21u);
  for (std::size_t i = 0; i < out.size(); ++i) {
    EXPECT_NEAR(out[i].x(), 0.05 * static_cast<double>(i), 1e-12);
    EXPECT_EQ(out[i].y(), 0.0);
  }
  EXPECT_EQ(out.back(), line.back());

  // 0.52 m: the step before the end would be 2 cm, so the point at 0.5 m goes.
  line.resize(27);
  const maps::Polyline short_end = Decimate(line, 0.05);
  ASSERT_EQ(short_end.size(), 11u);
  EXPECT_NEAR(short_end[9].x(), 0.45, 1e-12);
  EXPECT_EQ(short_end.back(), line.back());

  EXPECT_EQ(Decimate(maps::Polyline{{1, 2}, {1, 2.01}}, 0.05).size(), 2u);
  EXPECT_EQ(Decimate(maps::Polyline{{1, 2}}, 0.05).size(), 1u);
  EXPECT_EQ(test::ErrorMessage([&] { (void)Decimate(line, 0.0); }),
            "the point spacing must be positive and finite, got 0");
}

TEST(Decimate, PointsOfAnArcStayOnItsChords) {
  maps::Polyline arc;
  const double r = 0.35;
  for (int i = 0; i <= 30; ++i) {
    const double a = kPi / 2 * i / 30;
    arc.emplace_back(r * std::cos(a), r * std::sin(a));
  }
  for (const auto& p : Decimate(arc)) EXPECT_NEAR(p.norm(), r, 1e-3);
}

TEST(SignRegistry, HasEverySignOfTheMapWithItsTypePoseAndLane) {
  for (const std::string name : {"driving_school", "small_town"}) {
    SCOPED_TRACE(name);
    const Map map = LoadShipped(name);
    const auto m = BuildSignRegistry(map, "city", 3);
    EXPECT_EQ(dds::View(m->header.frame_id), "map");
    EXPECT_EQ(dds::View(m->city), "city");
    EXPECT_EQ(m->revision, 3u);
    const auto signs = dds::Elements(m->signs);
    ASSERT_EQ(signs.size(), map.signs.size());
    ASSERT_FALSE(signs.empty());
    for (std::size_t i = 0; i < signs.size(); ++i) {
      const maps::Sign& want = map.signs[i];
      const auto& s = signs[i];
      EXPECT_EQ(s.sign_id, want.id.value());
      EXPECT_EQ(s.sign_type, SignTypeToWire(want.type));
      EXPECT_FLOAT_EQ(s.value, static_cast<float>(want.value));
      EXPECT_DOUBLE_EQ(s.pose.position.x, want.X_MS.translation().x());
      EXPECT_DOUBLE_EQ(s.pose.position.y, want.X_MS.translation().y());
      EXPECT_DOUBLE_EQ(s.pose.position.z, maps::TerrainHeight(map, want.X_MS.translation().x(),
                                                              want.X_MS.translation().y()));
      const Eigen::Quaterniond q(s.pose.orientation.w, s.pose.orientation.x, s.pose.orientation.y,
                                 s.pose.orientation.z);
      EXPECT_NEAR(WrapAngle(YawFromQuaternion(q) - want.X_MS.yaw()), 0.0, 1e-9);
      EXPECT_EQ(dds::View(s.map_lane_id), want.lane ? map.lane(*want.lane).name : "");
      EXPECT_FALSE(dds::View(s.label).empty());
    }
  }
}

TEST(SignRegistry, MapsEveryTypeToItsConstant) {
  EXPECT_EQ(SignTypeToWire("stop"), autodrive_msgs_msg_TrafficSign_Constants_STOP);
  EXPECT_EQ(SignTypeToWire("yield"), autodrive_msgs_msg_TrafficSign_Constants_YIELD);
  EXPECT_EQ(SignTypeToWire("speed_limit"), autodrive_msgs_msg_TrafficSign_Constants_SPEED_LIMIT);
  EXPECT_EQ(SignTypeToWire("no_entry"), autodrive_msgs_msg_TrafficSign_Constants_NO_ENTRY);
  EXPECT_EQ(SignTypeToWire("parking"), autodrive_msgs_msg_TrafficSign_Constants_PARKING);
  EXPECT_EQ(SignTypeToWire("curve_left"), autodrive_msgs_msg_TrafficSign_Constants_CURVE_LEFT);
  EXPECT_EQ(SignTypeToWire("curve_right"), autodrive_msgs_msg_TrafficSign_Constants_CURVE_RIGHT);
  EXPECT_EQ(SignTypeToWire("pedestrian_crossing"),
            autodrive_msgs_msg_TrafficSign_Constants_PEDESTRIAN_CROSSING);
  EXPECT_EQ(SignTypeToWire("one_way"), autodrive_msgs_msg_TrafficSign_Constants_ONE_WAY);
}

TEST(SignRegistry, LabelsNameTheValueAndTheApproach) {
  const Map town = LoadShipped("small_town");
  const auto m = BuildSignRegistry(town, "town", 1);
  std::set<std::string> labels;
  for (const auto& s : dds::Elements(m->signs)) labels.insert(std::string(dds::View(s.label)));
  std::string all;
  for (const auto& l : labels) all += "\n  " + l;
  EXPECT_TRUE(labels.count("speed limit 0.2 m/s")) << all;
  EXPECT_TRUE(labels.count("curve left")) << all;
  EXPECT_TRUE(labels.count("stop, west_t east approach")) << all;
}

TEST(SignRegistry, RefusesAnUnknownSignTypeNamingIt) {
  Map map = LoadShipped("driving_school");
  map.signs[1].type = "moose_crossing";
  EXPECT_EQ(test::ErrorMessage([&] { (void)BuildSignRegistry(map, "city", 1); }),
            "sign 2 of map \"driving_school\": unknown sign type \"moose_crossing\" (known: stop, "
            "yield, speed_limit, no_entry, parking, curve_left, curve_right, pedestrian_crossing, "
            "one_way)");
}

}  // namespace
}  // namespace autodrive::scm
