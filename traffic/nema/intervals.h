#pragma once
/// @file
/// The intervals a phase runs through, recorded from what the lights show at each step: green,
/// yellow and red clearance, each with its start and end. The crosscheck records the SCM's
/// controller and SUMO's NEMA controller with the same recorder, so that both are measured by
/// one rule.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "common/time.h"

namespace autodrive::traffic::nema {

/// What a phase shows: green while all its movements are green, yellow while any is yellow,
/// red otherwise (flashing and dark count as red).
enum class PhaseSignal { kRed, kYellow, kGreen };

/// The kinds of interval a phase runs through.
enum class IntervalKind { kGreen, kYellow, kRedClearance };
/// "green", "yellow", "red_clearance".
[[nodiscard]] std::string_view ToString(IntervalKind kind);

/// One interval of one phase: [begin, end) on the run's timeline (SUMO's clock).
struct Interval {
  std::uint32_t phase = 0;
  IntervalKind kind = IntervalKind::kGreen;
  Duration begin{0};
  Duration end{0};
  bool operator==(const Interval&) const = default;
};

/// Records the intervals of a set of phases from samples of their signals. A green or a yellow
/// lasts from the first sample that shows it to the first that does not; a red clearance from
/// the end of the phase's yellow to the next sample at which a phase's green starts (any
/// phase: the one-ring plans the crosscheck runs serve one phase at a time). Value type.
class IntervalRecorder {
 public:
  /// Records `phases` (NEMA phase numbers); samples give their signals in this order.
  explicit IntervalRecorder(std::vector<std::uint32_t> phases);

  /// The signals at `t`, one per phase; `t` after the previous sample's. An interval under way
  /// at the first sample starts there.
  void Sample(Duration t, const std::vector<PhaseSignal>& signals);

  /// The intervals that have ended, in the order they ended (by phase within one instant).
  [[nodiscard]] const std::vector<Interval>& intervals() const { return done_; }
  /// The time of the first sample at which a phase was green, if any.
  [[nodiscard]] std::optional<Duration> first_green() const { return first_green_; }

 private:
  std::vector<std::uint32_t> phases_;
  std::vector<PhaseSignal> last_;
  std::vector<std::optional<Interval>> open_;       ///< green or yellow under way
  std::vector<std::optional<Interval>> clearance_;  ///< red clearance under way
  std::vector<Interval> done_;
  std::optional<Duration> first_green_;
  bool started_ = false;
};

}  // namespace autodrive::traffic::nema
