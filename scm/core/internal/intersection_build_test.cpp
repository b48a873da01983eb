#include "scm/core/internal/intersection_build.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>

#include "common/error.h"
#include "common/test_support.h"

namespace autodrive::scm::internal {
namespace {

using std::chrono::seconds;
using ::testing::HasSubstr;

/// The Driving School's crossing: four approaches, one group each, every pair in conflict.
class IntersectionBuild : public ::testing::Test {
 protected:
  IntersectionBuild()
      : city_(LoadCity(test::SourceDir() / "config" / "cities" / "driving_school.yaml")),
        cfg_(city_.config.intersections.at(0)),
        site_{city_.map, MapIntersection()},
        where_("city.yaml") {}

  const maps::Intersection& MapIntersection() const {
    const auto it = std::ranges::find_if(
        city_.map.intersections, [](const auto& x) { return x.name == "driving_school_crossing"; });
    return *it;
  }

  /// The shipped city's floors and clearing vehicles.
  GroupFloors Floors() const { return {city_.floors, city_.config.safety.clearing_vehicles}; }

  /// The model of `cfg` up to its plans (groups, conflicts, heads).
  IntersectionModel ModelOf(const IntersectionConfig& cfg) const {
    IntersectionModel x;
    Groups groups = BuildGroups(cfg, site_, Floors(), 1.0, where_);
    x.conflicts = BuildConflicts(cfg, site_, groups, where_);
    AssignHeads(cfg, site_, groups, where_);
    x.groups = std::move(groups.groups);
    return x;
  }

  City city_;
  IntersectionConfig cfg_;
  MapSite site_;
  Where where_;
};

TEST(Where, NamesTheKeyPathInMessages) {
  const Where w = Where("city.yaml").Then("intersections[0] (x)").Then("groups[1]");
  EXPECT_EQ(test::ErrorMessage<ConfigError>([&] { w.Fail("bad"); }),
            "city.yaml: intersections[0] (x).groups[1]: bad");
}

TEST_F(IntersectionBuild, GroupsTakeTheMovementsOfTheirApproachAndTheIntersectionsTiming) {
  const Groups g = BuildGroups(cfg_, site_, Floors(), 1.0, where_);
  ASSERT_EQ(g.groups.size(), 4u);
  EXPECT_EQ(g.group_of.size(), site_.x.movements.size());
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(g.groups[i].movements.size(), 3u);
    EXPECT_TRUE(std::ranges::is_sorted(g.groups[i].movements));
    for (MovementId m : g.groups[i].movements) EXPECT_EQ(g.group_of.at(m), i);
    EXPECT_EQ(g.groups[i].timing.min_green, seconds(5));
    EXPECT_EQ(g.groups[i].timing.max_green, seconds(15));
    EXPECT_TRUE(g.groups[i].heads.empty());
  }
  // Time scale 2: every duration doubles.
  const Groups slow = BuildGroups(cfg_, site_, Floors(), 2.0, where_);
  EXPECT_EQ(slow.groups[0].timing.yellow, seconds(6));
}

TEST_F(IntersectionBuild, AGroupOverrideBelowTheFloorIsRefused) {
  cfg_.groups[2].timing.yellow_s = std::chrono::milliseconds(2500);
  EXPECT_EQ(test::ErrorMessage<ConfigError>(
                [&] { (void)BuildGroups(cfg_, site_, Floors(), 1.0, where_); }),
            "city.yaml: groups[2] (west): group 3 (west): yellow 2.5 s is below the minimum 3 s; "
            "rule: minimum yellow");
  cfg_.groups[2].timing = {};
  cfg_.groups[2].timing.max_green_s = seconds(4);
  EXPECT_THAT(test::ErrorMessage<ConfigError>(
                  [&] { (void)BuildGroups(cfg_, site_, Floors(), 1.0, where_); }),
              HasSubstr("max green 4 s is below its min green 5 s"));
}

TEST_F(IntersectionBuild, GroupsRefuseDuplicatesAndUncontrolledMovements) {
  IntersectionConfig twice = cfg_;
  twice.groups[1].id = 1;
  EXPECT_THAT(test::ErrorMessage<ConfigError>(
                  [&] { (void)BuildGroups(twice, site_, Floors(), 1.0, where_); }),
              HasSubstr("groups[1] (north): group id 1 is used twice"));
  cfg_.groups.pop_back();
  EXPECT_THAT(test::ErrorMessage<ConfigError>(
                  [&] { (void)BuildGroups(cfg_, site_, Floors(), 1.0, where_); }),
              HasSubstr("is in no signal group; rule: every movement of a signalised "
                        "intersection is controlled"));
  cfg_.groups.clear();
  EXPECT_EQ(test::ErrorMessage<ConfigError>(
                [&] { (void)BuildGroups(cfg_, site_, Floors(), 1.0, where_); }),
            "city.yaml: no signal groups");
}

TEST_F(IntersectionBuild, ConflictsFollowTheGeometryAndMayOnlyGrow) {
  const Groups g = BuildGroups(cfg_, site_, Floors(), 1.0, where_);
  const ConflictMatrix geometric = BuildConflicts(cfg_, site_, g, where_);
  for (std::size_t a = 0; a < 4; ++a) {
    for (std::size_t b = 0; b < 4; ++b) EXPECT_EQ(geometric[a][b], a != b) << a << "," << b;
  }
  // Given in full (every pair) it is accepted; one pair short is refused.
  cfg_.conflicts =
      std::vector<std::vector<std::uint32_t>>{{1, 2}, {1, 3}, {1, 4}, {2, 3}, {2, 4}, {3, 4}};
  EXPECT_EQ(BuildConflicts(cfg_, site_, g, where_), geometric);
  cfg_.conflicts->pop_back();
  EXPECT_THAT(
      test::ErrorMessage<ConfigError>([&] { (void)BuildConflicts(cfg_, site_, g, where_); }),
      HasSubstr("city.yaml: conflicts: groups 3 (west) and 4 (south) conflict by geometry"));
  cfg_.conflicts.reset();
  cfg_.extra_conflicts = {{1, 9}};
  EXPECT_EQ(test::ErrorMessage<ConfigError>([&] { (void)BuildConflicts(cfg_, site_, g, where_); }),
            "city.yaml: extra_conflicts.[0]: unknown signal group 9");
  cfg_.extra_conflicts = {{2, 2}};
  EXPECT_THAT(
      test::ErrorMessage<ConfigError>([&] { (void)BuildConflicts(cfg_, site_, g, where_); }),
      HasSubstr("a conflict is a pair of two different group ids"));
}

TEST_F(IntersectionBuild, EachHeadShowsTheGroupOfItsApproach) {
  Groups g = BuildGroups(cfg_, site_, Floors(), 1.0, where_);
  AssignHeads(cfg_, site_, g, where_);
  std::size_t heads = 0;
  for (const auto& group : g.groups) {
    ASSERT_EQ(group.heads.size(), 1u);
    heads += group.heads.size();
    // The head's approach is the side of the group's movements.
    const auto& h = site_.map.signal_heads.at(group.heads[0].value() - 1);
    for (MovementId m : group.movements) {
      EXPECT_EQ(site_.map.movement(m).from_approach, h.approach);
    }
  }
  EXPECT_EQ(heads, site_.x.signal_heads.size());
  Groups again = BuildGroups(cfg_, site_, Floors(), 1.0, where_);
  cfg_.heads = {{g.groups[0].heads[0].value(), 3}};
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] { AssignHeads(cfg_, site_, again, where_); }),
              HasSubstr("shows group 3 (west), which controls no movement from there; rule: a "
                        "head shows its own approach"));
}

