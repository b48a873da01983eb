#pragma once
/// @file
/// The Purdue Coordination Diagram, arrivals on green, yellow and red, and approach delay
/// (docs/atspm.md): each detector-on of a phase's channels placed in its red-to-red cycle, as
/// UDOT's ATSPM does (utahudot/udot-atspm `Atspm/Application/Business/Common/CycleService.cs`
/// GetPcdCycles, `DetectorDataPoint.cs`, `CyclePcd.cs`, `LocationPhase.cs`,
/// `PurdueCoordinationPlan.cs`, `ArrivalOnRed/ArrivalOnRedService.cs`,
/// `AppoachDelay/ApproachDelayService.cs`). Pure functions.

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "common/time.h"
#include "scm/atspm/event_log.h"

namespace autodrive::scm::atspm {

/// Where in its cycle a vehicle arrived.
enum class Arrival : std::uint8_t { kRed, kGreen, kYellow };
/// "red", "green", "yellow".
[[nodiscard]] std::string_view ToString(Arrival a);

/// One detector-on in its cycle.
struct ArrivalPoint {
  Time at{};
  Arrival type = Arrival::kRed;
  Duration delay{0};  ///< arrivals on red: to the start of green; 0 otherwise
};

/// Counts and times summed over cycles (a cycle, a plan, a window) or a bin of time.
struct ArrivalTotals {
  int cycles = 0;
  int volume = 0;  ///< detector-ons
  int on_green = 0;
  int on_yellow = 0;
  int on_red = 0;
  Duration delay{0};  ///< total approach delay
  Duration green_time{0};
  Duration yellow_time{0};  ///< begin yellow to the cycle's end (yellow and red clearance)
  Duration red_time{0};
  [[nodiscard]] Duration cycle_time() const { return green_time + yellow_time + red_time; }
  [[nodiscard]] double percent_on_green() const { return Percent(on_green, volume); }
  [[nodiscard]] double percent_on_yellow() const { return Percent(on_yellow, volume); }
  [[nodiscard]] double percent_on_red() const { return Percent(on_red, volume); }
  /// Share of the cycles' time that was green, percent (0 for a bin: it has no cycles).
  [[nodiscard]] double percent_green_time() const;
  /// Percent arrivals on green over percent green time (UDOT's platoon ratio); 0 without either.
  [[nodiscard]] double platoon_ratio() const;
  /// Delay per vehicle; 0 without vehicles.
  [[nodiscard]] Duration delay_per_vehicle() const;
  void Add(const ArrivalPoint& p);
  /// Adds another's counts and times (a cycle's to a plan's).
  void Add(const ArrivalTotals& other);
};

/// A red-to-red cycle: end of yellow (9), green (1), yellow (8), end of yellow (9).
struct PcdCycle {
  Time start{};
  Time green{};
  Time yellow{};
  Time end{};
  std::vector<ArrivalPoint> arrivals;  ///< the detector-ons in [start, end)
  ArrivalTotals totals;
};

/// One phase's diagram and its sums.
struct PcdPhase {
  std::uint16_t phase = 0;
  std::vector<PcdCycle> cycles;
  ArrivalTotals total;                                    ///< over the cycles
  std::vector<std::pair<PlanSpan, ArrivalTotals>> plans;  ///< cycles by the plan they start in
  /// Detector-ons by the bin they fall in (UDOT ArrivalOnRedService, ApproachDelayService):
  /// cycle times are not summed into bins.
  std::vector<std::pair<Window, ArrivalTotals>> bins;
};

/// Purdue Coordination Diagram.
struct PcdResult {
  Duration bin{0};
  std::vector<PcdPhase> phases;  ///< ascending phase number
};

/// The Purdue Coordination Diagram over `window`: each served phase's red-to-red cycles that
/// touch the window (`CodeSequences` 9-1-8-9, `Window::Touches`) with the detector-ons of the
/// channels `map` says call the phase: before green an arrival on red with delay = green - t,
/// from green to yellow on green, from yellow on yellow (UDOT DetectorDataPoint). The bins of
/// `bin` from `window.since` count the detector-ons of the cycles that fall in each.
[[nodiscard]] PcdResult Pcd(std::span<const Event> events, const Window& window,
                            const ChannelMap& map, Duration bin = std::chrono::minutes(15));

}  // namespace autodrive::scm::atspm
