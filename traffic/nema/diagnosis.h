#pragma once
/// @file
/// What is behind each stretch of differences the sequence comparison finds (`CompareSequences`,
/// comparison.h): the rule in which the SCM's controller and SUMO's NEMA controller differ,
/// shown with the run's own times and calls, and the setting that would remove it. Pure: no
/// I/O, no SUMO.
///
/// The rules are those SUMO 1.15's NEMA controller was seen to follow in the crosscheck's runs
/// (docs/controller-crosscheck.md, "Differences the random calls found"); a stretch that none
/// of them explains is reported as "unexplained" with the evidence, never fitted.

#include <cstdint>
#include <map>
#include <vector>

#include "traffic/nema/call_script.h"
#include "traffic/nema/comparison.h"
#include "traffic/nema/intervals.h"

#include "common/time.h"

namespace autodrive::traffic::nema {

/// One phase's timing as both controllers run it.
struct PhaseTiming {
  Duration min_green{0};
  Duration max_green{0};  ///< max 1
  Duration passage{0};
  Duration yellow{0};
  Duration red_clear{0};
  bool recall = false;  ///< min or max recall: always called
};

/// What the diagnosis knows of a run.
struct DiagnosisInput {
  /// The phases in ring order.
  std::vector<std::uint32_t> ring;
  /// Each phase's side of SUMO's middle barrier (0: the places before it, 1: after it).
  std::map<std::uint32_t, int> barrier_side;
  std::map<std::uint32_t, PhaseTiming> timing;
  CallScript calls;
  /// Every interval each side recorded (not only the window's).
  std::vector<Interval> ours;
  std::vector<Interval> sumo;
  Duration step = std::chrono::milliseconds(100);
  Duration tolerance = std::chrono::milliseconds(100);
};

/// The rule ids `Diagnose` gives.
/// SUMO chooses the next phase again during the clearance; ours when the green ends.
inline constexpr const char* kRuleNextPhaseInClearance = "next_phase_in_clearance";
/// SUMO's first green (the phase it starts at its time 0) times nothing before its min green
/// ends (passage, max timer); ours times it as every other green.
inline constexpr const char* kRuleFirstGreen = "first_green";
/// A green held only by its passage (its own detector vacated) with conflicting calls waiting
/// when its own call ended: when they break off and one comes back before the passage has run
/// out, SUMO ends the green at once; ours runs the passage out.
inline constexpr const char* kRulePassageCut = "passage_cut";
/// A green end that matches a max-out or a gap-out on one side only.
inline constexpr const char* kRuleMaxTimer = "max_timer";
inline constexpr const char* kRuleGapTimer = "gap_timer";
inline constexpr const char* kRuleUnexplained = "unexplained";

/// One note per episode of `sequence` (same order). Throws nothing.
[[nodiscard]] std::vector<EpisodeNote> Diagnose(const SequenceComparison& sequence,
                                                const DiagnosisInput& input);

/// The phase our controller serves after `ended` when its green ends at `at`: the first phase
/// after it in ring order with a call at `at` (the next one when none is called).
[[nodiscard]] std::uint32_t OursNextPhase(const DiagnosisInput& input, std::uint32_t ended,
                                          Duration at);

/// The phase SUMO's NEMA controller enters at `green` after `ended`'s green ended at `at`, as
/// it was seen to choose: at `at` the nearest phase after `ended` in ring order with a call (the
/// next one when none is called); then at every step of the yellow and red clearance again the
/// nearest called phase on that phase's side of the barrier, keeping the last choice at a step
/// when none there is called.
[[nodiscard]] std::uint32_t SumoNextPhase(const DiagnosisInput& input, std::uint32_t ended,
                                          Duration at, Duration green);

}  // namespace autodrive::traffic::nema
