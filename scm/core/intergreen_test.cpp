// The intergreen matrix from the map's paths (scm/core/intergreen.h) against the hand figures
// of the controller research (../shared/research/controller.md §3.3) for the Driving School's
// crossing: eastbound through clearing, northbound through entering.
#include "scm/core/intergreen.h"

#include <gtest/gtest.h>

#include "common/config.h"
#include "common/error.h"
#include "common/test_support.h"
#include "scm/core/conflict_monitor.h"

namespace autodrive::scm {
namespace {

class Intergreen : public ::testing::Test {
 protected:
  void SetUp() override {
    city_ = LoadCity(test::SourceDir() / "config" / "cities" / "driving_school.yaml");
  }
  /// The through movement from the approach on `side`.
  MovementId Through(maps::Side side) const {
    const maps::Intersection& x = city_.map.intersections.front();
    for (const MovementId id : x.movements) {
      const maps::Movement& m = city_.map.movement(id);
      const auto& a = x.approaches[m.from_approach.value() - 1];
      if (m.turn == maps::Turn::kStraight && a.side == side) return id;
    }
    ADD_FAILURE() << "no through movement";
    return MovementId{0};
  }
  City city_;
};

TEST_F(Intergreen, TheCrossingThroughsGiveTheHandFiguresOfTheResearch) {
  const MovementId eastbound = Through(maps::Side::kWest);  // comes from the west
  const MovementId northbound = Through(maps::Side::kSouth);
  IntergreenInputs inputs;
  inputs.entering_speed_mps = 0.26;
  inputs.crossing_time_s = 0.0;
  const ClearingVehicleConfig nigel{"nigel", 0.318, 0.26};
  const IntergreenEntry e = MovementIntergreen(city_.map, eastbound, northbound, nigel, inputs);
  // s_clear: 0.65 m to the crossing point and 0.15 m (half a lane) past it; s_enter: 0.2 m.
  EXPECT_NEAR(e.clearing_path_m, 0.80, 0.01);
  EXPECT_NEAR(e.entering_path_m, 0.20, 0.01);
  EXPECT_NEAR(e.clearing_time_s, 4.3, 0.1) << "(0.80 + 0.318) / 0.26";
  EXPECT_NEAR(e.entering_time_s, 0.8, 0.1) << "0.20 / 0.26";
  EXPECT_DOUBLE_EQ(e.intergreen_s, 3.6) << "4.30 - 0.77, up to a tenth";
  EXPECT_DOUBLE_EQ(e.ite_s, 5.1) << "(1.0 + 0.318) / 0.26";
  // With t_cross the 3 s yellow, and at Nigel's typical 0.2 m/s.
  inputs.crossing_time_s = 3.0;
  EXPECT_DOUBLE_EQ(MovementIntergreen(city_.map, eastbound, northbound, nigel, inputs).intergreen_s,
                   6.6);
  const IntergreenEntry slow =
      MovementIntergreen(city_.map, eastbound, northbound, {"nigel", 0.318, 0.2}, inputs);
  EXPECT_NEAR(slow.clearing_time_s, 5.6, 0.1);
  EXPECT_DOUBLE_EQ(slow.ite_s, 6.6);
  // Paths that never come within half a lane: the ITE figure, no zone.
  const MovementId westbound = Through(maps::Side::kEast);
  const IntergreenEntry apart = MovementIntergreen(city_.map, eastbound, westbound, nigel, inputs);
  EXPECT_EQ(apart.clearing_path_m, 0.0);
  EXPECT_EQ(apart.intergreen_s, apart.ite_s);
}

TEST_F(Intergreen, TheMatrixHasAnEntryForEachConflictingPairTheWorstOfItsMovementsAndVehicles) {
  const IntersectionModel& x = city_.intersections.front();
  IntergreenInputs inputs;
  inputs.clearing_vehicles = {{"nigel", 0.318, 0.26}, {"bus", 0.857, 0.2}};
  const auto matrix = ComputeIntergreens(city_.map, x, inputs);
  ASSERT_EQ(matrix.size(), x.groups.size());
  for (std::size_t a = 0; a < x.groups.size(); ++a) {
    for (std::size_t b = 0; b < x.groups.size(); ++b) {
      EXPECT_EQ(matrix[a][b].has_value(), a != b && x.conflicts[a][b]) << a << " " << b;
      if (!matrix[a][b]) continue;
      const IntergreenEntry& e = *matrix[a][b];
      EXPECT_EQ(e.clearing, a);
      EXPECT_EQ(e.entering, b);
      EXPECT_EQ(e.vehicle, "bus") << "the slower, longer vehicle decides";
      EXPECT_TRUE(city_.map.Conflict(e.clearing_movement, e.entering_movement));
      EXPECT_GT(e.clearing_path_m, 0.0) << "decided by a pair that meets on the map";
      // No pair of the two groups' conflicting movements needs more than the entry.
      for (const MovementId ma : x.groups[a].movements) {
        for (const MovementId mb : x.groups[b].movements) {
          if (!city_.map.Conflict(ma, mb)) continue;
          for (const auto& v : inputs.clearing_vehicles) {
            EXPECT_LE(MovementIntergreen(city_.map, ma, mb, v, inputs).intergreen_s,
                      e.intergreen_s);
          }
        }
      }
    }
  }
}

/// The Driving School's file with `from` replaced by `to` (once; it must be there).
std::string EditedDrivingSchool(const std::string& from, const std::string& to) {
  std::string text = config::ReadFile(test::SourceDir() / "config/cities/driving_school.yaml");
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

TEST_F(Intergreen, TheModelCarriesTheMatrixInLabTime) {
  const IntersectionModel& x = city_.intersections.front();
  IntergreenInputs inputs;
  inputs.clearing_vehicles = city_.config.safety.clearing_vehicles;
  inputs.entering_speed_mps = city_.config.safety.entering_speed_mps;
  inputs.crossing_time_s = city_.config.safety.crossing_time_s;
  const auto matrix = ComputeIntergreens(city_.map, x, inputs);
  ASSERT_EQ(x.intergreens.size(), x.groups.size());
  for (std::size_t a = 0; a < x.groups.size(); ++a) {
    for (std::size_t b = 0; b < x.groups.size(); ++b) {
      EXPECT_EQ(x.intergreens[a][b],
                matrix[a][b] ? FromSeconds(matrix[a][b]->intergreen_s) : Duration{0});
      if (matrix[a][b]) {
        EXPECT_GT(x.intergreens[a][b], Duration{0});
      }
    }
  }
}

TEST_F(Intergreen, AClearanceBelowTheMatrixIsRefusedNamingThePairAndBothFigures) {
  // A 5 s crossing time (vehicles may cross their stop line 5 s into the yellow) makes the
  // crossing throughs' intergreen 5 + (0.80 + 0.318) / 0.2 - 0.20 / 0.26 = 9.8 s, beside the
  // shipped clearance of 3 s yellow + 7 s red clearance = 10 s: allowed. 6 s makes it 10.8 s.
  const auto dir = test::SourceDir() / "config/cities";
  EXPECT_NO_THROW((void)LoadCityString(
      EditedDrivingSchool("crossing_time_s: 3.0", "crossing_time_s: 4.0"), "four.yaml", dir));
  try {
    (void)LoadCityString(EditedDrivingSchool("crossing_time_s: 3.0", "crossing_time_s: 5.0"),
                         "five.yaml", dir);
    FAIL() << "a clearance under the intergreen matrix loaded";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("five.yaml: intersections[0] (driving_school_crossing): groups 1 (east) "
                        "> 2 (north): the clearance of group 1, yellow 3 s + red clearance 7 s = "
                        "10 s, is below the intergreen 10.8 s the map gives"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("rule: a clearance may exceed the intergreen matrix, never undercut it"),
              std::string::npos)
        << what;
  }
}

TEST_F(Intergreen, TheConflictMonitorHoldsAGreenToTheIntergreenOfEachConflictingGroup) {
  // A model whose matrix asks more than its groups' yellow + red clearance (no city file loads
  // so; the monitor judges by the matrix it is given): 3 s + 7 s against 12 s from group 1
  // (east) to group 2 (north).
  IntersectionModel x = city_.intersections.front();
  ASSERT_TRUE(x.conflicts[0][1]);
  x.intergreens[0][1] = std::chrono::seconds(12);
  const Aspect R = Aspect::kRed, Y = Aspect::kYellow, G = Aspect::kGreen;
  MonoTime now{std::chrono::hours(1)};
  ConflictMonitor monitor(x, now);
  ASSERT_FALSE(monitor.CheckAndRecord(now, {R, R, R, R}));
  now += std::chrono::seconds(8);
  ASSERT_FALSE(monitor.CheckAndRecord(now, {G, R, R, R}));
  now += std::chrono::seconds(8);
  ASSERT_FALSE(monitor.CheckAndRecord(now, {Y, R, R, R}));  // group 1's green ends
  now += std::chrono::seconds(3);
  ASSERT_FALSE(monitor.CheckAndRecord(now, {R, R, R, R}));
  now += std::chrono::seconds(8);  // 11 s after group 1's green: red clearance served
  const auto v = monitor.CheckAndRecord(now, {R, G, R, R});
  ASSERT_TRUE(v);
  EXPECT_EQ(v->rule, "short_intergreen");
  EXPECT_EQ(v->message,
            "driving_school_crossing: group 2 (north) turned green 11.000 s after conflicting "
            "group 1 (east)'s green ended, under their intergreen 12.000 s; rule: intergreen "
            "matrix");
  // Pairwise: group 3 (west), which conflicts with group 1 too, is held to its own entry.
  ASSERT_TRUE(x.conflicts[0][2]);
  ASSERT_LE(x.intergreens[0][2], std::chrono::seconds(11));
  EXPECT_FALSE(monitor.Check(now, {R, R, G, R}));
  now += std::chrono::seconds(1);
  EXPECT_FALSE(monitor.CheckAndRecord(now, {R, G, R, R}));  // 12 s: fine
}

}  // namespace
}  // namespace autodrive::scm
