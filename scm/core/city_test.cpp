#include "scm/core/city.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>

#include "common/test_support.h"
#include "scm/core/runtime.h"

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

// --- Pedestrians (docs/controller.md, "Pedestrians") ---

/// The Driving School's east leg (two 0.3 m lanes: 8.4 m at 1:14) with a crosswalk whose
/// push button is 0.1 m back (1.4 m): ped clear >= 8.4 / 1.07 = 7.85 -> 8 s, walk + ped clear
/// >= 9.8 / 0.91 = 10.8 -> 11 s. `changes` replace its keys' values (an empty value drops the
/// key) or add keys; `more` follows it in the list.
std::pair<std::string, std::string> Crosswalk(
    const std::vector<std::pair<std::string, std::string>>& changes = {},
    const std::string& more = "") {
  std::vector<std::pair<std::string, std::string>> keys{{"leg", "east"},
                                                        {"length_m", "0.6"},
                                                        {"button_setback_m", "0.1"},
                                                        {"walk_s", "7"},
                                                        {"ped_clear_s", "8"}};
  for (const auto& [key, value] : changes) {
    const auto it = std::ranges::find(keys, key, &std::pair<std::string, std::string>::first);
    if (it == keys.end()) {
      keys.emplace_back(key, value);
    } else {
      it->second = value;
    }
  }
  std::string fields;
  for (const auto& [key, value] : keys) {
    if (!value.empty()) fields += (fields.empty() ? "" : ", ") + key + ": " + value;
  }
  return {"    plans:\n      - name: day",
          "    crosswalks:\n      - {" + fields + "}\n" + more + "    plans:\n      - name: day"};
}

std::string WithCrosswalk(const std::vector<std::pair<std::string, std::string>>& changes = {}) {
  std::string text = config::ReadFile(CitiesDir() / "driving_school.yaml");
  const auto [from, to] = Crosswalk(changes);
  text.replace(text.find(from), from.size(), to);
  return text;
}

TEST(Pedestrians, ACrosswalkWithTheMutcdTimesLoads) {
  const City city = LoadCityString(WithCrosswalk(), "city.yaml", CitiesDir());
  ASSERT_EQ(city.config.intersections[0].crosswalks.size(), 1u);
  EXPECT_EQ(city.config.intersections[0].crosswalks[0].ped_clear_s, std::chrono::seconds(8));
  // Listing the groups it crosses: the east approach's and the westbound through's; the north
  // and south groups only turn into the east leg, so run parallel to it (yellow 3 + red 7).
  EXPECT_NO_THROW(
      (void)LoadCityString(WithCrosswalk({{"groups", "[1, 3]"}}), "city.yaml", CitiesDir()));
  EXPECT_NO_THROW(
      (void)LoadCityString(WithCrosswalk({{"groups", "[1]"}, {"movements", "[\"r2c2:W>E:0>0\"]"}}),
                           "city.yaml", CitiesDir()));
  // The file round-trips with its crosswalks.
  const std::string saved = config::SaveString(city.config);
  EXPECT_EQ(config::LoadString<CityConfig>(saved), city.config);
}

TEST(Pedestrians, RefusesAWalkBelow7SecondsOr4WithLowVolume) {
  EXPECT_EQ(LoadError({Crosswalk({{"walk_s", "6"}})}),
            "city.yaml: intersections[0] (driving_school_crossing).crosswalks[0] (east leg): the "
            "crossing of 0.6 lab m is 8.40 m at 1:14, its push button 1.40 m (0.1 lab m back); "
            "walk 6 s is below 7 s; rule: MUTCD 2009 4E.06: walk at least 7 s (4 s only with "
            "low_pedestrian_volume: true)");
  const auto low_volume =
      std::make_pair(std::string("    crosswalks:"), std::string("    low_pedestrian_volume: true\n"
                                                                 "    crosswalks:"));
  std::string text = WithCrosswalk({{"walk_s", "4"}});
  text.replace(text.find(low_volume.first), low_volume.first.size(), low_volume.second);
  EXPECT_NO_THROW((void)LoadCityString(text, "city.yaml", CitiesDir()));
  EXPECT_THAT(LoadError({Crosswalk({{"walk_s", "3.5"}}), low_volume}),
              HasSubstr("walk 3.5 s is below 4 s; rule: MUTCD 2009 4E.06: walk at least 4 s "
                        "where pedestrian volumes do not need 7 s"));
}

