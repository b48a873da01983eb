#pragma once
/// @file
/// The crosscheck's verdict: the SCM controller's phase intervals against SUMO's NEMA
/// controller's, paired interval by interval, and the report a person reads (text) and a program
/// reads (JSON). Pure: no I/O.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
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

/// How the verdict is reached.
enum class ComparisonMode {
  /// Each of our intervals with SUMO's nearest of the same phase and kind (within half a
  /// cycle), every start and end within the tolerance, the cycle lengths equal (`Compare`): for
  /// fixed-time plans and short scripted runs.
  kPairs,
  /// Both runs' intervals in time order, one after the other: the same phases in the same
  /// order and every start and end within the tolerance (`CompareSequences`): for actuated runs,
  /// where a difference early on shifts everything after it.
  kSequence,
};
/// "pairs", "sequence".
[[nodiscard]] std::string_view ToString(ComparisonMode mode);

/// Where two sequences part.
enum class SequenceDifferenceKind {
  kNone,
  kTime,           ///< the same phase and kind, a start or an end off by more than the tolerance
  kOrder,          ///< another phase or kind of interval at this place
  kMissingInSumo,  ///< ours has an interval here, SUMO's sequence has ended
  kMissingInOurs,  ///< SUMO has an interval in the window after the last of ours
};
/// "none", "time", "order", "missing_in_sumo", "missing_in_ours".
[[nodiscard]] std::string_view ToString(SequenceDifferenceKind kind);

/// One place of the sequences: our interval and SUMO's at the same position.
struct SequencePair {
  std::optional<Interval> ours;
  std::optional<Interval> sumo;
  SequenceDifferenceKind difference = SequenceDifferenceKind::kNone;
};

/// A stretch where the sequences differ: from `first`, the pair where they part, to where they
/// run together again.
struct SequenceEpisode {
  std::size_t first = 0;  ///< index into `SequenceComparison::pairs`
  /// Where both run together again: the start of the next green of one phase in both (within
  /// the tolerance) after an order difference, or the next pair that matches after a time
  /// difference; none when they do not before the window ends.
  std::optional<Duration> rejoin;
  /// Intervals of each side that were passed over to rejoin (after an order difference).
  std::size_t ours_skipped = 0, sumo_skipped = 0;
};

/// The sequence comparison's verdict.
struct SequenceComparison {
  /// Our intervals that begin in the window, in time order, each with SUMO's at the same
  /// position (from SUMO's first interval of the window). After an order difference the pairing
  /// goes on from where the two rejoin (`SequenceEpisode`); a SUMO interval left over at the end
  /// is the last entry.
  std::vector<SequencePair> pairs;
  /// Each stretch of differences, in time order.
  std::vector<SequenceEpisode> episodes;
  /// The earliest entry of `pairs` that does not match (the first episode's).
  std::optional<std::size_t> first_difference;
  /// The largest difference of a start or an end of a pair of the same phase and kind.
  Duration max_difference{0};
  /// Same phases and kinds in the same order through the window (times aside).
  bool order_match = false;
  /// Order and times match, and there was something to compare.
  bool match = false;
};

/// Compares our intervals that begin in [`from`, `to`) with SUMO's in sequence, position by
/// position: SUMO's sequence starts with its first interval that begins at or after `from` -
/// tolerance (one before `from` only when it is the partner of our first). The tolerance applies
/// to each start and end. Where the two part (another phase or kind at a place, or one side has
/// no more), the pairing goes on from the next green both start for one phase within the
/// tolerance. A SUMO interval left over that begins before `to` - tolerance is a difference.
/// `cycle` is not used. Throws nothing.
[[nodiscard]] SequenceComparison CompareSequences(const ComparisonInput& input);

/// Everything else the report says about a run.
struct RunFacts {
  std::string city, intersection, plan, tls, sumo_version;
  int cycles = 0;  ///< cycles compared; 0 when the window was given as a duration
  /// The compared window ends at this time on SUMO's clock (`--duration`) rather than after
  /// `cycles` cycles.
  std::optional<Duration> duration;
  std::string calls_note;  ///< where the calls came from ("random, seed 3, ...")
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

/// What is behind a stretch of differences (`Diagnose`, diagnosis.h): the rule in which the
/// two controllers differ, the evidence from the run, and the setting that removes it.
struct EpisodeNote {
  std::string rule;      ///< a short id: "next_phase_in_clearance", "unexplained", ...
  std::string summary;   ///< the rule in one sentence
  std::string evidence;  ///< times and calls from the run
  std::string remedy;    ///< the config switch (export or plan) or the change that removes it
  bool operator==(const EpisodeNote&) const = default;
};

/// Both comparisons of a run and which one gives the verdict.
struct Verdicts {
  ComparisonMode mode = ComparisonMode::kPairs;
  Comparison pairs;
  SequenceComparison sequence;
  /// Per entry of `sequence.episodes`, when diagnosed.
  std::vector<EpisodeNote> notes;
};

/// True when the comparison matched and SUMO's two outputs agree.
[[nodiscard]] bool Passed(const RunFacts& facts, const Comparison& comparison);
/// True when the comparison `verdicts.mode` names matched and SUMO's two outputs agree.
[[nodiscard]] bool Passed(const RunFacts& facts, const Verdicts& verdicts);

/// "phase 2 green 30.0 - 45.0 s" (or "none").
[[nodiscard]] std::string DescribeInterval(const std::optional<Interval>& interval);
/// One line on where the sequences part: "order: ours phase 2 green 30.0 - 45.0 s, SUMO phase 3
/// green 30.0 - 36.0 s", or "none".
[[nodiscard]] std::string DescribeSequenceDifference(const SequenceComparison& sequence);
/// The same for one pair.
[[nodiscard]] std::string DescribeSequencePair(const SequencePair& pair);
/// Episode `e` of `sequence`: where the sequences part and where they run together again.
[[nodiscard]] std::string DescribeEpisode(const SequenceComparison& sequence, std::size_t e);

/// The report for people: the run, the verdict, the first difference, the cycles and each
/// phase's intervals in both.
[[nodiscard]] std::string ReportText(const RunFacts& facts, const Comparison& comparison);
/// The same with the sequence comparison and the verdict of `verdicts.mode`.
[[nodiscard]] std::string ReportText(const RunFacts& facts, const Verdicts& verdicts);

/// The same as JSON (seconds as numbers).
[[nodiscard]] std::string ReportJson(const RunFacts& facts, const Comparison& comparison);
/// The same with the sequence comparison (`sequence`) and the verdict of `verdicts.mode`
/// (`compare`).
[[nodiscard]] std::string ReportJson(const RunFacts& facts, const Verdicts& verdicts);

}  // namespace autodrive::traffic::nema
