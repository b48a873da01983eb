// The interval recorder and the comparison, on hand-made signals (no SUMO run).
#include "traffic/nema/comparison.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "traffic/nema/intervals.h"

namespace autodrive::traffic::nema {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr auto G = PhaseSignal::kGreen;
constexpr auto Y = PhaseSignal::kYellow;
constexpr auto R = PhaseSignal::kRed;

// Two phases in turn, each green `green`, yellow 3 s, red clearance 2 s, from `start`, sampled
// every 0.1 s up to `end`.
std::vector<Interval> TwoPhases(Duration start, Duration green, Duration end) {
  IntervalRecorder r({1, 2});
  const Duration phase = green + seconds(5);
  for (Duration t{0}; t <= end; t += milliseconds(100)) {
    std::vector<PhaseSignal> s = {R, R};
    if (t >= start) {
      const Duration in = (t - start) % (2 * phase);
      const std::size_t k = in < phase ? 0 : 1;
      const Duration p = in - static_cast<Duration::rep>(k) * phase;
      s[k] = p < green ? G : p < green + seconds(3) ? Y : R;
    }
    r.Sample(t, s);
  }
  return r.intervals();
}

TEST(IntervalRecorder, RecordsGreenYellowAndRedClearanceUpToTheNextGreen) {
  const std::vector<Interval> i = TwoPhases(seconds(1), seconds(8), seconds(27));
  const std::vector<Interval> expected = {
      {1, IntervalKind::kGreen, seconds(1), seconds(9)},
      {1, IntervalKind::kYellow, seconds(9), seconds(12)},
      {1, IntervalKind::kRedClearance, seconds(12), seconds(14)},
      {2, IntervalKind::kGreen, seconds(14), seconds(22)},
      {2, IntervalKind::kYellow, seconds(22), seconds(25)},
      {2, IntervalKind::kRedClearance, seconds(25), seconds(27)},
  };
  EXPECT_EQ(i, expected);
}

ComparisonInput Input(std::vector<Interval> ours, std::vector<Interval> sumo) {
  ComparisonInput in;
  in.phases = {1, 2};
  in.ours = std::move(ours);
  in.sumo = std::move(sumo);
  in.from = seconds(1);
  in.to = seconds(53);  // two cycles of 26 s
  in.tolerance = milliseconds(100);
  in.cycle = seconds(26);
  return in;
}

TEST(Compare, SameIntervalsMatch) {
  const auto a = TwoPhases(seconds(1), seconds(8), seconds(80));
  const Comparison c = Compare(Input(a, a));
  EXPECT_TRUE(c.match);
  EXPECT_EQ(c.matches.size(), 12u);  // 2 cycles x 2 phases x 3 kinds
  EXPECT_EQ(c.max_difference, Duration{0});
  EXPECT_EQ(c.ours_cycles, (std::vector<Duration>{seconds(26), seconds(26)}));
  EXPECT_TRUE(c.cycles_match);
}

TEST(Compare, OneStepLateIsWithinTheToleranceTwoAreNot) {
  const auto ours = TwoPhases(seconds(1), seconds(8), seconds(80));
  const Comparison late =
      Compare(Input(ours, TwoPhases(milliseconds(1100), seconds(8), seconds(80))));
  EXPECT_TRUE(late.match);
  EXPECT_EQ(late.max_difference, milliseconds(100));

  const Comparison later =
      Compare(Input(ours, TwoPhases(milliseconds(1200), seconds(8), seconds(80))));
  EXPECT_FALSE(later.match);
  EXPECT_EQ(later.max_difference, milliseconds(200));
  ASSERT_TRUE(later.first_difference);
  const IntervalMatch& first = later.matches[*later.first_difference];
  EXPECT_EQ(first.phase, 1u);
  EXPECT_EQ(first.kind, IntervalKind::kGreen);
  EXPECT_EQ(first.ours->begin, seconds(1));
  EXPECT_EQ(first.sumo->begin, milliseconds(1200));
}

TEST(Compare, ALongerGreenInSumoIsTheFirstDifferenceAndChangesTheCycle) {
  const auto ours = TwoPhases(seconds(1), seconds(8), seconds(80));
  const auto sumo = TwoPhases(seconds(1), seconds(9), seconds(80));
  const Comparison c = Compare(Input(ours, sumo));
  EXPECT_FALSE(c.match);
  EXPECT_FALSE(c.cycles_match);
  ASSERT_TRUE(c.first_difference);
  const IntervalMatch& first = c.matches[*c.first_difference];
  EXPECT_EQ(first.kind, IntervalKind::kGreen);
  EXPECT_EQ(first.sumo->end - first.ours->end, seconds(1));

  RunFacts f;
  f.phase_groups = {{1, "group 1 (east)"}, {2, "group 2 (north)"}};
  const std::string text = ReportText(f, c);
  EXPECT_NE(text.find("verdict: DIFFERENT"), std::string::npos) << text;
  EXPECT_NE(text.find("first difference: phase 1 green: ours 1.0 - 9.0 s, SUMO 1.0 - 10.0 s"),
            std::string::npos)
      << text;
  const nlohmann::json j = nlohmann::json::parse(ReportJson(f, c));
  EXPECT_FALSE(j.at("match").get<bool>());
  EXPECT_EQ(j.at("first_difference").at("end_difference_s").get<double>(), 1.0);
  EXPECT_EQ(j.at("phases").size(), 2u);
}

TEST(Compare, AnIntervalMissingOnEitherSideIsADifference) {
  const auto ours = TwoPhases(seconds(1), seconds(8), seconds(80));
  auto sumo = ours;
  sumo.erase(sumo.begin() + 4);  // phase 2's first yellow
  const Comparison missing = Compare(Input(ours, sumo));
  EXPECT_FALSE(missing.match);
  ASSERT_TRUE(missing.first_difference);
  EXPECT_FALSE(missing.matches[*missing.first_difference].sumo);

  const Comparison extra = Compare(Input(sumo, ours));
  EXPECT_FALSE(extra.match);
  ASSERT_TRUE(extra.first_difference);
  EXPECT_FALSE(extra.matches[*extra.first_difference].ours);
}

TEST(Compare, NothingToCompareIsNoMatch) { EXPECT_FALSE(Compare(Input({}, {})).match); }

}  // namespace
}  // namespace autodrive::traffic::nema
