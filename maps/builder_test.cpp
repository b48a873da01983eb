#include "maps/builder.h"

#include <gtest/gtest.h>

#include <map>
#include <set>

#include "common/error.h"
#include "common/test_support.h"
#include "maps/test_layouts.h"

namespace autodrive::maps {
namespace {

Layout MakeLayout(const std::vector<std::vector<std::string>>& rows) {
  return maps::MakeLayout("test", rows);
}

// A 4-way intersection with one lane per direction, its arms leaving the map.
using test_layouts::FourWay;

// "S>N" from a movement name "r1c1:S>N:0>0".
std::string Short(const Movement& m) { return m.name.substr(m.name.find(':') + 1, 3); }

TEST(MapBuilder, FourWayConflictsMatchTheHandWrittenTable) {
  const Map map = Build(FourWay());
  ASSERT_EQ(map.intersections.size(), 1u);
  const Intersection& x = map.intersections[0];
  ASSERT_EQ(x.movements.size(), 12u);

  // Right-hand traffic, tile 1.0 m, lanes 0.3 m, clearance 0.2 m. Derived by hand:
  const std::set<std::set<std::string>> expected = {
      // crossing throughs
      {"S>N", "E>W"},
      {"S>N", "W>E"},
      {"N>S", "E>W"},
      {"N>S", "W>E"},
      // merges into one egress lane (right, left and through into E, N, W, S)
      {"S>E", "N>E"},
      {"S>E", "W>E"},
      {"N>E", "W>E"},
      {"E>N", "W>N"},
      {"E>N", "S>N"},
      {"W>N", "S>N"},
      {"N>W", "S>W"},
      {"N>W", "E>W"},
      {"S>W", "E>W"},
      {"W>S", "E>S"},
      {"W>S", "N>S"},
      {"E>S", "N>S"},
      // a left turn crosses the opposing through ...
      {"S>W", "N>S"},
      {"N>E", "S>N"},
      {"E>S", "W>E"},
      {"W>N", "E>W"},
      // ... and the through coming from its left
      {"S>W", "W>E"},
      {"N>E", "E>W"},
      {"E>S", "S>N"},
      {"W>N", "N>S"},
      // lefts: adjacent ones cross; opposing ones pass 0.11 m apart, under the clearance
      {"S>W", "E>S"},
      {"E>S", "N>E"},
      {"N>E", "W>N"},
      {"W>N", "S>W"},
      {"S>W", "N>E"},
      {"E>S", "W>N"},
  };
  std::set<std::set<std::string>> actual;
  for (const auto& [a, b] : x.conflicts) {
    actual.insert({Short(map.movement(a)), Short(map.movement(b))});
  }
  EXPECT_EQ(actual, expected);
  EXPECT_EQ(x.conflicts.size(), 30u);

  // The acceptance's three statements, spelt out.
  const auto id = [&](const std::string& s) {
    for (MovementId m : x.movements) {
      if (Short(map.movement(m)) == s) return m;
    }
    ADD_FAILURE() << "no movement " << s;
    return x.movements.front();
  };
  EXPECT_TRUE(map.Conflict(id("S>N"), id("E>W")));   // crossing throughs
  EXPECT_TRUE(map.Conflict(id("S>W"), id("N>S")));   // left vs opposing through
  EXPECT_FALSE(map.Conflict(id("S>E"), id("N>W")));  // rights into different lanes
  EXPECT_FALSE(map.Conflict(id("S>E"), id("S>N")));  // diverging from one lane: by rule
  EXPECT_FALSE(map.Conflict(id("S>N"), id("N>S")));  // opposing throughs
}

TEST(MapBuilder, MovementPathsStartAtTheIngressEndAndEndAtTheEgressStart) {
  const Map map = Build(FourWay());
  for (const auto& m : map.movements) {
    SCOPED_TRACE(m.name);
    EXPECT_EQ(m.path.front(), map.lane(m.from).centreline.back());
    EXPECT_EQ(m.path.back(), map.lane(m.to).centreline.front());
    EXPECT_EQ(map.lane(m.from).ingress_of, m.intersection);
    EXPECT_EQ(map.lane(m.to).egress_of, m.intersection);
  }
}

// Every lane names the intersection and approach its end enters exactly when that approach
// lists it as ingress, and the one its start leaves exactly when that approach lists it as
// egress.
void ExpectLanesKnowTheirApproaches(const Map& map) {
  std::map<LaneId, std::pair<IntersectionId, ApproachId>> ingress, egress;
  for (const auto& x : map.intersections) {
    for (const auto& a : x.approaches) {
      for (const LaneId l : a.ingress) ingress.insert_or_assign(l, std::pair{x.id, a.id});
      for (const LaneId l : a.egress) egress.insert_or_assign(l, std::pair{x.id, a.id});
    }
  }
  for (const auto& lane : map.lanes) {
    SCOPED_TRACE(lane.name);
    const auto in = ingress.find(lane.id);
    EXPECT_EQ(lane.ingress_of.has_value(), in != ingress.end());
    EXPECT_EQ(lane.ingress_approach.has_value(), in != ingress.end());
    if (in != ingress.end()) {
      EXPECT_EQ(lane.ingress_of, in->second.first);
      EXPECT_EQ(lane.ingress_approach, in->second.second);
    }
    const auto out = egress.find(lane.id);
    EXPECT_EQ(lane.egress_of.has_value(), out != egress.end());
    EXPECT_EQ(lane.egress_approach.has_value(), out != egress.end());
    if (out != egress.end()) {
      EXPECT_EQ(lane.egress_of, out->second.first);
      EXPECT_EQ(lane.egress_approach, out->second.second);
    }
  }
}

TEST(MapBuilder, LaneBetweenTwoIntersectionsKnowsTheApproachOfEach) {
  const Map map = Build(test_layouts::TwoFourWays());
  ASSERT_EQ(map.intersections.size(), 2u);
  const Intersection& west = map.intersections[0];
  const Intersection& east = map.intersections[1];
  ASSERT_EQ(west.tile, (TileIndex{1, 1}));
  ASSERT_EQ(east.tile, (TileIndex{1, 3}));
  const auto lane = [&](const std::string& name) -> const Lane& {
    for (const auto& l : map.lanes) {
      if (l.name == name) return l;
    }
    ADD_FAILURE() << "no lane " << name;
    return map.lanes.front();
  };
  constexpr ApproachId kEast(1), kWest(3);
  // Eastbound: leaves the west intersection by its east approach, enters the east one by its
  // west approach.
  const Lane& eastbound = lane("r1c2:W>E:0");
  EXPECT_EQ(eastbound.egress_of, west.id);
  EXPECT_EQ(eastbound.egress_approach, kEast);
  EXPECT_EQ(eastbound.ingress_of, east.id);
  EXPECT_EQ(eastbound.ingress_approach, kWest);
  const Lane& westbound = lane("r1c2:E>W:0");
  EXPECT_EQ(westbound.egress_of, east.id);
  EXPECT_EQ(westbound.egress_approach, kWest);
  EXPECT_EQ(westbound.ingress_of, west.id);
  EXPECT_EQ(westbound.ingress_approach, kEast);
  // A lane that only enters (from the map's edge) has no egress side, and the reverse.
  const Lane& from_edge = lane("r1c0:W>E:0");
  EXPECT_EQ(from_edge.ingress_approach, kWest);
  EXPECT_FALSE(from_edge.egress_of.has_value());
  EXPECT_FALSE(from_edge.egress_approach.has_value());
  const Lane& to_edge = lane("r1c4:W>E:0");
  EXPECT_EQ(to_edge.egress_approach, kEast);
  EXPECT_FALSE(to_edge.ingress_of.has_value());
  EXPECT_FALSE(to_edge.ingress_approach.has_value());
  ExpectLanesKnowTheirApproaches(map);
}

TEST(MapBuilder, EveryLaneOfTheSmallTownKnowsItsApproaches) {
  // Four-way and T-junctions, lanes between two of them, roads between none.
  const Map map = Build(LoadLayout((test::SourceDir() / "config/maps/small_town.yaml").string()));
  int between = 0;
  for (const auto& l : map.lanes) between += l.ingress_of && l.egress_of;
  EXPECT_EQ(between, 8) << "the centre's four arms lead to four T-junctions, both ways";
  ExpectLanesKnowTheirApproaches(map);
}

// The radius of the circle through three points.
double Circumradius(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  const double ab = (b - a).norm(), bc = (c - b).norm(), ca = (a - c).norm();
  const double cross = std::abs((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x());
  return cross < 1e-15 ? std::numeric_limits<double>::infinity() : ab * bc * ca / (2 * cross);
}

double MinRadius(const Polyline& p) {
  double r = std::numeric_limits<double>::infinity();
  for (std::size_t i = 2; i < p.size(); ++i)
    r = std::min(r, Circumradius(p[i - 2], p[i - 1], p[i]));
  return r;
}

TEST(MapBuilder, EveryLaneAndPathCanBeDrivenByNigel) {
  // Nigel's minimum turning radius: wheelbase / tan(30 deg) = 0.14154 / 0.57735 = 0.245 m.
  const Map map = Build(MakeLayout({{"curve", "t", "end"},
                                    {"straight@90", "straight@90", "empty"},
                                    {"curve@90", "x4", "parking@270"},
                                    {"empty", "end@270", "empty"}}));
  EXPECT_EQ(map.intersections.size(), 2u);
  EXPECT_EQ(map.parking_bays.size(), 3u);
  for (const auto& lane : map.lanes) EXPECT_GE(MinRadius(lane.centreline), 0.245) << lane.name;
  for (const auto& m : map.movements) EXPECT_GE(MinRadius(m.path), 0.245) << m.name;
}

TEST(MapBuilder, LanesChainAcrossTileEdgesAndAClosedLoopIsACycle) {
  const Map map = Build(MakeLayout({{"curve", "curve@270"}, {"curve@90", "curve@180"}}));
  ASSERT_EQ(map.lanes.size(), 8u);
  for (const auto& lane : map.lanes) {
    ASSERT_EQ(lane.successors.size(), 1u) << lane.name;
    EXPECT_EQ(map.lane(lane.successors[0]).centreline.front(), lane.centreline.back());
  }
  // Each lane knows the tile edges it crosses, and its ends lie on them.
  for (const auto& lane : map.lanes) {
    const Eigen::Vector2d c = map.TileCentre(lane.tile);
    const Eigen::Vector2d in = lane.centreline.front() - c;
    const Eigen::Vector2d out = lane.centreline.back() - c;
    EXPECT_NEAR(in.dot(Outward(lane.from_side)), 0.5, 1e-12) << lane.name;
    EXPECT_NEAR(out.dot(Outward(lane.to_side)), 0.5, 1e-12) << lane.name;
  }
  // Following successors from any lane comes back to it after 4 lanes (one lap).
  LaneId l = map.lanes[0].id;
  for (int i = 0; i < 4; ++i) l = map.lane(l).successors[0];
  EXPECT_EQ(l, map.lanes[0].id);
}

TEST(MapBuilder, SignalisedApproachesGetStopLinesAndOneHeadEach) {
  const Map map = Build(FourWay());
  EXPECT_EQ(map.signal_heads.size(), 4u);
  for (const auto& a : map.intersections[0].approaches) {
    for (LaneId in : a.ingress) {
      const Lane& lane = map.lane(in);
      ASSERT_TRUE(lane.stop_line.has_value()) << lane.name;
      EXPECT_NEAR((lane.stop_line->left - lane.stop_line->right).norm(), 0.3, 1e-12);
      EXPECT_NEAR(
          ((lane.stop_line->left + lane.stop_line->right) / 2 - lane.centreline.back()).norm(), 0,
          1e-12);
    }
  }
  // Heads stand at the corners of the intersection tile (centre (1.5, 1.5)), outside the road.
  for (const auto& h : map.signal_heads) {
    const Eigen::Vector2d d = h.X_MH.translation() - Eigen::Vector2d(1.5, 1.5);
    EXPECT_GT(std::abs(d.x()), 0.3);
    EXPECT_GT(std::abs(d.y()), 0.3);
    EXPECT_LT(d.norm(), 0.75);
  }
}

TEST(MapBuilder, StopControlledIntersectionsGetStopSignsAndNoHeads) {
  const Map map = Build(MakeLayout({{"empty", "straight@90", "empty"},
                                    {"straight", "x4 control=stop", "straight"},
                                    {"empty", "straight@90", "empty"}}));
  EXPECT_TRUE(map.signal_heads.empty());
  ASSERT_EQ(map.signs.size(), 4u);
  for (const auto& s : map.signs) {
    EXPECT_EQ(s.type, "stop");
    ASSERT_TRUE(s.lane.has_value());
    EXPECT_TRUE(map.lane(*s.lane).stop_line.has_value());
  }
}

// A sign the layout stands on a lane, or on a path through an intersection, is refused with
// its place and the lane; beside the road it is taken.
TEST(MapBuilder, ASignOnTheRoadIsRefusedNamingTheLane) {
  Layout layout = MakeLayout({{"empty", "straight@90", "empty"},
                              {"straight", "x4 control=signal", "straight"},
                              {"empty", "straight@90", "empty"}});
  SignSpec sign;
  sign.type = "curve_right";
  sign.x_m = 0.5;
  sign.y_m = 1.3;  // 5 cm from the west tile's eastbound lane (the lanes run at y 1.35 and 1.65)
  sign.yaw_rad = 0.0;
  layout.signs = {sign};
  try {
    (void)Build(layout);
    FAIL() << "a sign 5 cm from a lane's centre was taken";
  } catch (const InputError& e) {
    EXPECT_NE(
        std::string(e.what()).find("sign 1 (curve_right) at (0.500, 1.300) stands on lane r1c0:"),
        std::string::npos)
        << e.what();
  }
  layout.signs[0].x_m = 1.5;
  layout.signs[0].y_m = 1.5;  // the intersection's centre: on its paths
  EXPECT_THROW((void)Build(layout), InputError);
  layout.signs[0].x_m = 0.5;
  layout.signs[0].y_m = 1.12;  // beside the road
  EXPECT_EQ(Build(layout).signs.size(), 1u);
}

// The ids of each intersection's heads by the side of the approach they face: "E4 N5 W6 S7".
std::map<std::string, std::string> HeadIdsBySide(const Map& map) {
  std::map<std::string, std::string> out;
  for (const Intersection& x : map.intersections) {
    for (const SignalHeadId h : x.signal_heads) {
      for (const Approach& a : x.approaches) {
        if (a.id != map.signal_head(h).approach) continue;
        std::string& ids = out[x.name];
        ids += (ids.empty() ? "" : " ") + std::string(1, SideLetter(a.side)) +
               std::to_string(h.value());
      }
    }
  }
  return out;
}

// What a lab does in its first week: a stop-controlled junction made signalised. The heads the
// layout numbers keep their ids; the new ones get ids above them, whatever their place in the
// map (before this, west_t's new heads took 4..6 and moved centre's from 4..7 to 7..10).
TEST(MapBuilder, HeadIdsAreTheLayoutsAndANewSignalisedIntersectionMovesNoOther) {
  Layout town = LoadLayout((test::SourceDir() / "config" / "maps" / "small_town.yaml").string());
  const Map before = Build(town);
  EXPECT_EQ(HeadIdsBySide(before), (std::map<std::string, std::string>{{"north_t", "E1 W2 S3"},
                                                                       {"centre", "E4 N5 W6 S7"}}));
  Cell& west_t = town.grid[2][0];
  ASSERT_EQ(west_t.name, "west_t");
  west_t.control = Control::kSignal;
  const Map after = Build(town);
  EXPECT_EQ(HeadIdsBySide(after),
            (std::map<std::string, std::string>{
                {"north_t", "E1 W2 S3"}, {"centre", "E4 N5 W6 S7"}, {"west_t", "E8 N9 S10"}}));
  // In ascending id order, and each found by its id.
  for (std::size_t i = 0; i < after.signal_heads.size(); ++i) {
    EXPECT_EQ(after.signal_heads[i].id.value(), i + 1);
    EXPECT_EQ(&after.signal_head(after.signal_heads[i].id), &after.signal_heads[i]);
  }
  EXPECT_EQ(after.DescribeSignalHead(SignalHeadId(9)), "signal_9 (west_t, N approach)");
  EXPECT_EQ(after.DescribeSignalHead(SignalHeadId(11)), "signal_11 (not in map small_town)");
}

TEST(MapBuilder, HeadIdsMayLeaveGapsAndBeGivenAsAFirstId) {
  const Map map =
      Build(MakeLayout({{"empty", "straight@90", "empty", "empty", "straight@90", "empty"},
                        {"straight", "x4 name=a heads=E20/N3/W7/S12", "straight", "straight",
                         "x4 name=b heads=40", "straight"},
                        {"empty", "straight@90", "empty", "empty", "straight@90", "empty"}}));
  EXPECT_EQ(HeadIdsBySide(map),
            (std::map<std::string, std::string>{{"a", "E20 N3 W7 S12"}, {"b", "E40 N41 W42 S43"}}));
  ASSERT_EQ(map.signal_heads.size(), 8u);
  EXPECT_EQ(map.signal_heads.front().id.value(), 3u);
  EXPECT_EQ(map.signal_heads.back().id.value(), 43u);
  EXPECT_FALSE(map.HasSignalHead(SignalHeadId(1)));
  EXPECT_THROW((void)map.signal_head(SignalHeadId(1)), std::out_of_range);
}

// ---- Bad layouts: each kind of error names the place and the reason ----------------------

std::string BuildError(const Layout& layout) {
  return test::ErrorMessage([&] { (void)Build(layout); });
}

TEST(MapBuilderErrors, HeadIdsGivenTwiceToASideWithoutARoadOrToTooFewApproaches) {
  const auto two_ways = [](const std::string& a, const std::string& b) {
    return MakeLayout(
        {{"empty", "straight@90", "empty", "empty", "straight@90", "empty"},
         {"straight", "x4 name=a " + a, "straight", "straight", "x4 name=b " + b, "straight"},
         {"empty", "straight@90", "empty", "empty", "straight@90", "empty"}});
  };
  EXPECT_EQ(BuildError(two_ways("heads=1", "heads=E9/N4/W10/S11")),
            "signal head 4 is given twice: to intersection a and to b (heads= of their cells)");
  EXPECT_EQ(BuildError(two_ways("heads=E1/N2/W3", "")),
            "tile r1c1 (row 1, column 1, \"x4 name=a heads=E1/N2/W3\"): heads= gives no id to "
            "its S approach (give every approach one: heads=E1/N2/W3/S4)");
  EXPECT_EQ(BuildError(MakeLayout({{"straight", "t name=t heads=E1/N2/W3/S4", "straight"},
                                   {"empty", "straight@90", "empty"}})),
            "tile r0c1 (row 0, column 1, \"t name=t heads=E1/N2/W3/S4\"): heads= gives head 2 to "
            "its N approach, but it has no road on that side");
  EXPECT_EQ(test::ErrorMessage([] { (void)Cell::FromConfigString("x4 control=stop heads=1"); }),
            "heads applies to signalised intersections (x4, t with control=signal) only, in cell "
            "\"x4 control=stop heads=1\"");
  EXPECT_EQ(test::ErrorMessage([] { (void)Cell::FromConfigString("x4 heads=E1,N2"); }),
            "a head id must be a number, got \"1,N2\" in cell \"x4 heads=E1,N2\"");
  EXPECT_EQ(test::ErrorMessage([] { (void)Cell::FromConfigString("x4 heads=E1/E2"); }),
            "heads gives side E twice in cell \"x4 heads=E1/E2\"");
  EXPECT_EQ(test::ErrorMessage([] { (void)Cell::FromConfigString("x4 heads=0"); }),
            "a head id must be in [1, 999999], got 0 in cell \"x4 heads=0\"");
}

TEST(MapBuilderErrors, RoadMeetingAnEdgeWithoutARoad) {
  EXPECT_EQ(BuildError(MakeLayout({{"straight", "empty"}})),
            "tile r0c0 (row 0, column 0, \"straight\"): its road on the E edge meets tile r0c1 "
            "(row 0, column 1, \"empty\"), which has no road on its W edge (mismatched tile "
            "edges)");
}

TEST(MapBuilderErrors, MismatchedLaneCounts) {
  Layout l = MakeLayout({{"straight lanes=2", "straight"}});
  l.tile_size_m = 1.5;
  EXPECT_EQ(BuildError(l),
            "tile r0c0 (row 0, column 0, \"straight lanes=2\"): 2 lane(s) per direction on its E "
            "edge but tile r0c1 (row 0, column 1, \"straight\") has 1");
}

TEST(MapBuilderErrors, MismatchedLaneWidths) {
  EXPECT_EQ(BuildError(MakeLayout({{"straight width=0.25", "straight"}})),
            "tile r0c0 (row 0, column 0, \"straight width=0.25\"): lanes 0.25 m wide on its E edge "
            "but tile r0c1 (row 0, column 1, \"straight\") has lanes 0.3 m wide");
}

TEST(MapBuilder, LaneWidthIsSetPerModule) {
  const Map map = Build(MakeLayout({{"curve width=0.25", "curve@270 width=0.25"},
                                    {"curve@90 width=0.25", "curve@180 width=0.25"}}));
  for (const auto& lane : map.lanes) {
    EXPECT_DOUBLE_EQ(lane.width_m, 0.25);
    EXPECT_NEAR((lane.left_boundary[3] - lane.right_boundary[3]).norm(), 0.25, 1e-9);
  }
}

TEST(MapBuilderErrors, IntersectionArmOnTheMapBoundary) {
  EXPECT_EQ(BuildError(MakeLayout({{"x4"}})),
            "tile r0c0 (row 0, column 0, \"x4\"): its E edge is the map boundary; an "
            "intersection arm needs a road tile beyond it");
}

TEST(MapBuilderErrors, IntersectionNextToIntersection) {
  Layout l = MakeLayout({{"empty", "straight@90", "straight@90", "empty"},
                         {"straight", "x4", "x4", "straight"},
                         {"empty", "straight@90", "straight@90", "empty"}});
  EXPECT_EQ(BuildError(l),
            "tile r1c1 (row 1, column 1, \"x4\"): next to another intersection, tile r1c2 (row 1, "
            "column 2, \"x4\"); put a road tile between them");
}

TEST(MapBuilderErrors, RoadEndingInAWall) {
  Layout l = MakeLayout({{"straight", "straight"}});
  l.boundary_walls = true;
  EXPECT_EQ(BuildError(l),
            "the boundary wall closes the road of tile r0c0 (row 0, column 0, \"straight\") at "
            "its W edge (a road that ends in a wall)");
}

TEST(MapBuilderErrors, OverlappingObstacles) {
  Layout l = MakeLayout({{"empty", "empty"}});
  l.obstacles = {{"box", 0.5, 0.5, 0, 0.2, 0.2, 0.2}, {"box", 0.6, 0.55, 0.3, 0.2, 0.2, 0.2}};
  EXPECT_EQ(BuildError(l),
            "obstacle 1 (box at x 0.6, y 0.55) overlaps obstacle 0 (box at x 0.5, y 0.5)");
  l.obstacles[1].x_m = 0.7;  // touching is not overlapping
  l.obstacles[1].yaw_rad = 0;
  l.obstacles[1].y_m = 0.5;
  EXPECT_NO_THROW((void)Build(l));
}

TEST(MapBuilderErrors, ObstacleOutsideTheMap) {
  Layout l = MakeLayout({{"empty", "empty"}});
  l.obstacles = {{"box", 1.95, 0.5, 0, 0.2, 0.2, 0.2}};
  EXPECT_EQ(BuildError(l),
            "obstacle 0 (box at x 1.95, y 0.5) reaches outside the map [0, 2] x [0, 1] m");
}

TEST(MapBuilderErrors, MismatchedRampHeights) {
  EXPECT_EQ(BuildError(MakeLayout({{"ramp rise=0.1", "straight"}})),
            "tile r0c0 (row 0, column 0, \"ramp rise=0.1\"): its road on the E edge is at 0.1 m "
            "but tile r0c1 (row 0, column 1, \"straight\") is at 0 m there (mismatched heights)");
  EXPECT_NO_THROW((void)Build(MakeLayout({{"ramp rise=0.1", "straight elevation=0.1"}})));
}

TEST(MapBuilderErrors, UnknownModuleAndBadOptions) {
  EXPECT_EQ(test::ErrorMessage([] { (void)Cell::FromConfigString("roundabout"); }),
            "unknown module \"roundabout\" (known: empty, straight, curve, x4, t, end, parking, "
            "ramp, open)");
  EXPECT_EQ(test::ErrorMessage([] { (void)Cell::FromConfigString("curve@45"); }),
            "the rotation must be 0, 90, 180 or 270 degrees, got 45 in cell \"curve@45\"");
  EXPECT_EQ(test::ErrorMessage([] { (void)Cell::FromConfigString("straight control=stop"); }),
            "control applies to intersections (x4, t), not to straight");
}

TEST(MapBuilderErrors, RaggedGridAndRoadsTooWideForTheTile) {
  EXPECT_EQ(BuildError(MakeLayout({{"empty", "empty"}, {"empty"}})),
            "grid row 1 has 1 cells but row 0 has 2 (the grid must be rectangular)");
  EXPECT_EQ(BuildError(MakeLayout({{"straight lanes=2"}})),
            "tile r0c0: a road of 2 lane(s) per direction is 1.2 m wide and does not fit a 1 m "
            "tile (at most 90% of it)");
}

TEST(MapLayout, CellsRoundTripThroughText) {
  for (const char* text :
       {"empty", "straight@90", "x4 control=stop name=main", "ramp@180 rise=0.05",
        "t@270 lanes=2 control=yield", "parking elevation=0.1", "straight width=0.25",
        "x4 heads=12", "t@90 name=a heads=S3/N1/E2"}) {
    EXPECT_EQ(Cell::FromConfigString(Cell::FromConfigString(text).ToConfigString()),
              Cell::FromConfigString(text))
        << text;
  }
  EXPECT_EQ(Cell::FromConfigString("."), Cell::FromConfigString("empty"));
}

}  // namespace
}  // namespace autodrive::maps