TEST_F(IntersectionBuild, AFixedPlansCycleIsItsGreensAndClearances) {
  const IntersectionModel x = ModelOf(cfg_);
  cfg_.plans[0].offset_s = seconds(60);
  const Plan day = BuildPlan(cfg_.plans[0], x, site_, 1.0, where_);
  EXPECT_EQ(day.type, PlanType::kFixed);
  EXPECT_EQ(day.cycle, seconds(4 * (8 + 3 + 7)));
  ASSERT_EQ(day.phase_starts.size(), 4u);
  EXPECT_EQ(day.phase_starts[1], seconds(8 + 3 + 7));
  EXPECT_EQ(day.phase_starts[3], seconds(3 * (8 + 3 + 7)));
  cfg_.plans[0].offset_s = seconds(80);
  EXPECT_EQ(BuildPlan(cfg_.plans[0], x, site_, 1.0, where_).offset,
            seconds(80 - 72));  // modulo the cycle
  // Two phases that share a group: no clearance for it between them.
  PlanConfig overlap = cfg_.plans[0];
  overlap.phases = {{{1}, seconds(8)},
                    {{2}, seconds(8)},
                    {{3}, seconds(8)},
                    {{4}, seconds(8)},
                    {{4}, seconds(6)}};
  const Plan o = BuildPlan(overlap, x, site_, 1.0, where_);
  EXPECT_EQ(o.phase_starts[4], seconds(8 * 4 + 3 * (3 + 7)));
  EXPECT_EQ(o.cycle, seconds(8 * 4 + 6 + (3 + 7) * 4));
}

