#pragma once
/// @file
/// Yellow and Red Actuations (docs/atspm.md): the detector-ons of a phase's channels from its
/// begin yellow to its next green, those after the red clearance began counted as red-light
/// violations, those more than the severe level into it as severe, as UDOT's ATSPM does
/// (utahudot/udot-atspm `Atspm/Application/Business/Common/CycleService.cs`
/// GetYellowRedActivationsCycles, `YellowRedActivations/YellowRedActivationsCycle.cs`,
/// `YellowRedActivationPlan.cs`). Pure functions.

#include <cstdint>
#include <span>
#include <vector>

#include "common/time.h"
#include "scm/atspm/event_log.h"

namespace autodrive::scm::atspm {

/// Counts of actuations over cycles.
struct YellowRedTotals {
  int cycles = 0;
  int volume = 0;              ///< actuations from begin yellow to the next green
  int on_yellow = 0;           ///< up to the red clearance (UDOT's yellow occurrences)
  int violations = 0;          ///< after the red clearance began
  int severe = 0;              ///< more than the severe level after it
  Duration violation_time{0};  ///< sum of each violation's time after the red clearance began
  [[nodiscard]] double percent_violations() const { return Percent(violations, volume); }
  [[nodiscard]] double percent_severe() const { return Percent(severe, volume); }
  [[nodiscard]] double percent_on_yellow() const { return Percent(on_yellow, volume); }
  /// Average time into the red of a violation (UDOT's TRLV); 0 without violations.
  [[nodiscard]] Duration average_violation_time() const;
  void Add(const YellowRedTotals& other);
};

/// Begin yellow (8), begin red clearance (9, end of yellow), red (11, end of red clearance),
/// end of red (the next begin green, 1).
struct YellowRedCycle {
  Time yellow{};
  Time red_clearance{};
  Time red{};
  Time end{};
  std::vector<Time> actuations;  ///< detector-ons in [yellow, end)
  YellowRedTotals totals;
};

/// One phase's actuations.
struct YellowRedPhase {
  std::uint16_t phase = 0;
  std::vector<YellowRedCycle> cycles;
  YellowRedTotals total;
  std::vector<std::pair<PlanSpan, YellowRedTotals>> plans;  ///< cycles by the plan they start in
};

/// Yellow and Red Actuations.
struct YellowRedResult {
  Duration severe_after{0};
  std::vector<YellowRedPhase> phases;  ///< ascending phase number
};

/// Yellow and Red Actuations over `window`: each served phase's cycles 8-9-11-1 that touch the
/// window with the detector-ons of the channels `map` says call the phase; a violation is an
/// actuation after the red clearance began (9), a severe one more than `severe_after` after it
/// (UDOT's SevereLevelSeconds, 5 s by default). Throws InputError when `severe_after` < 0.
[[nodiscard]] YellowRedResult YellowRedActuations(std::span<const Event> events,
                                                  const Window& window, const ChannelMap& map,
                                                  Duration severe_after = std::chrono::seconds(5));

}  // namespace autodrive::scm::atspm
