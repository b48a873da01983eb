// GLOSA's rule on indications written by hand: when it advises, what, and when it stays quiet.
#include "examples/v2i/glosa.h"

#include <gtest/gtest.h>

namespace autodrive::examples {
namespace {

using State = vehicle_sim::SignalIndication::State;

vehicle_sim::SignalIndication Shown(State state, std::optional<double> min_end,
                                    std::optional<double> likely, std::optional<double> next) {
  return vehicle_sim::SignalIndication{state, min_end, likely, next};
}

TEST(Glosa, TheGreenStartsWhenSpatSaysInThatOrder) {
  EXPECT_EQ(GreenStartsIn(Shown(State::kRed, 5, 12, 14)), 14.0) << "next_time first";
  EXPECT_EQ(GreenStartsIn(Shown(State::kRed, 5, 12, {})), 12.0) << "then the red's likely end";
  EXPECT_EQ(GreenStartsIn(Shown(State::kRed, 5, {}, {})), 5.0) << "then its min end";
  EXPECT_EQ(GreenStartsIn(Shown(State::kYellow, 2, 2, 40)), 40.0);
  EXPECT_FALSE(GreenStartsIn(Shown(State::kYellow, 2, 2, {}))) << "a yellow's end is a red's start";
  EXPECT_FALSE(GreenStartsIn(Shown(State::kGreen, 2, 6, 60)));
  EXPECT_FALSE(GreenStartsIn(Shown(State::kFlashingRed, 0, {}, {})));
}

TEST(Glosa, ARedEndingBeforeTheCarArrivesAtCruiseGetsNoAdvice) {
  GlosaParams p;  // cruise 0.156 m/s, margin 1 s, horizon 8 m
  // 1.56 m at cruise: 10 s; the green in 8 s (+1 s margin): it arrives on green anyway.
  EXPECT_FALSE(GlosaSpeed(p, 1.56, Shown(State::kRed, 8, 8, 8)));
}

TEST(Glosa, ARedEndingLaterSlowsTheCarToArriveJustAfterTheGreen) {
  GlosaParams p;
  const auto v = GlosaSpeed(p, 1.56, Shown(State::kRed, 10, 15, 19));
  ASSERT_TRUE(v);
  EXPECT_DOUBLE_EQ(*v, 1.56 / (19 + 1.0));  // distance over (next green + margin)
  // Never slower than the slowest speed advised: it will stop, but later and for less time.
  const auto slow = GlosaSpeed(p, 1.56, Shown(State::kRed, 50, 60, 60));
  ASSERT_TRUE(slow);
  EXPECT_DOUBLE_EQ(*slow, p.min_speed_mps);
}

TEST(Glosa, AGreenThatEndsBeforeTheTailIsThroughAimsForTheNextGreen) {
  GlosaParams p;
  // 1 m + the body (0.318 m) at 0.156 m/s: 8.4 s; the green ends in 5 s, next green in 60 s.
  const auto v = GlosaSpeed(p, 1.0, Shown(State::kGreen, 2, 5, 60));
  ASSERT_TRUE(v);
  EXPECT_DOUBLE_EQ(*v, p.min_speed_mps) << "1 m in 61 s is slower than the slowest advised";
  const auto near = GlosaSpeed(p, 4.0, Shown(State::kGreen, 2, 5, 30));
  ASSERT_TRUE(near);
  EXPECT_DOUBLE_EQ(*near, 4.0 / 31.0);
  // A green it passes in time, or one whose next green SPaT does not give: no advice.
  EXPECT_FALSE(GlosaSpeed(p, 1.0, Shown(State::kGreen, 2, 12, 60)));
  EXPECT_FALSE(GlosaSpeed(p, 1.0, Shown(State::kGreen, 2, 5, {})));
}

TEST(Glosa, NoAdviceOutsideTheHorizonPastTheLineOrForStatesWithoutAGreenAhead) {
  GlosaParams p;
  EXPECT_FALSE(GlosaSpeed(p, 8.5, Shown(State::kRed, 30, 40, 40))) << "beyond the horizon";
  EXPECT_FALSE(GlosaSpeed(p, 0.0, Shown(State::kRed, 30, 40, 40))) << "at the line";
  EXPECT_FALSE(GlosaSpeed(p, 2.0, Shown(State::kFlashingRed, 0, {}, {})));
  EXPECT_FALSE(GlosaSpeed(p, 2.0, Shown(State::kDark, 0, {}, {})));
}

}  // namespace
}  // namespace autodrive::examples
