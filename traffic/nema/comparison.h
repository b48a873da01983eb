#pragma once
/// @file
/// The crosscheck's verdict: the SCM controller's phase intervals against SUMO's NEMA
/// controller's, paired interval by interval, and the report a person reads (text) and a program
/// reads (JSON). Pure: no I/O.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "traffic/nema/intervals.h"

#include "common/time.h"

namespace autodrive::traffic::nema {

/// What to compare: every interval of ours that begins in [from, to), each with the SUMO
/// interval of the same phase and kind that begins nearest to it.
struct ComparisonInput {
  std::vector<std::uint32_t> phases;  ///< the phases, ring order; the first one times the cycle
  std::vector<Interval> ours;
  std::vector<Interval> sumo;
  Duration from{0};
  Duration to{0};
  Duration tolerance{0};  ///< largest difference of a start or an end that still matches
  /// The plan's cycle (a fixed-time plan's, else the sum of max greens and clearances): a SUMO
  /// interval more than half of it away is not a partner.
  Duration cycle{0};
};

/// One interval of ours and its SUMO partner (either may be missing).
struct IntervalMatch {
  std::uint32_t phase = 0;
  IntervalKind kind = IntervalKind::kGreen;
  std::optional<Interval> ours;
  std::optional<Interval> sumo;
  /// max(|begin difference|, |end difference|) when both are there.
  Duration difference{0};
  bool match = false;

  /// The earliest begin of the two.
  [[nodiscard]] Duration time() const;
};

/// The verdict.
struct Comparison {
  /// By phase (ring order), then time.
  std::vector<IntervalMatch> matches;
  /// The earliest entry of `matches` that does not match.
  std::optional<std::size_t> first_difference;
  /// The largest difference of a paired start or end.
  Duration max_difference{0};
  /// Cycle lengths in the window: the first phase's successive green starts.
  std::vector<Duration> ours_cycles;
  std::vector<Duration> sumo_cycles;
  bool cycles_match = false;
  /// Every interval paired within the tolerance, none of SUMO's left over, cycles equal.
  bool match = false;
};

/// Pairs and compares. Throws nothing.
[[nodiscard]] Comparison Compare(const ComparisonInput& input);

/// Everything else the report says about a run.
struct RunFacts {
  std::string city, intersection, plan, tls, sumo_version;
  int cycles = 0;
  Duration step{0}, tolerance{0}, cycle{0};
  Duration plan_offset{0};  ///< where phase 1's green starts, SUMO's clock mod cycle
  Duration sumo_offset{0};  ///< the tlLogic offset (the coordinated phase's green start)
  std::uint32_t coordinated_phase = 0;
  bool fixed_time = false;
  Duration our_start{0};       ///< when our controller started (SUMO's clock)
  Duration our_plan_start{0};  ///< our first green (after the start-up flash and all red)
  Duration from{0}, to{0};     ///< the compared window
  Duration end{0};             ///< the last step run
  /// Per phase, ring order: its number and its signal groups ("group 1 (east)").
  std::vector<std::pair<std::uint32_t, std::string>> phase_groups;
  /// Steps of the window at which the link states (one character a link) differ.
  std::size_t link_steps = 0, link_steps_differing = 0;
  std::optional<Duration> first_link_difference;
  std::string first_link_ours, first_link_sumo;
  /// SUMO's greens from its states checked against its SaveTLSSwitchTimes file.
  std::size_t switch_greens_checked = 0, switch_greens_disagreeing = 0;
  std::vector<std::string> switch_disagreements;  ///< the first ten
  /// Test-only changes to SUMO's program, said in the report.
  std::vector<std::string> alterations;
  std::string files_note;  ///< where the run's files are
};

/// True when the comparison matched and SUMO's two outputs agree.
[[nodiscard]] bool Passed(const RunFacts& facts, const Comparison& comparison);

/// The report for people: the run, the verdict, the first difference, the cycles and each
/// phase's intervals in both.
[[nodiscard]] std::string ReportText(const RunFacts& facts, const Comparison& comparison);

/// The same as JSON (seconds as numbers).
[[nodiscard]] std::string ReportJson(const RunFacts& facts, const Comparison& comparison);

}  // namespace autodrive::traffic::nema
