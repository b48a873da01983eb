// The MUTCD pedestrian timing rules (scm/core/pedestrian_timing.h) against the FHWA worked
// example (FHWA's MUTCD FAQ on 4E.06 P14, as quoted at aaroads.com, topics 7510 and 8658; the
// controller research, ../shared/research/controller.md §6): a 130 ft crossing with its push
// button 60 ft back needs walk 26 s + clearance 38 s = 64 s under the 2009 rules, and
// 7 s + 33 s = 40 s under the 2003 rules.
#include "scm/core/pedestrian_timing.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace autodrive::scm {
namespace {

using ::testing::HasSubstr;

constexpr double kFoot = 0.3048;  // m

const PedestrianCrossing kFhwaExample{130 * kFoot, 60 * kFoot};

TEST(PedestrianTiming, TheFhwaExampleUnder2009RulesIsWalk26PlusClearance38) {
  const PedestrianMinimums m = MutcdPedestrianMinimums(kFhwaExample, false);
  EXPECT_EQ(m.walk_s, 7.0);
  EXPECT_NEAR(m.ped_clear_exact_s, 39.624 / 1.07, 1e-9);  // 37.0 s
  EXPECT_EQ(m.ped_clear_s, 38.0);
  EXPECT_NEAR(m.walk_and_clear_exact_s, 57.912 / 0.91, 1e-9);  // 63.6 s
  EXPECT_EQ(m.walk_and_clear_s, 64.0);
  EXPECT_EQ(m.shortest_walk_s, 26.0);
  EXPECT_EQ(m.ShortestTotalS(), 64.0);
  // The shortest timing passes its own check; a second less of walk does not.
  EXPECT_TRUE(CheckPedestrianTiming(kFhwaExample, {26.0, 38.0}, false).empty());
  const auto v = CheckPedestrianTiming(kFhwaExample, {25.0, 38.0}, false);
  ASSERT_EQ(v.size(), 1u);
  EXPECT_EQ(v[0].configured_s, 63.0);
  EXPECT_EQ(v[0].minimum_s, 64.0);
  EXPECT_THAT(v[0].rule, HasSubstr("MUTCD 2009 4E.06 P14"));
}

TEST(PedestrianTiming, TheFhwaExampleUnder2003RulesIsWalk7PlusClearance33) {
  const PedestrianMinimums m = MutcdPedestrianMinimums(kFhwaExample, false, MutcdEdition::k2003);
  EXPECT_EQ(m.walk_s, 7.0);
  EXPECT_EQ(m.ped_clear_s, 33.0);  // 130 ft / 4 ft/s = 32.5 s, rounded up
  EXPECT_EQ(m.walk_and_clear_s, 0.0) << "no push-button rule before 2009";
  EXPECT_EQ(m.shortest_walk_s, 7.0);
  EXPECT_EQ(m.ShortestTotalS(), 40.0);
}

TEST(PedestrianTiming, LowVolumeAllowsA4SecondWalk) {
  const PedestrianCrossing short_crossing{8.4, 1.4};  // the lab's 0.6 m x 14, button 0.1 m back
  const PedestrianMinimums m = MutcdPedestrianMinimums(short_crossing, true);
  EXPECT_EQ(m.walk_s, 4.0);
  EXPECT_EQ(m.ped_clear_s, 8.0);        // 8.4 / 1.07 = 7.85 s
  EXPECT_EQ(m.walk_and_clear_s, 11.0);  // 9.8 / 0.91 = 10.8 s
  EXPECT_EQ(m.shortest_walk_s, 4.0);
  EXPECT_TRUE(CheckPedestrianTiming(short_crossing, {4.0, 8.0}, true).empty());
  const auto v = CheckPedestrianTiming(short_crossing, {4.0, 8.0}, false);
  ASSERT_EQ(v.size(), 1u);
  EXPECT_EQ(v[0].message,
            "walk 4 s is below 7 s; rule: MUTCD 2009 4E.06: walk at least 7 s (4 s only with "
            "low_pedestrian_volume: true)");
}

TEST(PedestrianTiming, EachBrokenRuleIsNamedWithItsNumbers) {
  const PedestrianCrossing crossing{8.4, 1.4};
  const auto v = CheckPedestrianTiming(crossing, {3.0, 5.0}, true);
  ASSERT_EQ(v.size(), 3u);
  EXPECT_EQ(v[0].message,
            "walk 3 s is below 4 s; rule: MUTCD 2009 4E.06: walk at least 4 s where pedestrian "
            "volumes do not need 7 s");
  EXPECT_EQ(v[1].message,
            "ped clear 5 s is below 8.40 m / 1.07 m/s = 7.85 s, rounded up 8 s; rule: MUTCD 2009 "
            "4E.06 P07: pedestrian clearance to the far side of the traveled way at 3.5 ft/s "
            "(1.07 m/s)");
  EXPECT_THAT(v[2].message,
              HasSubstr("walk + ped clear 3 s + 5 s = 8 s is below (8.40 m + 1.40 m) / 0.91 m/s "
                        "= 10.77 s, rounded up 11 s (a walk of at least 6 s with this ped "
                        "clear); rule: MUTCD 2009 4E.06 P14"));
  // Clearance long enough, the sum short: only P14.
  const auto p14 = CheckPedestrianTiming({8.4, 6.0}, {7.0, 8.0}, false);
  ASSERT_EQ(p14.size(), 1u);
  EXPECT_EQ(p14[0].configured_s, 15.0);
  EXPECT_EQ(p14[0].minimum_s, 16.0);  // 14.4 / 0.91 = 15.8 s
}

TEST(PedestrianTiming, TheBufferIsAtLeast3Seconds) {
  EXPECT_FALSE(CheckBufferInterval(3.0));
  EXPECT_FALSE(CheckBufferInterval(10.0));
  const auto v = CheckBufferInterval(2.5);
  ASSERT_TRUE(v);
  EXPECT_EQ(v->minimum_s, 3.0);
  EXPECT_THAT(v->message, HasSubstr("buffer 2.5 s is below 3 s; rule: MUTCD Figure 4E-2"));
}

TEST(PedestrianTiming, TheDescriptionForPeopleShowsTheFhwaExampleStepByStep) {
  // scmctl pedestrian-timing 130 --button-setback 60 --feet
  const PedestrianCrossing fhwa{130 * 0.3048, 60 * 0.3048};
  EXPECT_EQ(DescribePedestrianMinimums(fhwa, false, MutcdEdition::k2009, true),
            "crossing 39.62 m (130 ft), push button 18.29 m (60 ft) back from the kerb, MUTCD "
            "2009 rules\n"
            "  walk                >= 7 s\n"
            "  ped clear           >= 39.62 m / 1.07 m/s = 37.03 s, rounded up 38 s\n"
            "  walk + ped clear    >= (39.62 m + 18.29 m) / 0.91 m/s = 63.64 s, rounded up 64 s\n"
            "  shortest timing:    walk 26 s + ped clear 38 s = 64 s\n"
            "  buffer              >= 3 s (the parallel phase's yellow + red clearance)\n");
  EXPECT_THAT(DescribePedestrianMinimums(fhwa, false, MutcdEdition::k2003),
              HasSubstr("  shortest timing:    walk 7 s + ped clear 33 s = 40 s\n"));
}

}  // namespace
}  // namespace autodrive::scm
