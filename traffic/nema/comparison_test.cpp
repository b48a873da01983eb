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

// Greens of `phases` one after the other from `start`, each `green` long with yellow 3 s and red
// clearance 2 s (13 s a phase for 8 s greens).
std::vector<Interval> InTurn(const std::vector<std::uint32_t>& phases, Duration start,
                             Duration green) {
  std::vector<Interval> out;
  Duration t = start;
  for (std::uint32_t p : phases) {
    out.push_back({p, IntervalKind::kGreen, t, t + green});
    out.push_back({p, IntervalKind::kYellow, t + green, t + green + seconds(3)});
    out.push_back({p, IntervalKind::kRedClearance, t + green + seconds(3), t + green + seconds(5)});
    t += green + seconds(5);
  }
  return out;
}

TEST(CompareSequences, TheSameSequenceMatches) {
  const auto a = InTurn({1, 2, 1, 2}, seconds(1), seconds(8));
  const SequenceComparison c = CompareSequences(Input(a, a));
  EXPECT_TRUE(c.match);
  EXPECT_TRUE(c.order_match);
  EXPECT_EQ(c.pairs.size(), 12u);
  EXPECT_TRUE(c.episodes.empty());
  EXPECT_FALSE(c.first_difference);
}

TEST(CompareSequences, AStepLateIsWithinTheToleranceTwoAreATimeDifference) {
  const auto ours = InTurn({1, 2, 1, 2}, seconds(1), seconds(8));
  EXPECT_TRUE(
      CompareSequences(Input(ours, InTurn({1, 2, 1, 2}, milliseconds(1100), seconds(8)))).match);
  const SequenceComparison c =
      CompareSequences(Input(ours, InTurn({1, 2, 1, 2}, milliseconds(1200), seconds(8))));
  EXPECT_FALSE(c.match);
  EXPECT_TRUE(c.order_match);
  EXPECT_EQ(c.max_difference, milliseconds(200));
  ASSERT_EQ(c.episodes.size(), 1u);
  EXPECT_EQ(c.pairs[c.episodes[0].first].difference, SequenceDifferenceKind::kTime);
  EXPECT_FALSE(c.episodes[0].rejoin);  // every interval stays 0.2 s late
  EXPECT_EQ(DescribeSequenceDifference(c),
            "time: ours phase 1 green 1.0 - 9.0 s, SUMO phase 1 green 1.2 - 9.2 s (start +0.2 s, "
            "end +0.2 s)");
}

TEST(CompareSequences, AnotherPhaseIsAnOrderDifferenceAndTheSequencesRejoin) {
  // SUMO serves phase 1 again where ours serves phase 2; both serve phase 1 at 27 s.
  const auto ours = InTurn({1, 2, 1, 2}, seconds(1), seconds(8));
  const auto sumo = InTurn({1, 1, 1, 2}, seconds(1), seconds(8));
  const SequenceComparison c = CompareSequences(Input(ours, sumo));
  EXPECT_FALSE(c.match);
  EXPECT_FALSE(c.order_match);
  ASSERT_EQ(c.episodes.size(), 1u);
  const SequencePair& first = c.pairs[c.episodes[0].first];
  EXPECT_EQ(first.difference, SequenceDifferenceKind::kOrder);
  EXPECT_EQ(first.ours->phase, 2u);
  EXPECT_EQ(first.sumo->phase, 1u);
  EXPECT_EQ(first.ours->begin, seconds(14));
  EXPECT_EQ(c.episodes[0].rejoin, seconds(27));
  EXPECT_EQ(c.episodes[0].ours_skipped, 3u);
  EXPECT_EQ(c.episodes[0].sumo_skipped, 3u);
  // After the rejoin, the rest is compared and matches: 3 before, 1 difference, 6 after.
  EXPECT_EQ(c.pairs.size(), 10u);
  EXPECT_EQ(DescribeEpisode(c, 0),
            "order: ours phase 2 green 14.0 - 22.0 s, SUMO phase 1 green 14.0 - 22.0 s; together "
            "again from 27.0 s (passed over: ours 3, SUMO 3 intervals)");
}

TEST(CompareSequences, AnIntervalOnlySumoHasIsMissingInOurs) {
  auto ours = InTurn({1, 2, 1, 2}, seconds(1), seconds(8));
  const auto sumo = ours;
  ours.resize(6);  // ours rests in phase 1's green from 27 s (not ended, so not recorded)
  const SequenceComparison c = CompareSequences(Input(ours, sumo));
  EXPECT_FALSE(c.match);
  ASSERT_EQ(c.episodes.size(), 1u);
  const SequencePair& p = c.pairs[c.episodes[0].first];
  EXPECT_EQ(p.difference, SequenceDifferenceKind::kMissingInOurs);
  EXPECT_FALSE(p.ours);
  EXPECT_EQ(p.sumo->phase, 1u);
  EXPECT_EQ(p.sumo->kind, IntervalKind::kGreen);
}

TEST(CompareSequences, TheReportsCarryTheSequenceAndItsNotes) {
  const auto ours = InTurn({1, 2, 1, 2}, seconds(1), seconds(8));
  Verdicts v;
  v.mode = ComparisonMode::kSequence;
  v.pairs = Compare(Input(ours, ours));
  v.sequence = CompareSequences(Input(ours, InTurn({1, 1, 1, 2}, seconds(1), seconds(8))));
  v.notes = {{"a_rule", "what it is", "times", "a switch"}};
  RunFacts f;
  f.phase_groups = {{1, "group 1 (east)"}, {2, "group 2 (north)"}};
  // The pairs matched; the sequence, which gives the verdict, did not.
  EXPECT_FALSE(Passed(f, v));
  const std::string text = ReportText(f, v);
  EXPECT_NE(text.find("verdict: DIFFERENT (comparison: sequence)"), std::string::npos) << text;
  EXPECT_NE(text.find("     rule: a_rule: what it is"), std::string::npos) << text;
  const nlohmann::json j = nlohmann::json::parse(ReportJson(f, v));
  EXPECT_EQ(j.at("compare").get<std::string>(), "sequence");
  EXPECT_FALSE(j.at("sequence").at("match").get<bool>());
  const auto& e = j.at("sequence").at("episodes").at(0);
  EXPECT_EQ(e.at("difference").get<std::string>(), "order");
  EXPECT_EQ(e.at("rejoin_s").get<double>(), 27.0);
  EXPECT_EQ(e.at("diagnosis").at("remedy").get<std::string>(), "a switch");
  v.mode = ComparisonMode::kPairs;
  EXPECT_TRUE(Passed(f, v));
}

}  // namespace
}  // namespace autodrive::traffic::nema
