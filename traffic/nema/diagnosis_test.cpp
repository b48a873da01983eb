// The diagnosis of sequence differences, on the calls and intervals of runs the crosscheck made
// (docs/controller-crosscheck.md), without SUMO.
#include "traffic/nema/diagnosis.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace autodrive::traffic::nema {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

Duration Ds(int tenths) { return milliseconds(100) * tenths; }

// The Driving School's evening plan: four phases, SUMO's barrier between 2 and 3, min 5 s,
// max 15 s, passage 2 s, yellow 3 s, red clearance 7 s.
DiagnosisInput Plan(const std::string& calls) {
  DiagnosisInput in;
  in.ring = {1, 2, 3, 4};
  in.barrier_side = {{1, 0}, {2, 0}, {3, 1}, {4, 1}};
  for (std::uint32_t p : in.ring) {
    in.timing[p] = {seconds(5), seconds(15), seconds(2), seconds(3), seconds(7), false};
  }
  in.calls = ParseCallScript(calls, "calls");
  in.tolerance = milliseconds(200);
  return in;
}

// A green of `phase` from `begin` to `end` (tenths of a second) and its yellow and clearance.
void Served(std::vector<Interval>& out, std::uint32_t phase, int begin, int end) {
  out.push_back({phase, IntervalKind::kGreen, Ds(begin), Ds(end)});
  out.push_back({phase, IntervalKind::kYellow, Ds(end), Ds(end + 30)});
  out.push_back({phase, IntervalKind::kRedClearance, Ds(end + 30), Ds(end + 100)});
}

ComparisonInput Window(const DiagnosisInput& in) {
  ComparisonInput c;
  c.phases = in.ring;
  c.ours = in.ours;
  c.sumo = in.sumo;
  c.from = milliseconds(100);
  c.to = seconds(900);
  c.tolerance = in.tolerance;
  return c;
}

// Seed 7: phase 2's green ends at 20 s with only phase 4 called; phase 3 is called during the
// yellow (22.4-24 s) and phase 1 during the red clearance (28.3 s).
constexpr const char* kSeed7 = "4 3.5 23.6\n1 21 21.5\n3 22.4 24\n1 28.3 28.7\n";

TEST(NextPhase, OursChoosesWhenTheGreenEndsSumoAgainDuringTheClearance) {
  const DiagnosisInput in = Plan(kSeed7);
  EXPECT_EQ(OursNextPhase(in, 2, seconds(20)), 4u);
  // SUMO: 4 at 20 s, 3 (nearer, same side of the barrier) from 22.4 s, kept when its call ends;
  // phase 1's call at 28.3 s is on the other side and does not count.
  EXPECT_EQ(SumoNextPhase(in, 2, seconds(20), seconds(22)), 4u);
  EXPECT_EQ(SumoNextPhase(in, 2, seconds(20), seconds(30)), 3u);

  // Seed 2: phase 1 chosen at 23.8 s, its call gone at 24.2 s, phase 2 called from 27.3 s.
  const DiagnosisInput seed2 = Plan("1 23.8 24.2\n2 27.3 29.1\n");
  EXPECT_EQ(OursNextPhase(seed2, 3, Ds(238)), 1u);
  EXPECT_EQ(SumoNextPhase(seed2, 3, Ds(238), Ds(338)), 2u);
}

TEST(Diagnose, NamesTheNextPhaseRuleWithTheRunsTimes) {
  DiagnosisInput in = Plan(kSeed7);
  Served(in.ours, 2, 150, 200);
  Served(in.ours, 4, 300, 608);
  Served(in.sumo, 2, 150, 200);
  Served(in.sumo, 3, 300, 423);
  const SequenceComparison seq = CompareSequences(Window(in));
  ASSERT_EQ(seq.episodes.size(), 1u);
  const std::vector<EpisodeNote> notes = Diagnose(seq, in);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_EQ(notes[0].rule, kRuleNextPhaseInClearance);
  EXPECT_NE(notes[0].evidence.find("phase 2's green ended at 20.0 s in both (calls then: 4); ours "
                                   "chose phase 4"),
            std::string::npos)
      << notes[0].evidence;
  EXPECT_NE(notes[0].evidence.find("SUMO's choice: 4 at 20.0 s, 3 at 22.4 s; it started phase 3 "
                                   "at 30.0 s"),
            std::string::npos)
      << notes[0].evidence;
  EXPECT_NE(notes[0].remedy.find("next_phase_decision: end_of_clearance"), std::string::npos);
}

TEST(Diagnose, AnOrderDifferenceTheRuleDoesNotPredictIsUnexplained) {
  // The same greens with no call of phase 3 in the clearance: SUMO's phase 3 is not what the
  // rule says, so it is not put down to it.
  DiagnosisInput in = Plan("4 3.5 23.6\n");
  Served(in.ours, 2, 150, 200);
  Served(in.ours, 4, 300, 608);
  Served(in.sumo, 2, 150, 200);
  Served(in.sumo, 3, 300, 423);
  const std::vector<EpisodeNote> notes = Diagnose(CompareSequences(Window(in)), in);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_EQ(notes[0].rule, kRuleUnexplained);
  EXPECT_EQ(notes[0].remedy, "not established");
}

