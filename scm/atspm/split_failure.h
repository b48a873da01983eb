#pragma once
/// @file
/// Purdue Split Failure (docs/atspm.md): a green that did not clear its queue, seen as the
/// detectors of its phase occupied more than 79 % of the green and more than 79 % of the first
/// seconds of the red that follows, as UDOT's ATSPM computes it (utahudot/udot-atspm
/// `Atspm/Application/Business/Common/CycleService.cs` GetSplitFailCycles,
/// `Common/CycleSplitFail.cs`, `SplitFail/SplitFailPhaseService.cs`, `SplitFail/SplitFailBin.cs`).
/// Pure functions.

#include <cstdint>
#include <span>
#include <vector>

#include "common/time.h"
#include "scm/atspm/event_log.h"
#include "scm/atspm/splits.h"

namespace autodrive::scm::atspm {

/// A split fails when both occupancies are above this, percent (CycleSplitFail).
inline constexpr double kSplitFailThreshold = 79.0;

/// A green-to-green cycle: green (1), yellow (8), red (9, end of yellow), next green (1).
struct SplitFailCycle {
  Time green{};
  Time yellow{};
  Time red{};
  Time end{};
  Termination termination = Termination::kUnknown;  ///< the first 4/5/6/19/20 after the green
  double green_occupancy = 0;  ///< percent of [green, yellow) the detectors were occupied
  double red_occupancy = 0;    ///< percent of [red, red + first seconds of red)
  bool failed = false;
};

/// Counts over cycles.
struct SplitFailTotals {
  int cycles = 0;
  int failures = 0;
  double green_occupancy_sum = 0;  ///< percent, summed over the cycles
  double red_occupancy_sum = 0;
  [[nodiscard]] double percent_failures() const { return Percent(failures, cycles); }
  [[nodiscard]] double average_green_occupancy() const;
  [[nodiscard]] double average_red_occupancy() const;
  void Add(const SplitFailCycle& c);
};

/// One phase's split failures.
struct SplitFailPhase {
  std::uint16_t phase = 0;
  std::vector<SplitFailCycle> cycles;
  SplitFailTotals total;
  std::vector<std::pair<PlanSpan, SplitFailTotals>> plans;  ///< cycles by the plan they start in
  std::vector<std::pair<Window, SplitFailTotals>> bins;     ///< cycles by the bin they start in
};

/// Purdue Split Failure.
struct SplitFailResult {
  Duration first_of_red{0};
  Duration bin{0};
  std::vector<SplitFailPhase> phases;  ///< ascending phase number
};

/// Purdue Split Failure over `window`: each served phase's cycles 1-8-9-1 that touch the window,
/// the occupancy of the channels `map` says call the phase (`Activations`) over the green and
/// over the first `first_of_red` of the red (UDOT's FirstSecondsOfRed, 5 s by default); a split
/// failure when both are above `kSplitFailThreshold`. Bins of `bin` from `window.since` count
/// the cycles that start in each. Throws InputError when `first_of_red` or `bin` is not
/// positive.
[[nodiscard]] SplitFailResult SplitFailure(std::span<const Event> events, const Window& window,
                                           const ChannelMap& map,
                                           Duration first_of_red = std::chrono::seconds(5),
                                           Duration bin = std::chrono::minutes(15));

}  // namespace autodrive::scm::atspm