TEST_F(IntersectionBuild, AnActuatedPlanRunsToMaxGreenAndPlacesDetectorsOnIngressLanes) {
  const IntersectionModel x = ModelOf(cfg_);
  const Plan evening = BuildPlan(cfg_.plans[1], x, site_, 1.0, where_);
  for (const auto& phase : evening.phases) EXPECT_EQ(phase.green, seconds(15));
  std::size_t lanes = 0;
  for (const auto& a : site_.x.approaches) lanes += a.ingress.size();
  EXPECT_EQ(evening.detectors.size(), lanes);
  for (const auto& d : evening.detectors) EXPECT_DOUBLE_EQ(d.to_stop_line_m, 0.6);
  PlanConfig fixed = cfg_.plans[0];
  fixed.detectors = cfg_.plans[1].detectors;
  EXPECT_THAT(
      test::ErrorMessage<ConfigError>([&] { (void)BuildPlan(fixed, x, site_, 1.0, where_); }),
      HasSubstr("city.yaml: detectors[0]: only an actuated plan has detectors"));
}

TEST_F(IntersectionBuild, PlansRefuseConflictsUnservedGroupsAndBadGreens) {
  const IntersectionModel x = ModelOf(cfg_);
  PlanConfig p = cfg_.plans[0];
  p.phases[0].groups = {1, 2};
  EXPECT_EQ(test::ErrorMessage<ConfigError>([&] { (void)BuildPlan(p, x, site_, 1.0, where_); }),
            "city.yaml: phases[0]: groups 1 (east) and 2 (north) conflict; rule: conflicting "
            "groups are never green or yellow together");
  p = cfg_.plans[0];
  p.phases[3].groups = {1};
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] { (void)BuildPlan(p, x, site_, 1.0, where_); }),
              HasSubstr("group 4 (south) is never green in this plan; rule: every group is "
                        "served"));
  p = cfg_.plans[0];
  p.phases[1].green_s = seconds(16);
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] { (void)BuildPlan(p, x, site_, 1.0, where_); }),
              HasSubstr("phases[1]: green 16 s is above its groups' max green 15 s"));
  p = cfg_.plans[2];  // flash
  p.phases = cfg_.plans[0].phases;
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] { (void)BuildPlan(p, x, site_, 1.0, where_); }),
              HasSubstr("a flash plan has no phases or detectors"));
  IntersectionConfig named = cfg_;
  named.plans[1].name = "day";
  EXPECT_THAT(
      test::ErrorMessage<ConfigError>([&] { (void)BuildPlans(named, x, site_, 1.0, where_); }),
      HasSubstr("plans[1] (day): plan name day is used twice"));
  named.plans[1].name = "auto";
  EXPECT_THAT(
      test::ErrorMessage<ConfigError>([&] { (void)BuildPlans(named, x, site_, 1.0, where_); }),
      HasSubstr("a plan needs a name other than"));
}

TEST_F(IntersectionBuild, TheScheduleIsSortedAndDefaultsToTheFirstPlan) {
  IntersectionModel x = ModelOf(cfg_);
  x.plans = BuildPlans(cfg_, x, site_, 1.0, where_);
  cfg_.schedule = {{"19:00", "evening"}, {"06:00", "day"}, {"23:30", "night"}};
  const auto s = BuildSchedule(cfg_, x, where_);
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(s[0].minute_of_day, 6 * 60);
  EXPECT_EQ(s[0].plan, *x.PlanIndex("day"));
  EXPECT_EQ(s[2].minute_of_day, 23 * 60 + 30);
  EXPECT_EQ(s[2].plan, *x.PlanIndex("night"));
  cfg_.schedule.push_back({"06:00", "off"});
  EXPECT_EQ(test::ErrorMessage<ConfigError>([&] { (void)BuildSchedule(cfg_, x, where_); }),
            "city.yaml: schedule[3]: 06:00 is scheduled twice");
  cfg_.schedule.clear();
  const auto all_day = BuildSchedule(cfg_, x, where_);
  ASSERT_EQ(all_day.size(), 1u);
  EXPECT_EQ(all_day[0].minute_of_day, 0);
  EXPECT_EQ(all_day[0].plan, 0u);
}

TEST(ParseMinuteOfDay, TakesOnlyHhMm) {
  const Where w("s");
  EXPECT_EQ(ParseMinuteOfDay("00:00", w), 0);
  EXPECT_EQ(ParseMinuteOfDay("23:59", w), 23 * 60 + 59);
  for (const char* bad : {"24:00", "7:00", "07:60", "07-00", "07:00 ", "ab:cd", ""}) {
    EXPECT_THAT(test::ErrorMessage<ConfigError>([&] { (void)ParseMinuteOfDay(bad, w); }),
                HasSubstr("(expected HH:MM, 00:00 to 23:59)"))
        << bad;
  }
}

}  // namespace
}  // namespace autodrive::scm::internal