TEST(Diagnose, SumosFirstGreenTimesNothingBeforeItsMinGreenEnds) {
  // Phase 1 green from 0 in both, its call 2.1-3.7 s and phase 3's from 4.7 s: SUMO ends it at
  // its min green, 5.0 s, ours at 5.6 s (3.6 + 2).
  DiagnosisInput in = Plan("1 2.1 3.7\n3 4.7 5.8\n3 8 30\n");
  Served(in.ours, 1, 0, 56);
  Served(in.sumo, 1, 0, 50);
  std::vector<EpisodeNote> notes = Diagnose(CompareSequences(Window(in)), in);
  ASSERT_FALSE(notes.empty());
  EXPECT_EQ(notes[0].rule, kRuleFirstGreen);
  EXPECT_NE(notes[0].evidence.find("SUMO ended it at its min green, 5.0 s: its own call before "
                                   "then (last called step 3.6 s) did not start its passage; "
                                   "ours ended it at 5.6 s = 3.6 + passage 2.0 s"),
            std::string::npos)
      << notes[0].evidence;

  // Phase 1 called throughout, phase 2 from 1 s: ours maxes out at 16 s, SUMO at 19.9 s (as
  // the crosscheck measured).
  DiagnosisInput max = Plan("1 0 40\n2 1 60\n");
  Served(max.ours, 1, 0, 160);
  Served(max.sumo, 1, 0, 199);
  notes = Diagnose(CompareSequences(Window(max)), max);
  ASSERT_FALSE(notes.empty());
  EXPECT_EQ(notes[0].rule, kRuleFirstGreen);
  EXPECT_NE(notes[0].evidence.find("SUMO maxed it out at 19.9 s, its max 15.0 s after the end of "
                                   "its min green"),
            std::string::npos)
      << notes[0].evidence;
  EXPECT_NE(notes[0].evidence.find("ours ended it at 16.0 s = first conflicting call 1.0 + max "
                                   "15.0 s"),
            std::string::npos)
      << notes[0].evidence;
}

TEST(Diagnose, AGreenInItsPassageCutWhenAConflictingCallComesBack) {
  // Phase 3 green from 15 s, its call to 22 s (passage to 23.9 s), phase 4 called from 16 s
  // with a one-step break at 22.5 s: SUMO ends the green at 22.6 s, ours at 23.9 s (as the
  // crosscheck measured).
  DiagnosisInput in = Plan("3 0 22\n4 16 22.5\n4 22.6 60\n");
  Served(in.ours, 1, 0, 50);
  Served(in.sumo, 1, 0, 50);
  Served(in.ours, 3, 150, 239);
  Served(in.sumo, 3, 150, 226);
  const std::vector<EpisodeNote> notes = Diagnose(CompareSequences(Window(in)), in);
  ASSERT_FALSE(notes.empty());
  EXPECT_EQ(notes[0].rule, kRulePassageCut);
  EXPECT_NE(notes[0].evidence.find("its own last called step 21.9 s, passage 2.0 s, so ours held "
                                   "it to 23.9 s"),
            std::string::npos)
      << notes[0].evidence;
  EXPECT_NE(notes[0].evidence.find("broke off from 22.5 to 22.6 s and SUMO ended the green at "
                                   "22.6 s"),
            std::string::npos)
      << notes[0].evidence;

  // A break at the step its own call ends is not one (SUMO held that green to 23.9 s too): an
  // end when the call comes back, at 22.1 s, is not put down to the rule.
  DiagnosisInput other = Plan("3 0 22\n4 16 22\n4 22.1 60\n");
  other.ours = in.ours;
  Served(other.sumo, 1, 0, 50);
  Served(other.sumo, 3, 150, 221);
  const std::vector<EpisodeNote> none = Diagnose(CompareSequences(Window(other)), other);
  ASSERT_FALSE(none.empty());
  EXPECT_NE(none[0].rule, kRulePassageCut);

  // Nor is a conflicting call that had gone before its own call ended (SUMO held that green to
  // 23.9 s too).
  DiagnosisInput gone = Plan("3 0 22\n4 16 20\n4 22.6 60\n");
  gone.ours = in.ours;
  gone.sumo = in.sumo;
  const std::vector<EpisodeNote> not_cut = Diagnose(CompareSequences(Window(gone)), gone);
  ASSERT_FALSE(not_cut.empty());
  EXPECT_NE(not_cut[0].rule, kRulePassageCut);
}

TEST(Diagnose, AGreenEndThatMatchesAMaxOutOnOneSideIsTheMaxTimer) {
  // Phase 2 green from 15 s, called throughout, phase 3 called from 17 s: ours maxes out 15 s
  // after the conflicting call (32 s); a SUMO that counted from the green's start would end at
  // 30 s.
  DiagnosisInput in = Plan("2 0 60\n3 17 60\n");
  Served(in.ours, 1, 0, 50);
  Served(in.sumo, 1, 0, 50);
  Served(in.ours, 2, 150, 320);
  Served(in.sumo, 2, 150, 300);
  const std::vector<EpisodeNote> notes = Diagnose(CompareSequences(Window(in)), in);
  ASSERT_FALSE(notes.empty());
  EXPECT_EQ(notes[0].rule, kRuleMaxTimer);
  EXPECT_NE(notes[0].summary.find("ours by max-out: max green counted from the first conflicting "
                                  "call, SUMO by max-out: max green counted from the start of "
                                  "the green"),
            std::string::npos)
      << notes[0].summary;
}

}  // namespace
}  // namespace autodrive::traffic::nema