TEST(Pedestrians, RefusesAPedClearBelowTheCrossingAt3Point5FeetPerSecond) {
  EXPECT_THAT(LoadError({Crosswalk({{"ped_clear_s", "7.5"}})}),
              HasSubstr("crosswalks[0] (east leg): the crossing of 0.6 lab m is 8.40 m at 1:14, "
                        "its push button 1.40 m (0.1 lab m back); ped clear 7.5 s is below "
                        "8.40 m / 1.07 m/s = 7.85 s, rounded up 8 s; rule: MUTCD 2009 4E.06 P07: "
                        "pedestrian clearance to the far side of the traveled way at 3.5 ft/s "
                        "(1.07 m/s)"));
}

TEST(Pedestrians, RefusesAWalkAndPedClearBelowTheWalkFromTheButtonAt3FeetPerSecond) {
  // The button 0.5 lab m back: (8.4 + 7.0) / 0.91 = 16.9 -> 17 s; 7 + 8 is 15.
  EXPECT_THAT(LoadError({Crosswalk({{"button_setback_m", "0.5"}})}),
              HasSubstr("its push button 7.00 m (0.5 lab m back); walk + ped clear 7 s + 8 s = "
                        "15 s is below (8.40 m + 7.00 m) / 0.91 m/s = 16.92 s, rounded up 17 s (a "
                        "walk of at least 9 s with this ped clear); rule: MUTCD 2009 4E.06 P14"));
  EXPECT_NO_THROW((void)LoadCityString(
      WithCrosswalk({{"button_setback_m", "0.5"}, {"walk_s", "9"}}), "city.yaml", CitiesDir()));
  // Without a button, P14 measures from 6 ft (1.83 m) back: (8.4 + 1.83) / 0.91 = 11.2 -> 12 s.
  EXPECT_THAT(
      LoadError({Crosswalk({{"button_setback_m", ""}, {"ped_clear_s", "4"}})}),
      HasSubstr("its start (no push button) 1.83 m (the MUTCD's 6 ft back from the kerb); ped "
                "clear 4 s is below 8.40 m / 1.07 m/s = 7.85 s, rounded up 8 s; rule: MUTCD 2009 "
                "4E.06 P07: pedestrian clearance to the far side of the traveled way at 3.5 ft/s "
                "(1.07 m/s); and walk + ped clear 7 s + 4 s = 11 s is below (8.40 m + 1.83 m) / "
                "0.91 m/s = 11.24 s, rounded up 12 s"));
}

TEST(Pedestrians, RefusesABufferBelow3SecondsOnAGroupParallelToTheCrosswalk) {
  // Floors and a clearing vehicle that let yellow 1.5 s + red clearance 1 s load.
  const std::vector<std::pair<std::string, std::string>> short_clearances{
      {"min_yellow_s: 3.0", "min_yellow_s: 1.0"},
      {"length_m: 0.318, speed_mps: 0.2", "length_m: 0.318, speed_mps: 2.0"},
      {"crossing_time_s: 3.0", "crossing_time_s: 0.0"},
      {"{id: 2, name: north, approaches: [north]}",
       "{id: 2, name: north, approaches: [north], timing: {yellow_s: 1.5, red_clearance_s: 1}}"}};
  auto edits = short_clearances;
  edits.push_back(Crosswalk({{"groups", "[1, 3]"}}));
  EXPECT_THAT(LoadError(edits),
              HasSubstr("crosswalks[0] (east leg): group 2 (north) runs parallel to it (it is not "
                        "among the groups it crosses): its yellow 1.5 s + red clearance 1 s = "
                        "2.5 s; buffer 2.5 s is below 3 s; rule: MUTCD Figure 4E-2: buffer "
                        "interval"));
  // Crossed by group 2 (its left turn into the east leg), the crosswalk never runs with it.
  std::string text = config::ReadFile(CitiesDir() / "driving_school.yaml");
  edits.back() = Crosswalk({{"groups", "[1, 2, 3]"}});
  for (const auto& [from, to] : edits) text.replace(text.find(from), from.size(), to);
  EXPECT_NO_THROW((void)LoadCityString(text, "city.yaml", CitiesDir()));
}

