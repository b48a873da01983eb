#include "scm/core/city.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <regex>

#include "common/test_support.h"

namespace autodrive::scm {
namespace {

using ::testing::HasSubstr;

std::filesystem::path CitiesDir() { return test::SourceDir() / "config" / "cities"; }

TEST(City, EveryShippedCityLoads) {
  int count = 0;
  for (const auto& entry : std::filesystem::directory_iterator(CitiesDir())) {
    if (entry.path().extension() != ".yaml") continue;
    SCOPED_TRACE(entry.path().string());
    const City city = LoadCity(entry.path());
    // Signalised intersections where the map has signal heads (the Parking School has none).
    EXPECT_EQ(city.intersections.empty(), city.map.signal_heads.empty());
    ++count;
  }
  EXPECT_GE(count, 2);
}

TEST(City, DrivingSchoolHasFourSplitPhasedGroups) {
  const City city = LoadCity(CitiesDir() / "driving_school.yaml");
  ASSERT_EQ(city.intersections.size(), 1u);
  const auto& x = city.intersections[0];
  EXPECT_EQ(x.name, "driving_school_crossing");
  ASSERT_EQ(x.groups.size(), 4u);
  for (std::size_t a = 0; a < 4; ++a) {
    EXPECT_EQ(x.groups[a].heads.size(), 1u);
    EXPECT_EQ(x.groups[a].movements.size(), 3u);  // left, through, right
    for (std::size_t b = 0; b < 4; ++b) EXPECT_EQ(x.conflicts[a][b], a != b) << a << "," << b;
  }
  const auto& day = x.plans[*x.PlanIndex("day")];
  EXPECT_EQ(day.cycle, std::chrono::seconds(4 * (8 + 3 + 7)));
  EXPECT_EQ(x.ScheduledPlan(5 * 60), *x.PlanIndex("evening"));
  EXPECT_EQ(x.ScheduledPlan(12 * 60), *x.PlanIndex("day"));
  EXPECT_EQ(x.ScheduledPlan(21 * 60), *x.PlanIndex("evening"));
  EXPECT_EQ(x.plans[*x.PlanIndex("evening")].detectors.size(), 4u);
}

TEST(City, ConfigRoundTrips) {
  for (const char* name : {"driving_school.yaml", "small_town.yaml"}) {
    const City city = LoadCity(CitiesDir() / name);
    const std::string saved = config::SaveString(city.config);
    EXPECT_EQ(config::LoadString<CityConfig>(saved), city.config) << name;
  }
}

/// Loads the Driving School config with `edits` (from, to) applied to its text.
std::string LoadError(const std::vector<std::pair<std::string, std::string>>& edits) {
  std::string text = config::ReadFile(CitiesDir() / "driving_school.yaml");
  for (const auto& [from, to] : edits) {
    const auto pos = text.find(from);
    EXPECT_NE(pos, std::string::npos) << from;
    if (pos == std::string::npos) return "";
    text.replace(pos, from.size(), to);
  }
  return test::ErrorMessage<ConfigError>(
      [&] { (void)LoadCityString(text, "city.yaml", CitiesDir()); });
}

std::string LoadError(const std::string& from, const std::string& to) {
  return LoadError({{from, to}});
}

TEST(City, RefusesTwoPublishersOfTheIpsTopics) {
  // The Driving School runs its cars in the simulator, which publishes their ips topics: the
  // Eye may not publish them too.
  EXPECT_THAT(LoadError("eye:\n  cameras:", "eye:\n  outputs: {ips: true}\n  cameras:"),
              HasSubstr("eye.outputs.ips: the simulator (the sim section) publishes every car's "
                        "ips topic, so the Eye may not"));
  // Without the simulator's cars the Eye is the lab's IPS.
  const std::string text = config::ReadFile(CitiesDir() / "driving_school.yaml");
  std::string eye_only = text.substr(0, text.find("\nsim:\n")) + text.substr(text.find("\neye:\n"));
  eye_only.replace(eye_only.find("eye:\n  cameras:"), 15,
                   "eye:\n  outputs: {ips: true}\n  cameras:");
  EXPECT_NO_THROW((void)LoadCityString(eye_only, "city.yaml", CitiesDir()));
}

TEST(City, RefusesARedClearanceBelowTheIteFigureForItsClearingVehicles) {
  // The Driving School's left turn is 1.021 m through the box: a Nigel (0.318 m) at 0.2 m/s
  // needs (1.021 + 0.318) / 0.2 = 6.69 s to clear it.
  EXPECT_THAT(LoadError("red_clearance_s: 7.0}", "red_clearance_s: 6.5}"),
              HasSubstr("groups[0] (east): group 1 (east): red clearance 6.5 s is below the ITE "
                        "figure (1.021 m through the box on r2c2:E>S:0>0 + nigel 0.318 m) / "
                        "0.20 m/s = 6.69 s"));
  // A slower vehicle raises the figure; it is the vehicles' worst that counts.
  EXPECT_THAT(LoadError("    - {name: nigel, length_m: 0.318, speed_mps: 0.2}",
                        "    - {name: nigel, length_m: 0.318, speed_mps: 0.2}\n"
                        "    - {name: bus, length_m: 0.857, speed_mps: 0.2}"),
              HasSubstr("red clearance 7 s is below the ITE figure (1.021 m through the box on "
                        "r2c2:E>S:0>0 + bus 0.857 m) / 0.20 m/s = 9.39 s"));
  // A group's own red clearance is checked too, and naming none means the figure.
  EXPECT_THAT(LoadError("{id: 2, name: north, approaches: [north]}",
                        "{id: 2, name: north, approaches: [north], timing: {red_clearance_s: 3}}"),
              HasSubstr("group 2 (north): red clearance 3 s is below the ITE figure"));
  std::string text = config::ReadFile(CitiesDir() / "driving_school.yaml");
  text.replace(text.find(", red_clearance_s: 7.0}"), 23, "}");
  text.replace(text.find("all_red_s: 7.0"), 14, "flash_s: 3.0");
  text.replace(text.find("{flash_s: 3.0, "), 15, "{");
  const City city = LoadCityString(text, "city.yaml", CitiesDir());
  for (const auto& g : city.intersections[0].groups) {
    EXPECT_EQ(g.timing.red_clearance, std::chrono::milliseconds(6700)) << g.name;
  }
  EXPECT_EQ(city.intersections[0].startup_all_red, std::chrono::milliseconds(6700));
  EXPECT_THAT(
      LoadError("  clearing_vehicles:\n    - {name: nigel, length_m: 0.318, speed_mps: 0.2}",
                "  clearing_vehicles: []"),
      HasSubstr("safety.clearing_vehicles: is empty"));
}

TEST(City, RefusesConflictingGroupsInOnePhase) {
  EXPECT_EQ(LoadError("- {groups: [1], green_s: 8.0}", "- {groups: [1, 2], green_s: 8.0}"),
            "city.yaml: intersections[0] (driving_school_crossing).plans[0] (day).phases[0]: "
            "groups 1 (east) and 2 (north) conflict; rule: conflicting groups are never green or "
            "yellow together");
}

TEST(City, RefusesShortYellowAllRedAndGreen) {
  EXPECT_THAT(LoadError("yellow_s: 3.0, red", "yellow_s: 2.5, red"),
              HasSubstr("groups[0] (east): group 1 (east): yellow 2.5 s is below the minimum 3 "
                        "s; rule: minimum yellow"));
  // Below the floor (with a clearing vehicle fast enough for the ITE figure to allow it).
  EXPECT_THAT(LoadError({{"red_clearance_s: 7.0}", "red_clearance_s: 0.5}"},
                         {"length_m: 0.318, speed_mps: 0.2", "length_m: 0.1, speed_mps: 10"}}),
              HasSubstr("red clearance 0.5 s is below the minimum 1 s; rule: minimum all-red"));
  EXPECT_THAT(LoadError("min_green_s: 5.0", "min_green_s: 2.0"),
              HasSubstr("min green 2 s is below the minimum 4 s; rule: minimum green"));
  EXPECT_THAT(LoadError("all_red_s: 7.0", "all_red_s: 1.0"),
              HasSubstr("start_up.all_red_s 1 s is shorter than group 1 (east)'s red clearance "
                        "7 s; rule: minimum all-red"));
  EXPECT_THAT(LoadError("- {groups: [2], green_s: 8.0}", "- {groups: [2], green_s: 4.5}"),
              HasSubstr("plans[0] (day).phases[1]: green 4.5 s is below its groups' min green "
                        "5 s; rule: minimum green"));
}

TEST(City, RefusesRemovingAGeometricConflict) {
  EXPECT_THAT(
      LoadError(
          "    plans:\n      - name: day",
          "    conflicts: [[1, 2], [1, 3], [1, 4], [2, 3], [2, 4]]\n    plans:\n      - name: "
          "day"),
      HasSubstr("conflicts: groups 3 (west) and 4 (south) conflict by geometry"));
  EXPECT_THAT(
      LoadError(
          "    plans:\n      - name: day",
          "    conflicts: [[1, 2], [1, 3], [1, 4], [2, 3], [2, 4]]\n    plans:\n      - name: "
          "day"),
      HasSubstr("rule: the conflict matrix may be extended, never reduced below the geometry"));
}

TEST(City, RefusesUncontrolledMovementsAndBadReferences) {
  EXPECT_THAT(LoadError("      - {id: 4, name: south, approaches: [south]}\n", ""),
              HasSubstr("is in no signal group; rule: every movement of a signalised "
                        "intersection is controlled"));
  EXPECT_THAT(LoadError("- name: driving_school_crossing", "- name: nowhere"),
              HasSubstr("the map driving_school has no intersection nowhere (it has: "
                        "driving_school_crossing)"));
  EXPECT_THAT(LoadError("{at: \"19:00\", plan: evening}", "{at: \"19:00\", plan: evenin}"),
              HasSubstr("schedule[1]: unknown plan \"evenin\""));
  EXPECT_THAT(LoadError("{at: \"19:00\"", "{at: \"25:00\""),
              HasSubstr("bad time of day \"25:00\""));
  EXPECT_THAT(
      LoadError("approaches: [north]}", "approaches: [north], movements: [\"r2c2:E>W:0>0\"]}"),
      HasSubstr("groups[1] (north): movement r2c2:E>W:0>0 is also in group 1 (east); "
                "rule: a movement belongs to one signal group"));
  EXPECT_THAT(LoadError("approaches: [east]}", "approaches: [east, north]}"),
              HasSubstr("movements r2c2:E>W:0>0 and r2c2:N>E:0>0 conflict but are in one "
                        "group; rule: conflicting movements are never green together"));
  EXPECT_THAT(
      LoadError("- {groups: [4], green_s: 8.0}", "- {groups: [1], green_s: 8.0}"),
      HasSubstr("group 4 (south) is never green in this plan; rule: every group is served"));
}

TEST(City, RefusesAHeadShowingAnotherApproach) {
  EXPECT_THAT(LoadError("    plans:\n      - name: day",
                        "    heads: [{head: 1, group: 3}]\n    plans:\n      - name: day"),
              HasSubstr("rule: a head shows its own approach"));
}

}  // namespace
}  // namespace autodrive::scm
