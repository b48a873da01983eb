#include "maps/sumo.h"

#include <gtest/gtest.h>
#include <libsumo/libsumo.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iterator>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <pugixml.hpp>

#include "common/error.h"
#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/test_layouts.h"

namespace autodrive::maps {
namespace {

namespace fs = std::filesystem;

Layout MakeLayout(const std::vector<std::vector<std::string>>& rows) {
  return maps::MakeLayout("sumo_test", rows);
}

// A signalised 4-way intersection whose arms leave the map.
Layout FourWaySignal() { return test_layouts::FourWay("signal"); }

// A stop-controlled T-junction (roads west, east and south).
Layout TJunctionStop() {
  return MakeLayout(
      {{"straight", "t control=stop", "straight"}, {"empty", "straight@90", "empty"}});
}

// A closed loop of four curves.
Layout ClosedLoop() { return MakeLayout({{"curve", "curve@270"}, {"curve@90", "curve@180"}}); }

// Curves, a yield T-junction and a signalised 4-way, each with a turning loop (road end,
// parking) right at one of its arms.
Layout Mixed() {
  return MakeLayout({{"curve", "t control=yield", "end"},
                     {"straight@90", "straight@90", "empty"},
                     {"curve@90", "x4", "parking@270"},
                     {"empty", "end@270", "empty"}});
}

// Two lanes per direction on 1.5 m tiles: an uncontrolled 4-way ...
Layout TwoLaneFourWay() {
  Layout l = MakeLayout({{"empty", "straight@90", "empty"},
                         {"straight", "x4 control=none", "straight"},
                         {"empty", "straight@90", "empty"}});
  l.tile_size_m = 1.5;
  l.lanes_per_direction = 2;
  return l;
}

// ... and a closed loop of curves.
Layout TwoLaneLoop() {
  Layout l = ClosedLoop();
  l.tile_size_m = 1.5;
  l.lanes_per_direction = 2;
  return l;
}

// The test's own folder.
class TempDir : public test::TempDir {
 public:
  TempDir() : test::TempDir("autodrive_sumo_test") {}
};

// libsumo runs one simulation per process: this one, from construction to destruction.
class Simulation {
 public:
  explicit Simulation(const SumoExport& e) {
    libsumo::Simulation::start({"sumo", "--net-file", e.net_file.string(), "--additional-files",
                                e.vtype_file.string(), "--step-length", "0.1", "--no-step-log",
                                "true", "--seed", "1", "--time-to-teleport", "-1"});
  }
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;
  ~Simulation() { libsumo::Simulation::close(); }
};

// Lengths and positions in the lab's metres: SUMO's divided by the export's scale.
double SumoLength(const SumoExport& e, const std::vector<SumoLaneRef>& pieces) {
  double l = 0;
  for (const auto& p : pieces) l += libsumo::Lane::getLength(p.id());
  return l / e.scale;
}

double Distance(const SumoExport& e, const libsumo::TraCIPosition& p, const Eigen::Vector2d& q) {
  return std::hypot(p.x / e.scale - q.x(), p.y / e.scale - q.y());
}

// The length of a connection's internal lanes: one, or two when SUMO puts an internal junction
// (a waiting point) on it.
double ViaLength(const libsumo::TraCIConnection& link) {
  double length = 0;
  std::string lane = link.approachedInternal;
  for (int i = 0; i < 5 && !lane.empty() && lane.front() == ':'; ++i) {
    length += libsumo::Lane::getLength(lane);
    const auto next = libsumo::Lane::getLinks(lane);
    if (next.size() != 1) break;
    lane = next[0].approachedInternal.empty() ? next[0].approachedLane : next[0].approachedInternal;
  }
  return length;
}

// Every map lane has its SUMO lanes, where the map has it and as long; every lane connects to
// exactly its successors and movements.
void ExpectLanesMatch(const Map& map, const SumoExport& e) {
  for (const Lane& lane : map.lanes) {
    SCOPED_TRACE(lane.name);
    ASSERT_EQ(e.lanes.count(lane.id), 1u);
    const auto& pieces = e.lane_pieces.at(lane.id);
    ASSERT_FALSE(pieces.empty());
    EXPECT_EQ(pieces.front(), e.lane(lane.id));
    // SUMO gives all lanes of an edge one length: the mean of the map's (its own on one-lane
    // edges and on straights).
    const auto& siblings = e.edges.at(pieces.front().edge);
    double mean = 0;
    for (LaneId l : siblings) mean += map.lane(l).length_m / static_cast<double>(siblings.size());
    EXPECT_NEAR(SumoLength(e, pieces), mean, 0.02 * mean);
    if (siblings.size() == 1) {
      EXPECT_NEAR(SumoLength(e, pieces), lane.length_m, 0.02 * lane.length_m);
    }
    // The SUMO lane lies where the map lane does (this checks the kerb-first index mapping).
    const auto first = libsumo::Lane::getShape(pieces.front().id()).value;
    const auto last = libsumo::Lane::getShape(pieces.back().id()).value;
    EXPECT_LT(Distance(e, first.front(), lane.centreline.front()), 0.01);
    EXPECT_LT(Distance(e, last.back(), lane.centreline.back()), 0.01);
    EXPECT_NEAR(libsumo::Lane::getWidth(pieces.front().id()) / e.scale, lane.width_m, 1e-6);

    std::set<std::string> expected, actual;
    for (LaneId next : lane.successors) expected.insert(e.lane(next).id());
    for (MovementId m : lane.movements_out) expected.insert(e.movement(m).to.id());
    for (const auto& link : libsumo::Lane::getLinks(pieces.back().id())) {
      actual.insert(link.approachedLane);
    }
    EXPECT_EQ(actual, expected);
  }
}

// Each intersection is its junction; a signalised one is a traffic light whose link i is its
// i-th movement; each movement's internal lanes are as long as its path.
void ExpectIntersectionsMatch(const Map& map, const SumoExport& e) {
  const auto junctions = libsumo::Junction::getIDList();
  const auto lights = libsumo::TrafficLight::getIDList();
  for (const Intersection& x : map.intersections) {
    SCOPED_TRACE(x.name);
    const std::string& id = e.junctions.at(x.id);
    EXPECT_EQ(id, x.name);
    EXPECT_NE(std::find(junctions.begin(), junctions.end(), id), junctions.end());
    const bool is_light = std::find(lights.begin(), lights.end(), id) != lights.end();
    const bool light = x.control == Control::kSignal || x.control == Control::kStop;
    EXPECT_EQ(is_light, light);
    if (is_light) {
      const auto links = libsumo::TrafficLight::getControlledLinks(id);
      ASSERT_EQ(links.size(), x.movements.size());
      for (std::size_t i = 0; i < links.size(); ++i) {
        const SumoMovement& m = e.movement(x.movements[i]);
        ASSERT_EQ(links[i].size(), 1u) << "link " << i;
        EXPECT_EQ(links[i][0].fromLane, m.from.id()) << "link " << i;
        EXPECT_EQ(links[i][0].toLane, m.to.id()) << "link " << i;
        EXPECT_EQ(m.tls_link_index, static_cast<int>(i));
      }
    }
    for (MovementId mid : x.movements) {
      const Movement& m = map.movement(mid);
      const SumoMovement& sm = e.movement(mid);
      EXPECT_EQ(sm.junction, id);
      EXPECT_EQ(sm.tls_link_index.has_value(), light);
      bool found = false;
      for (const auto& link : libsumo::Lane::getLinks(sm.from.id())) {
        if (link.approachedLane != sm.to.id()) continue;
        found = true;
        EXPECT_NEAR(ViaLength(link) / e.scale, m.length_m, 0.02 * m.length_m) << m.name;
      }
      EXPECT_TRUE(found) << m.name;
    }
  }
}

bool Contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

// Sends one car of the export's type through every movement, one at a time: it departs at the
// start of the ingress lane and must reach the egress lane within `max_steps` 0.1 s steps. At a
// traffic light only the movement's own link is green.
void DriveEveryMovement(const Map& map, const SumoExport& e, int max_steps = 1200) {
  int n = 0;
  for (const Intersection& x : map.intersections) {
    for (MovementId mid : x.movements) {
      const Movement& m = map.movement(mid);
      const SumoMovement& sm = e.movement(mid);
      SCOPED_TRACE(m.name);
      const std::string veh = "car" + std::to_string(n);
      const std::string route = "route" + std::to_string(n++);
      libsumo::Route::add(route, {sm.from.edge, sm.to.edge});
      libsumo::Vehicle::add(veh, route, e.vehicle_type, "now", std::to_string(sm.from.index),
                            "base", "0");
      if (sm.tls_link_index) {
        std::string state(x.movements.size(), 'r');
        state[static_cast<std::size_t>(*sm.tls_link_index)] = 'G';
        libsumo::TrafficLight::setRedYellowGreenState(sm.junction, state);
      }
      bool departed = false, arrived = false;
      for (int step = 0; step < max_steps && !arrived; ++step) {
        libsumo::Simulation::step();
        if (!Contains(libsumo::Vehicle::getIDList(), veh)) {
          if (departed) break;  // left the network without being seen on the egress lane
          continue;
        }
        if (!departed) {
          departed = true;
          EXPECT_EQ(libsumo::Vehicle::getLaneID(veh), sm.from.id());
        }
        arrived = libsumo::Vehicle::getLaneID(veh) == sm.to.id();
      }
      EXPECT_TRUE(departed);
      EXPECT_TRUE(arrived) << "not on " << sm.to.id() << " after " << max_steps << " steps";
      if (Contains(libsumo::Vehicle::getIDList(), veh)) libsumo::Vehicle::remove(veh);
      libsumo::Simulation::step();
    }
  }
}

TEST(SumoExport, FourWaySignalIsATrafficLightWithOneLinkPerMovementAndEveryMovementDrives) {
  const Map map = Build(FourWaySignal());
  const TempDir dir;
  const SumoExport e = ExportSumo(map, dir.str());
  ASSERT_EQ(map.intersections.size(), 1u);
  EXPECT_EQ(e.junctions.at(map.intersections[0].id), "x_r1c1");
  EXPECT_EQ(e.lanes.size(), map.lanes.size());
  EXPECT_EQ(e.movements.size(), 12u);
  Simulation sim(e);
  ExpectLanesMatch(map, e);
  ExpectIntersectionsMatch(map, e);
  EXPECT_EQ(libsumo::TrafficLight::getRedYellowGreenState("x_r1c1").size(), 12u);
  DriveEveryMovement(map, e);
}

TEST(SumoExport, EveryShippedMapLoadsInLibsumoAndEveryMovementDrives) {
  int maps = 0;
  for (const auto& entry :
       std::filesystem::directory_iterator(test::SourceDir() / "config" / "maps")) {
    if (entry.path().extension() != ".yaml") continue;
    SCOPED_TRACE(entry.path().string());
    const Map map = Build(LoadLayout(entry.path().string()));
    const TempDir dir;
    if (map.lanes.empty()) {
      // The Parking School is an open floor: no road network for SUMO.
      EXPECT_EQ(test::ErrorMessage([&] { (void)ExportSumo(map, dir.str()); }),
                "map \"" + map.name +
                    "\" has no lanes: there is no road network for SUMO "
                    "(open floors are not exported)");
      continue;
    }
    const SumoExport e = ExportSumo(map, dir.str());
    Simulation sim(e);
    ExpectLanesMatch(map, e);
    ExpectIntersectionsMatch(map, e);
    DriveEveryMovement(map, e);
    ++maps;
  }
  EXPECT_GE(maps, 2);  // driving school and small town
}

// A stop-controlled intersection is a traffic light (SUMO's allway_stop is not safe on these
// small boxes; the co-simulation runs it as an all-way stop), with one link per movement.
TEST(SumoExport,
     StopControlledTJunctionIsATrafficLightWithOneLinkPerMovementAndEveryMovementDrives) {
  const Map map = Build(TJunctionStop());
  const TempDir dir;
  const SumoExport e = ExportSumo(map, dir.str());
  ASSERT_EQ(map.intersections.size(), 1u);
  EXPECT_EQ(e.movements.size(), 6u);
  Simulation sim(e);
  ExpectLanesMatch(map, e);
  ExpectIntersectionsMatch(map, e);
  EXPECT_EQ(libsumo::TrafficLight::getIDList(),
            std::vector<std::string>{map.intersections[0].name});
  DriveEveryMovement(map, e);
}

// Drives a lap of the closed loop from `start` and checks that the distance driven is the sum
// of the map's lane lengths: plain junctions add (almost) nothing.
void DriveLap(const Map& map, const SumoExport& e, LaneId start, const std::string& veh) {
  std::vector<std::string> edges;
  double lap_m = 0;
  LaneId l = start;
  do {
    for (const auto& piece : e.lane_pieces.at(l)) edges.push_back(piece.edge);
    lap_m += map.lane(l).length_m;
    ASSERT_EQ(map.lane(l).successors.size(), 1u);
    l = map.lane(l).successors[0];
  } while (l != start && edges.size() < 100);
  ASSERT_EQ(l, start);
  edges.push_back(edges.front());
  libsumo::Route::add(veh + "_route", edges);
  libsumo::Vehicle::add(veh, veh + "_route", e.vehicle_type, "now",
                        std::to_string(e.lane(start).index), "base", "0");
  double d0 = -1, p0 = 0;
  bool left_start = false, done = false;
  for (int step = 0; step < 3000 && !done; ++step) {
    libsumo::Simulation::step();
    if (!Contains(libsumo::Vehicle::getIDList(), veh)) continue;
    const bool on_start = libsumo::Vehicle::getRoadID(veh) == edges.front();
    if (on_start && d0 < 0) {
      d0 = libsumo::Vehicle::getDistance(veh);
      p0 = libsumo::Vehicle::getLanePosition(veh);
    }
    if (!on_start && d0 >= 0) left_start = true;
    if (on_start && left_start) {
      const double lap =
          (libsumo::Vehicle::getDistance(veh) - d0) - (libsumo::Vehicle::getLanePosition(veh) - p0);
      EXPECT_NEAR(lap / e.scale, lap_m, 0.01 * lap_m);
      done = true;
    }
  }
  EXPECT_TRUE(done) << veh << " did not complete a lap";
  if (Contains(libsumo::Vehicle::getIDList(), veh)) libsumo::Vehicle::remove(veh);
}

TEST(SumoExport, ClosedLoopChainsLanesAcrossTileEdgesAndALapIsAsLongAsTheMapSays) {
  const Map map = Build(ClosedLoop());
  const TempDir dir;
  const SumoExport e = ExportSumo(map, dir.str());
  EXPECT_TRUE(e.junctions.empty());
  EXPECT_EQ(e.edges.size(), 8u);  // 4 tiles x 2 directions
  Simulation sim(e);
  ExpectLanesMatch(map, e);
  // Clockwise and counter-clockwise.
  DriveLap(map, e, map.lanes[0].id, "ccw");
  DriveLap(map, e, map.lanes[1].id, "cw");
}

TEST(SumoExport, MixedLayoutWithTurningLoopsAtIntersectionArmsDrivesEveryMovement) {
  const Map map = Build(Mixed());
  const TempDir dir;
  const SumoExport e = ExportSumo(map, dir.str());
  ASSERT_EQ(map.intersections.size(), 2u);
  // Road ends and the parking loop are split in two SUMO edges.
  std::size_t loops = 0;
  for (const auto& [lane, pieces] : e.lane_pieces) loops += pieces.size() == 2 ? 1u : 0u;
  EXPECT_EQ(loops, 3u);
  EXPECT_EQ(e.lane_pieces.at(map.lanes.back().id).size(), 2u);  // end@270 is the last tile
  Simulation sim(e);
  ExpectLanesMatch(map, e);
  ExpectIntersectionsMatch(map, e);
  DriveEveryMovement(map, e);
}

TEST(SumoExport, TwoLaneRoadsCountLanesFromTheKerbAndEveryMovementDrives) {
  for (const Layout& layout : {TwoLaneFourWay(), TwoLaneLoop()}) {
    const Map map = Build(layout);
    const TempDir dir;
    const SumoExport e = ExportSumo(map, dir.str());
    // Map lane k of two is SUMO lane 1 - k.
    for (const Lane& lane : map.lanes) {
      EXPECT_EQ(e.lane(lane.id).index, 1 - lane.index_from_centre) << lane.name;
    }
    Simulation sim(e);
    ExpectLanesMatch(map, e);
    ExpectIntersectionsMatch(map, e);
    DriveEveryMovement(map, e);
  }
}

TEST(SumoExport, WritesItsFilesIntoTheOutputDirectoryOnly) {
  Layout l = FourWaySignal();
  l.name = "lab one";
  const Map map = Build(l);
  const TempDir tmp;
  const fs::path dir = tmp.path() / "out";  // created by ExportSumo
  const SumoExport e = ExportSumo(map, dir.string());
  std::set<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.insert(entry.path().filename());
  EXPECT_EQ(names,
            (std::set<std::string>{"lab_one.nod.xml", "lab_one.edg.xml", "lab_one.con.xml",
                                   "lab_one.tll.xml", "lab_one.net.xml", "lab_one.vtypes.xml",
                                   "lab_one.sumocfg", "lab_one.netconvert.log"}));
  EXPECT_EQ(e.net_file, dir / "lab_one.net.xml");
  EXPECT_EQ(std::distance(fs::directory_iterator(tmp.path()), fs::directory_iterator()), 1);
  ASSERT_GE(e.netconvert_command.size(), 2u);
  EXPECT_EQ(e.netconvert_command[0], "netconvert");
}

// Parses the XML file at `path` with pugixml, comments included, into `doc`; a fatal failure
// when it does not parse.
void LoadXml(const fs::path& path, pugi::xml_document& doc) {
  const pugi::xml_parse_result result =
      doc.load_file(path.c_str(), pugi::parse_default | pugi::parse_comments);
  ASSERT_EQ(result.status, pugi::status_ok)
      << path << ": " << result.description() << " at offset " << result.offset;
}

std::string Attribute(pugi::xml_node node, const char* name) {
  return node.attribute(name).value();
}

TEST(SumoExport, PlainXmlFilesOfAMapWithXmlSpecialCharactersInItsNameParseAndGiveBackItsIds) {
  Layout l = Mixed();
  l.name = "lab <A> & \"B\" 'C'";
  const Map map = Build(l);
  const TempDir tmp;
  const SumoExport e = ExportSumo(map, tmp.str());
  EXPECT_EQ(e.node_file, tmp.path() / "lab__A_____B___C_.nod.xml");
  pugi::xml_document nodes, edges, connections, lights, vtypes, net;
  ASSERT_NO_FATAL_FAILURE(LoadXml(e.node_file, nodes));
  ASSERT_NO_FATAL_FAILURE(LoadXml(e.edge_file, edges));
  ASSERT_NO_FATAL_FAILURE(LoadXml(e.connection_file, connections));
  ASSERT_NO_FATAL_FAILURE(LoadXml(e.tll_file, lights));
  ASSERT_NO_FATAL_FAILURE(LoadXml(e.vtype_file, vtypes));
  ASSERT_NO_FATAL_FAILURE(LoadXml(e.net_file, net));

  // Every intersection is a node of its type, named like the intersection.
  for (const Intersection& x : map.intersections) {
    SCOPED_TRACE(x.name);
    const pugi::xml_node node =
        nodes.child("nodes").find_child_by_attribute("node", "id", x.name.c_str());
    ASSERT_FALSE(node.empty());
    EXPECT_EQ(Attribute(node, "type"),
              x.control == Control::kSignal ? "traffic_light" : "right_before_left");
    EXPECT_FALSE(
        net.child("net").find_child_by_attribute("junction", "id", x.name.c_str()).empty());
  }
  // The edges are the export's, with their lane counts.
  std::map<std::string, std::size_t> edge_lanes;
  for (pugi::xml_node edge : edges.child("edges").children("edge")) {
    edge_lanes[Attribute(edge, "id")] = edge.attribute("numLanes").as_uint();
  }
  std::map<std::string, std::size_t> expected_lanes;
  for (const auto& [id, lanes] : e.edges) expected_lanes[id] = lanes.size();
  EXPECT_EQ(edge_lanes, expected_lanes);
  // Every movement is a connection after a comment with its name (which holds '>').
  std::vector<std::string> named;
  for (pugi::xml_node c : connections.child("connections").children()) {
    if (c.type() != pugi::node_comment) continue;
    const std::string text = c.value();
    ASSERT_GE(text.size(), 2u);
    const std::string name = text.substr(1, text.size() - 2);
    const auto m = std::find_if(map.movements.begin(), map.movements.end(),
                                [&](const Movement& mv) { return mv.name == name; });
    ASSERT_NE(m, map.movements.end()) << "no movement named \"" << name << "\"";
    const SumoMovement& sm = e.movement(m->id);
    const pugi::xml_node connection = c.next_sibling();
    EXPECT_STREQ(connection.name(), "connection") << name;
    EXPECT_EQ(Attribute(connection, "from"), sm.from.edge) << name;
    EXPECT_EQ(Attribute(connection, "to"), sm.to.edge) << name;
    EXPECT_EQ(connection.attribute("fromLane").as_int(-1), sm.from.index) << name;
    EXPECT_EQ(connection.attribute("toLane").as_int(-1), sm.to.index) << name;
    named.push_back(name);
  }
  std::vector<std::string> expected_names;
  for (const Movement& m : map.movements) expected_names.push_back(m.name);
  EXPECT_EQ(named, expected_names);
  // The signalised intersection's program, and the car type.
  std::vector<std::string> programs;
  for (pugi::xml_node t : lights.child("tlLogics").children("tlLogic")) {
    programs.push_back(Attribute(t, "id"));
  }
  EXPECT_EQ(programs, std::vector<std::string>{"x_r2c1"});
  EXPECT_EQ(Attribute(vtypes.child("additional").child("vType"), "id"), e.vehicle_type);
}

TEST(SumoExportErrors, MissingNetconvertNamesTheProgramAndTheCommand) {
  SumoOptions o;
  o.netconvert = "/nonexistent/netconvert";
  const Map map = Build(ClosedLoop());
  const TempDir tmp;
  const std::string dir = tmp.str();
  const std::string msg = test::ErrorMessage([&] { (void)ExportSumo(map, dir, o); });
  EXPECT_NE(msg.find("cannot run netconvert: \"/nonexistent/netconvert\" is not an executable "
                     "file nor on PATH"),
            std::string::npos)
      << msg;
  EXPECT_NE(msg.find("command: /nonexistent/netconvert --node-files " + dir + "/sumo_test.nod.xml"),
            std::string::npos)
      << msg;
}

TEST(SumoExportErrors, FailingNetconvertReportsItsOutputAndTheCommand) {
  SumoOptions o;
  o.extra_netconvert_args = {"--no-such-option", "1"};
  const Map map = Build(ClosedLoop());
  const TempDir tmp;
  const std::string dir = tmp.str();
  const std::string msg = test::ErrorMessage([&] { (void)ExportSumo(map, dir, o); });
  EXPECT_EQ(msg.rfind("netconvert failed (exit code 1) on map \"sumo_test\"; command: netconvert "
                      "--node-files ",
                      0),
            0u)
      << msg;
  EXPECT_NE(msg.find("--no-such-option 1\nits output:\n"), std::string::npos) << msg;
  EXPECT_NE(msg.find("no-such-option"), msg.rfind("no-such-option")) << msg;  // also its output
}

TEST(SumoExportErrors, IntersectionNamesMustBeValidAndUniqueSumoIds) {
  const TempDir tmp;
  const std::string dir = tmp.str();
  Layout bad = FourWaySignal();
  bad.grid[1][1] = Cell::FromConfigString("x4 name=main|north");
  EXPECT_EQ(test::ErrorMessage([&] { (void)ExportSumo(Build(bad), dir); }),
            "intersection r1c1 is named \"main|north\", which is not a valid SUMO id (it must not "
            "start with ':' nor contain spaces or any of |\\'\";,<>&)");
  Layout twice = MakeLayout({{"empty", "straight@90", "empty", "straight@90", "empty"},
                             {"straight", "x4 name=main", "straight", "x4 name=main", "straight"},
                             {"empty", "straight@90", "empty", "straight@90", "empty"}});
  EXPECT_EQ(test::ErrorMessage([&] { (void)ExportSumo(Build(twice), dir); }),
            "two intersections are named \"main\" (tile r1c3); SUMO junction ids must be unique");
  Layout clash = FourWaySignal();
  clash.grid[1][1] = Cell::FromConfigString("x4 name=n_r1c0_W");  // the map's west edge
  EXPECT_EQ(test::ErrorMessage([&] { (void)ExportSumo(Build(clash), dir); }),
            "an intersection is named \"n_r1c0_W\", which is the SUMO junction id of a tile edge "
            "or turning loop; rename it");
  Layout control = FourWaySignal();
  control.grid[1][1] = Cell::FromConfigString("x4 name=main\x01");
  EXPECT_EQ(test::ErrorMessage([&] { (void)ExportSumo(Build(control), dir); }),
            "attribute id of <node> \"main\\x01\" holds the control character 0x01, which XML "
            "cannot carry");
  SumoOptions o;
  o.speed_mps = 0;
  EXPECT_EQ(test::ErrorMessage([&] { (void)ExportSumo(Build(twice), dir, o); }),
            "SumoOptions.speed_mps must be > 0, got 0");
  EXPECT_TRUE(fs::is_empty(dir));
}

}  // namespace
}  // namespace autodrive::maps