TEST(Pedestrians, RefusesACrosswalkThatMissesTheTrafficOverItOrItsLeg) {
  EXPECT_THAT(LoadError({Crosswalk({{"groups", "[3]"}})}),
              HasSubstr("crosswalks[0] (east leg): group 1 (east) is not among the groups it "
                        "crosses, but its movement r2c2:E>N:0>0 comes from the east leg; rule: "
                        "traffic from a leg or straight into it never runs with the leg's walk"));
  EXPECT_THAT(LoadError({Crosswalk({{"groups", "[1]"}})}),
              HasSubstr("group 3 (west) is not among the groups it crosses, but its movement "
                        "r2c2:W>E:0>0 goes straight into the east leg"));
  EXPECT_THAT(LoadError({Crosswalk({{"groups", "[1, 3]"}, {"movements", "[\"r2c2:N>W:0>0\"]"}})}),
              HasSubstr("crosswalks[0] (east leg).movements: movement r2c2:N>W:0>0 neither comes "
                        "from nor goes into the east leg"));
  EXPECT_THAT(LoadError({Crosswalk({{"length_m", "0.5"}})}),
              HasSubstr("length_m 0.5 is shorter than the east leg's traveled way, 0.600 m over 2 "
                        "lanes"));
  EXPECT_THAT(
      LoadError({Crosswalk({}, "      - {leg: east, length_m: 0.6, walk_s: 7, ped_clear_s: 8}\n")}),
      HasSubstr("crosswalks[1] (east leg): crosswalks[0] is on the east leg too; rule: "
                "one crosswalk per leg"));
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

/// The Small Town's text with `districts` (YAML of the section's items) inserted before its
/// fleet section.
std::string SmallTownWithDistricts(const std::string& districts) {
  std::string text = config::ReadFile(CitiesDir() / "small_town.yaml");
  const auto pos = text.find("\nfleet:");
  EXPECT_NE(pos, std::string::npos);
  text.insert(pos + 1, "districts:\n" + districts);
  return text;
}

std::string DistrictsError(const std::string& districts) {
  return test::ErrorMessage<ConfigError>(
      [&] { (void)LoadCityString(SmallTownWithDistricts(districts), "city.yaml", CitiesDir()); });
}

constexpr const char* kTwoDistricts =
    "  - {name: uptown, domain: 11, intersections: [north_t]}\n"
    "  - {name: downtown, domain: 12, intersections: [centre]}\n";

TEST(Districts, EachHasItsSignalsAndTheNearestUnsignalisedIntersections) {
  City city = LoadCityString(SmallTownWithDistricts(kTwoDistricts), "city.yaml", CitiesDir());
  ASSERT_EQ(city.districts.all().size(), 2u);
  const maps::District& up = *city.districts.Find("uptown");
  const maps::District& down = *city.districts.Find("downtown");
  EXPECT_EQ(up.domain, 11u);
  EXPECT_EQ(down.domain, 12u);
  EXPECT_EQ(city.districts.Find("midtown"), nullptr);
  // Every intersection of the map is in exactly one district; the signalised ones where the
  // file puts them; each other one with its nearest signalised intersection.
  std::size_t listed = 0;
  for (const maps::Intersection& x : city.map.intersections) {
    const bool in_up = std::ranges::find(up.intersections, x.id) != up.intersections.end();
    const bool in_down = std::ranges::find(down.intersections, x.id) != down.intersections.end();
    EXPECT_NE(in_up, in_down) << x.name;
    ++listed;
    const auto distance = [&](const char* name) {
      return (city.map.intersection(city.Find(name)->id).centre - x.centre).norm();
    };
    EXPECT_EQ(in_up, distance("north_t") < distance("centre")) << x.name;
  }
  EXPECT_EQ(up.intersections.size() + down.intersections.size(), listed);
  // A point's district: its nearest intersection's.
  EXPECT_EQ(city.districts.At(city.map.intersection(city.Find("north_t")->id).centre), &up);
  EXPECT_EQ(city.districts.At(city.map.intersection(city.Find("centre")->id).centre), &down);
  EXPECT_EQ(city.districts.Of(city.Find("centre")->id), &down);

  ASSERT_EQ(city.intersections.size(), 2u);
  NarrowToDistrict(city, "uptown");
  ASSERT_EQ(city.intersections.size(), 1u);
  EXPECT_EQ(city.intersections[0].name, "north_t");
  EXPECT_EQ(city.district, "uptown");
  EXPECT_EQ(city.districts.all().size(), 2u) << "the city's districts stay known";
  EXPECT_THAT(test::ErrorMessage<InputError>([&] { NarrowToDistrict(city, "midtown"); }),
              HasSubstr("city small_town has no district midtown (it has: uptown, downtown)"));
  City whole = LoadCity(CitiesDir() / "small_town.yaml");
  EXPECT_TRUE(whole.districts.empty());
  EXPECT_EQ(whole.districts.At(Eigen::Vector2d::Zero()), nullptr);
  EXPECT_THAT(test::ErrorMessage<InputError>([&] { NarrowToDistrict(whole, "uptown"); }),
              HasSubstr("has no district uptown (it has no districts: section)"));
}

TEST(Districts, TheDomainOfADistrictComesFromTheFileAndMustMatchAnyDomainAskedFor) {
  const test::TempDir dir("district_domain");
  const auto file = dir.path() / "city.yaml";
  std::ofstream(file) << SmallTownWithDistricts(kTwoDistricts);
  EXPECT_EQ(DistrictDomain(file, "uptown", std::nullopt), 11u);
  EXPECT_EQ(DistrictDomain(file, "downtown", 12u), 12u);
  EXPECT_THAT(test::ErrorMessage<InputError>([&] { (void)DistrictDomain(file, "uptown", 12u); }),
              HasSubstr("district uptown is on DDS domain 11"));
  EXPECT_THAT(
      test::ErrorMessage<InputError>([&] { (void)DistrictDomain(file, "midtown", std::nullopt); }),
      HasSubstr("no district midtown (it has: uptown, downtown)"));
  EXPECT_THAT(test::ErrorMessage<InputError>([&] {
                (void)DistrictDomain(CitiesDir() / "small_town.yaml", "uptown", std::nullopt);
              }),
              HasSubstr("no district uptown (the city has no districts: section)"));
}

TEST(Districts, RefusesWhatTwoSCMsWouldFightOverOrNoneWouldRun) {
  EXPECT_THAT(DistrictsError("  - {name: uptown, domain: 11, intersections: [north_t]}\n"),
              HasSubstr("districts: centre is in no district; rule: with districts, every "
                        "signalised intersection is in one"));
  EXPECT_THAT(DistrictsError("  - {name: uptown, domain: 11, intersections: [north_t, centre]}\n"
                             "  - {name: downtown, domain: 12, intersections: [centre]}\n"),
              HasSubstr("districts[1] (downtown): centre is in district uptown already; rule: "
                        "each intersection is run by one district's SCM"));
  EXPECT_THAT(DistrictsError("  - {name: uptown, domain: 11, intersections: [north_t]}\n"
                             "  - {name: downtown, domain: 11, intersections: [centre]}\n"),
              HasSubstr("districts[1] (downtown): domain 11 is district uptown's too; rule: one "
                        "DDS domain per district"));
  EXPECT_THAT(DistrictsError("  - {name: uptown, domain: 11, intersections: [north_t]}\n"
                             "  - {name: uptown, domain: 12, intersections: [centre]}\n"),
              HasSubstr("districts[1] (uptown): a district of this name comes before"));
  EXPECT_THAT(DistrictsError("  - {name: uptown, domain: 11, intersections: [north_t]}\n"
                             "  - {name: downtown, domain: 12, intersections: [centre, x_r1c1]}\n"),
              HasSubstr("x_r1c1 is not a signalised intersection of the map small_town (they "
                        "are: "));
  EXPECT_THAT(DistrictsError("  - {name: uptown, domain: 11, intersections: [north_t]}\n"
                             "  - {name: downtown, domain: 12, intersections: []}\n"),
              HasSubstr("districts[1] (downtown): names no intersection"));
  EXPECT_THAT(DistrictsError("  - {name: up-town, domain: 11, intersections: [north_t]}\n"),
              HasSubstr("1 to 64 letters, digits or '_'"));
  EXPECT_THAT(DistrictsError("  - {name: uptown, domain: 233, intersections: [north_t]}\n"),
              HasSubstr("233"));
}

// A city edited by hand between a save and a restart: a saved phase control whose plan or phase
// the city no longer has, or whose time is up, is dropped; the rest come back with their time left.
TEST(RuntimeRestore, SavedPhaseControlsComeBackWithTheirTimeLeftUnlessTheCityLostTheirPhase) {
  CityRuntime runtime(
      std::make_unique<City>(LoadCity(test::SourceDir() / "config/cities/driving_school.yaml")));
  const ClockReading now{MonoTime(std::chrono::seconds(100)), Time(std::chrono::seconds(5000)), 0};
  const Time later = now.wire + std::chrono::seconds(30);
  IntersectionStateRecord saved{
      runtime.intersections()[0].model->id, "auto", "auto", false, now.wire, {}};
  saved.controls = {{"hold", "day", 1, later},
                    {"omit", "rush", 2, later},    // no such plan
                    {"omit", "day", 9, later},     // no such phase
                    {"call", "day", 3, now.wire},  // its time is up
                    {"stop", "day", 2, later}};    // no such control
  runtime.Start(now, {saved});
  const auto& controls = runtime.intersections()[0].controller->controls().all();
  ASSERT_EQ(controls.size(), 1u);
  EXPECT_EQ(controls[0].kind, PhaseControlKind::kHold);
  EXPECT_EQ(controls[0].phase, 0u);
  EXPECT_EQ(controls[0].until, now.mono + std::chrono::seconds(30));
}

}  // namespace
}  // namespace autodrive::scm
