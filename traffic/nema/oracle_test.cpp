// The intergreen collision oracle's parts that need no SUMO run: its vehicle types and flows
// from the city, and the intergreens altered in memory (the negative control).
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>
#include <string>

#include <pugixml.hpp>

#include "traffic/nema/collision_oracle.h"
#include "traffic/nema/oracle_traffic.h"

#include "common/error.h"
#include "common/test_support.h"
#include "maps/sumo.h"
#include "scm/core/city.h"

namespace autodrive::traffic::nema {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

const scm::City& City(const std::string& name) {
  static std::map<std::string, scm::City> cities;
  auto it = cities.find(name);
  if (it == cities.end()) {
    it =
        cities.emplace(name, scm::LoadCity(test::SourceDir() / ("config/cities/" + name + ".yaml")))
            .first;
  }
  return it->second;
}

class TempDir : public test::TempDir {
 public:
  TempDir() : test::TempDir("traffic_nema_oracle_test") {}
};

TEST(OracleTraffic, TypesAreTheSlowestClearingVehicleAndTheEnteringSpeedAtTheFastestAccelX14) {
  const OracleTraffic t = OracleTypesOf(City("driving_school"), maps::kSumoScale);
  ASSERT_EQ(t.types.size(), 2u);
  const OracleVehicleType& clearing = t.types[0];
  const OracleVehicleType& entering = t.types[1];
  EXPECT_EQ(clearing.id, "clearing");
  EXPECT_EQ(entering.id, "entering");
  // safety.clearing_vehicles: a Nigel (0.318 m) at 0.2 m/s; entering 0.26 m/s (the default).
  EXPECT_NEAR(clearing.max_speed_mps, 0.2 * 14, 1e-9);
  EXPECT_NEAR(clearing.length_m, 0.318 * 14, 1e-9);
  EXPECT_NEAR(entering.max_speed_mps, 0.26 * 14, 1e-9);
  // The co-simulation's fastest declared acceleration: Nigel's 0.5 m/s^2 (the bus has 0.3).
  EXPECT_NEAR(t.fastest_accel_mps2, 0.5, 1e-12);
  EXPECT_NEAR(clearing.accel_mps2, 7.0, 1e-9);
  EXPECT_NEAR(entering.accel_mps2, 7.0, 1e-9);
  // They drive through the whole yellow (3 s), and the roads let both run at their own speed.
  EXPECT_EQ(clearing.drive_after_yellow, seconds(3));
  EXPECT_EQ(entering.drive_after_yellow, seconds(3));
  EXPECT_GT(t.road_speed_mps * 14, entering.max_speed_mps);
  EXPECT_EQ(t.clearing_vehicle, "nigel");
}

TEST(OracleTraffic, ASlowerLongerClearingVehicleIsTheOneTheTypeTakes) {
  scm::City city = City("driving_school");
  city.config.safety.clearing_vehicles = {{"nigel", 0.318, 0.2}, {"bus", 0.857, 0.15}};
  const OracleTraffic t = OracleTypesOf(city, 14.0);
  EXPECT_EQ(t.clearing_vehicle, "bus");
  EXPECT_NEAR(t.types[0].max_speed_mps, 0.15 * 14, 1e-9);
  EXPECT_NEAR(t.types[0].length_m, 0.857 * 14, 1e-9);
  city.config.safety.clearing_vehicles.clear();
  try {
    (void)OracleTypesOf(city, 14.0);
    FAIL() << "no clearing vehicle accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("safety.clearing_vehicles"), std::string::npos)
        << e.what();
  }
}

TEST(OracleTraffic, EveryConflictingMovementHasAFlowOfEachTypeSharingItsLanesArrivals) {
  const TempDir dir;
  const scm::City& city = City("small_town");
  const maps::SumoExport net = maps::ExportSumo(city.map, dir.str());
  OracleTrafficParams params;
  params.begin = seconds(10);
  params.end = seconds(3600);
  params.headway = seconds(6);
  const OracleTraffic t = OracleTrafficOf(city, net, params);
  std::size_t movements = 0;
  for (const scm::IntersectionModel& x : city.intersections) {
    for (const scm::SignalGroup& g : x.groups) movements += g.movements.size();
  }
  ASSERT_EQ(t.flows.size(), 2 * movements);  // every group of both conflicts with another
  std::map<std::string, double> per_lane;    // SUMO lane: probability per second
  std::set<std::string> ids;
  for (const OracleFlow& f : t.flows) {
    SCOPED_TRACE(f.id);
    EXPECT_TRUE(ids.insert(f.id).second);
    const maps::SumoMovement& m = net.movement(f.movement);
    EXPECT_EQ(f.from_edge, m.from.edge);
    EXPECT_EQ(f.to_edge, m.to.edge);
    EXPECT_EQ(f.depart_lane, m.from.index);
    EXPECT_EQ(m.junction, f.intersection);
    EXPECT_EQ(t.FlowOfVehicle(f.id + ".12"), &f);
    per_lane[m.from.id()] += f.probability_per_s;
  }
  for (const auto& [lane, p] : per_lane) EXPECT_NEAR(p, 1.0 / 6, 1e-9) << lane;

  // One intersection only; an unknown one is named with the city's.
  params.intersection = "north_t";
  for (const OracleFlow& f : OracleTrafficOf(city, net, params).flows) {
    EXPECT_EQ(f.intersection, "north_t");
  }
  params.intersection = "nowhere";
  try {
    (void)OracleTrafficOf(city, net, params);
    FAIL() << "an unknown intersection accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("centre"), std::string::npos) << e.what();
  }
}

TEST(OracleTraffic, TheRouteFileTrustsTheSignalThroughTheYellow) {
  const TempDir dir;
  const scm::City& city = City("driving_school");
  OracleTrafficParams params;
  params.begin = seconds(10);
  params.end = seconds(600);
  const OracleTraffic t = OracleTrafficOf(city, maps::ExportSumo(city.map, dir.str()), params);
  pugi::xml_document doc;
  ASSERT_TRUE(doc.load_string(OracleRoutesXml(t).c_str()));
  int types = 0;
  for (pugi::xml_node v : doc.child("routes").children("vType")) {
    ++types;
    EXPECT_STREQ(v.attribute("jmIgnoreJunctionFoeProb").as_string(), "1");
    EXPECT_STREQ(v.attribute("jmIgnoreFoeProb").as_string(), "1");
    EXPECT_STREQ(v.attribute("jmDriveAfterYellowTime").as_string(), "3");
    EXPECT_STREQ(v.attribute("sigma").as_string(), "0");
  }
  EXPECT_EQ(types, 2);
  int flows = 0;
  for (pugi::xml_node f : doc.child("routes").children("flow")) {
    ++flows;
    EXPECT_STREQ(f.attribute("begin").as_string(), "10");
    EXPECT_STREQ(f.attribute("end").as_string(), "600");
    EXPECT_FALSE(std::string(f.child("route").attribute("edges").as_string()).empty());
  }
  EXPECT_EQ(flows, 24);  // 12 movements, 2 types
}

TEST(ChangeIntergreens, HalvingKeepsTheYellowCutsTheRedAndTheMatrixAndShortensTheCycle) {
  scm::City city = City("driving_school");
  const scm::IntersectionModel before = city.intersections.front();
  const auto notes =
      ChangeIntergreens(city, {IntergreenChange::Kind::kScale, 0.5}, milliseconds(100));
  const scm::IntersectionModel& x = city.intersections.front();
  for (const scm::SignalGroup& g : x.groups) {
    EXPECT_EQ(g.timing.yellow, seconds(3));
    EXPECT_EQ(g.timing.red_clearance, seconds(2));  // (3 + 7) / 2 - 3
  }
  for (std::size_t a = 0; a < x.groups.size(); ++a) {
    for (std::size_t b = 0; b < x.groups.size(); ++b) {
      const Duration half = before.intergreens[a][b] / 2;
      EXPECT_EQ(x.intergreens[a][b], half - half % milliseconds(100));
    }
  }
  const scm::Plan& day = x.plans[*x.PlanIndex("day")];
  EXPECT_EQ(day.cycle, seconds(4 * (8 + 5)));
  EXPECT_EQ(day.phase_starts[1], seconds(13));
  ASSERT_FALSE(notes.empty());
  EXPECT_NE(notes.front().find("-> 3 s + 2 s = 5 s"), std::string::npos) << notes.front();
}

TEST(ChangeIntergreens, AFactorBelowTheYellowCutsItAndTheMatrixEntryIsTheLeastTheLoaderWants) {
  scm::City scaled = City("driving_school");
  (void)ChangeIntergreens(scaled, {IntergreenChange::Kind::kScale, 0.2}, milliseconds(100));
  EXPECT_EQ(scaled.intersections.front().groups[0].timing.yellow, seconds(2));
  EXPECT_EQ(scaled.intersections.front().groups[0].timing.red_clearance, seconds(0));

  scm::City at_matrix = City("driving_school");
  (void)ChangeIntergreens(at_matrix, {IntergreenChange::Kind::kMatrix, 1.0}, milliseconds(100));
  const scm::IntersectionModel& x = at_matrix.intersections.front();
  for (std::size_t g = 0; g < x.groups.size(); ++g) {
    Duration row{0};
    for (Duration e : x.intergreens[g]) row = std::max(row, e);
    EXPECT_GT(row, seconds(3));
    EXPECT_EQ(x.groups[g].timing.yellow + x.groups[g].timing.red_clearance, row);
    EXPECT_EQ(x.groups[g].timing.yellow, seconds(3));
  }

  scm::City bad = City("driving_school");
  try {
    (void)ChangeIntergreens(bad, {IntergreenChange::Kind::kScale, 1.5}, milliseconds(100));
    FAIL() << "a factor above 1 accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("1.5"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace autodrive::traffic::nema
