// A stage plan's one-ring NTCIP form (scm/core/ring_plan.h) for the shipped cities.
#include "scm/core/ring_plan.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "common/test_support.h"

namespace autodrive::scm {
namespace {

using std::chrono::seconds;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

TEST(RingPlan, TheDrivingSchoolsFixedPlanIsOneRingOfFourPhasesOnMaxRecall) {
  const City city = LoadCity(test::SourceDir() / "config/cities/driving_school.yaml");
  const IntersectionModel& x = city.intersections.front();
  const Plan& day = x.plans[*x.PlanIndex("day")];
  const RingPlan ring = RingPlanOf(x, day);
  ASSERT_EQ(ring.phases.size(), 4u);
  ASSERT_EQ(ring.rings.size(), 1u);
  EXPECT_THAT(ring.rings[0], ElementsAre(1u, 2u, 3u, 4u));
  for (std::size_t k = 0; k < 4; ++k) {
    const RingPhase& p = ring.phases[k];
    EXPECT_EQ(p.number, k + 1);
    EXPECT_EQ(p.groups, day.phases[k].groups);
    EXPECT_EQ(p.min_green, seconds(5));
    EXPECT_EQ(p.max1, seconds(8));
    EXPECT_EQ(p.yellow, seconds(3));
    EXPECT_EQ(p.red_clear, seconds(7));
    EXPECT_EQ(p.passage, Duration{0});
    EXPECT_EQ(p.recall, Recall::kMax);
    EXPECT_EQ(p.ring, 1u);
  }
  // The cycle is the controller's own fixed-time cycle.
  EXPECT_EQ(ring.cycle, day.cycle);
  EXPECT_EQ(ring.cycle, seconds(72));
  EXPECT_EQ(ring.offset, day.offset);
  const std::string text = DescribeRingPlan(x, ring);
  EXPECT_THAT(text, HasSubstr("ring 1 sequence: 1, 2, 3, 4"));
  EXPECT_THAT(text, HasSubstr("cycle 72.0 s"));
}

TEST(RingPlan, AnActuatedStageWithAGroupNoDetectorCallsIsOnMinRecall) {
  const City city = LoadCity(test::SourceDir() / "config/cities/small_town.yaml");
  for (const IntersectionModel& x : city.intersections) {
    const Plan& evening = x.plans[*x.PlanIndex("evening")];
    ASSERT_EQ(evening.type, PlanType::kActuated);
    const RingPlan ring = RingPlanOf(x, evening);
    ASSERT_EQ(ring.phases.size(), evening.phases.size());
    EXPECT_EQ(ring.cycle, Duration{0});
    for (std::size_t k = 0; k < ring.phases.size(); ++k) {
      bool called = true;
      for (std::size_t g : evening.phases[k].groups) {
        called = called && std::ranges::any_of(evening.detectors,
                                               [&](const Detector& d) { return d.group == g; });
      }
      EXPECT_EQ(ring.phases[k].recall, called ? Recall::kNone : Recall::kMin) << x.name << k;
      EXPECT_EQ(ring.phases[k].passage, evening.extension);
      EXPECT_EQ(ring.phases[k].max1, evening.phases[k].green);
    }
  }
  // Flash and dark plans have no phases.
  const IntersectionModel& x = city.intersections.front();
  EXPECT_TRUE(RingPlanOf(x, x.plans[*x.PlanIndex("night")]).phases.empty());
}

}  // namespace
}  // namespace autodrive::scm
