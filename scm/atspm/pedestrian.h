#pragma once
/// @file
/// Pedestrian Delay (docs/atspm.md): from a pedestrian's push of the button to the walk it was
/// waiting for, as UDOT's ATSPM computes it (utahudot/udot-atspm `Atspm/Application/Business/
/// PedDelay/PedPhaseService.cs` GetCycles, CountUniquePedDetections, `PedCycle.cs`,
/// `PedPlan.cs`). Pure functions.

#include <cstdint>
#include <span>
#include <vector>

#include "common/time.h"
#include "scm/atspm/event_log.h"

namespace autodrive::scm::atspm {

/// A pedestrian's wait: the call, and the walk that served it.
struct PedCycle {
  Time call{};
  Time walk{};
  [[nodiscard]] Duration delay() const { return walk - call; }
};

/// Delays summed over waits.
struct PedDelayTotals {
  int cycles = 0;  ///< waits (UDOT's cycles with pedestrian requests)
  Duration total{0};
  Duration min{0};
  Duration max{0};
  [[nodiscard]] Duration average() const;
  void Add(const PedCycle& c);
};

/// One pedestrian phase's delays and counts.
struct PedPhase {
  std::uint16_t phase = 0;
  /// The code read as the call: 90 (pedestrian detector on, UDOT's), or 45 (pedestrian call
  /// registered) when the phase logged no 90 but 45s.
  std::uint16_t call_code = 0;
  std::vector<PedCycle> cycles;
  PedDelayTotals total;
  std::vector<std::pair<PlanSpan, PedDelayTotals>> plans;  ///< waits by the plan of their call
  std::vector<std::pair<Window, PedDelayTotals>> bins;     ///< waits by the bin of their call
  int presses = 0;                                         ///< calls in the window
  int requests = 0;           ///< calls with runs of calls counted once
  int unique_detections = 0;  ///< calls at least the time buffer after the last one counted
  int calls_registered = 0;   ///< 45s
  int walks = 0;              ///< 21s
};

/// Pedestrian Delay.
struct PedDelayResult {
  Duration time_buffer{0};
  Duration bin{0};
  std::vector<PedPhase> phases;  ///< ascending phase number
};

/// Pedestrian Delay over `window` for each phase with pedestrian records (21, 22, 45, 89, 90;
/// the parameter of 89/90 is the pedestrian detector, one per phase and numbered like it, as
/// UDOT assumes by default, PedsAre1to1). Among the phase's walks (21), clearances (22) and
/// calls (runs of calls counted once, from the first): a call first in the window and then a
/// walk, a clearance-call-walk and a walk-call-walk are waits from the call to the walk; a
/// walk-call-clearance (a push during the walk) is a wait of 0 (UDOT GetCycles, its cases 1, 2
/// and 4). Bins of `bin` (UDOT: an hour) from `window.since` by the call. Throws InputError
/// when `time_buffer` is negative or `bin` not positive.
[[nodiscard]] PedDelayResult PedestrianDelay(std::span<const Event> events, const Window& window,
                                             Duration time_buffer = std::chrono::seconds(15),
                                             Duration bin = std::chrono::hours(1));

}  // namespace autodrive::scm::atspm
