#pragma once
/// @file
/// The high-resolution event log as the ATSPM measures read it (docs/atspm.md): records of the
/// Indiana enumerations (Purdue/INDOT, TPF-5(377) edition, as UDOT's ATSPM reads them,
/// `Atspm/Data/Enums/IndianaEnumerations.cs`), the window a measure covers, the plans in force
/// (code 131), which detector channels call which phase, and the cycles the measures are built
/// on. Pure functions over a time-ordered vector of records: no store, no DDS, no clock.

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include "common/time.h"

namespace autodrive::scm::atspm {

/// The Indiana codes the measures read (the full enumeration is in docs/atspm.md). The
/// parameter is a phase number for 1-23, a vehicle detector channel for 81/82, a pedestrian
/// detector for 89/90, a pre-emption number for 101-111 and a plan for 131.
namespace code {
inline constexpr std::uint16_t kPhaseBeginGreen = 1;
inline constexpr std::uint16_t kPhaseGapOut = 4;
inline constexpr std::uint16_t kPhaseMaxOut = 5;
inline constexpr std::uint16_t kPhaseForceOff = 6;
inline constexpr std::uint16_t kPhaseGreenTermination = 7;
inline constexpr std::uint16_t kPhaseBeginYellow = 8;
inline constexpr std::uint16_t kPhaseEndYellow = 9;
inline constexpr std::uint16_t kPhaseBeginRedClearance = 10;
inline constexpr std::uint16_t kPhaseEndRedClearance = 11;
inline constexpr std::uint16_t kTspEarlyForceOff = 19;
inline constexpr std::uint16_t kPreemptionForceOff = 20;
inline constexpr std::uint16_t kPedBeginWalk = 21;
inline constexpr std::uint16_t kPedBeginClearance = 22;
inline constexpr std::uint16_t kPedBeginSolidDontWalk = 23;
inline constexpr std::uint16_t kPedCallRegistered = 45;
inline constexpr std::uint16_t kDetectorOff = 81;
inline constexpr std::uint16_t kDetectorOn = 82;
inline constexpr std::uint16_t kPedDetectorOff = 89;
inline constexpr std::uint16_t kPedDetectorOn = 90;
inline constexpr std::uint16_t kPreemptAdvanceWarning = 101;
inline constexpr std::uint16_t kPreemptCallInputOn = 102;
inline constexpr std::uint16_t kPreemptGateDown = 103;
inline constexpr std::uint16_t kPreemptCallInputOff = 104;
inline constexpr std::uint16_t kPreemptEntryStarted = 105;
inline constexpr std::uint16_t kPreemptBeginTrackClearance = 106;
inline constexpr std::uint16_t kPreemptBeginDwell = 107;
inline constexpr std::uint16_t kPreemptLinkActive = 108;
inline constexpr std::uint16_t kPreemptLinkInactive = 109;
inline constexpr std::uint16_t kPreemptMaxPresenceExceeded = 110;
inline constexpr std::uint16_t kPreemptBeginExit = 111;
inline constexpr std::uint16_t kCoordPatternChange = 131;
inline constexpr std::uint16_t kSplit1Change = 134;  ///< 134..149: split of phase 1..16, s
inline constexpr std::uint16_t kSplit16Change = 149;
}  // namespace code

/// One record of the log: when, the code and its parameter.
struct Event {
  Time at{};
  std::uint16_t code = 0;
  std::uint16_t param = 0;
  bool operator==(const Event&) const = default;
};

/// The stretch of time a measure covers: `since <= t < until`.
struct Window {
  Time since{};
  Time until{};
  [[nodiscard]] bool Contains(Time t) const { return since <= t && t < until; }
  /// UDOT's rule for a cycle (CycleService, every Get*Cycles): it belongs to the window when
  /// its start or its end lies in [since, until].
  [[nodiscard]] bool Touches(Time start, Time end) const {
    return (since <= start && start <= until) || (since <= end && end <= until);
  }
};

/// Throws InputError when `events` are not in time order (records of one instant keep the
/// order they were logged in), naming the first record out of order and its predecessor's
/// time; or when `window` ends before it starts.
void CheckInput(std::span<const Event> events, const Window& window);

/// A plan in force from `start` to `end`: the parameter of code 131 (the SCM's plan number,
/// from 1), 0 when the log does not say (no 131 at or before `start`: UDOT's "unknown").
struct PlanSpan {
  std::uint16_t plan = 0;
  Time start{};
  Time end{};
  [[nodiscard]] bool Contains(Time t) const { return start <= t && t < end; }
};

/// The plans in force in `window`, in order: the one at `since` (the last 131 at or before it,
/// else 0), then one from each 131 inside the window, the last to `until` (UDOT
/// PlanService.SetFirstAndLastPlan).
[[nodiscard]] std::vector<PlanSpan> PlansIn(std::span<const Event> events, const Window& window);

/// Which vehicle detector channels (the parameter of 81/82) call which phase, under every plan
/// or under one plan (UDOT configures this per approach; the SCM's city file gives it per
/// plan). Copyable value.
class ChannelMap {
 public:
  /// `channel` calls `phase` whatever plan runs.
  void Add(std::uint16_t channel, std::uint16_t phase);
  /// `channel` calls `phase` while plan `plan` (131's parameter) runs. Once a plan has entries
  /// of its own, only they count under it.
  void Add(std::uint16_t plan, std::uint16_t channel, std::uint16_t phase);
  /// True when `channel` calls `phase` under `plan` (0: not known; the entries for every plan).
  [[nodiscard]] bool Calls(std::uint16_t plan, std::uint16_t channel, std::uint16_t phase) const;
  [[nodiscard]] bool empty() const { return any_plan_.empty() && by_plan_.empty(); }

 private:
  using Pairs = std::vector<std::array<std::uint16_t, 2>>;  // {channel, phase}
  Pairs any_plan_;
  std::map<std::uint16_t, Pairs> by_plan_;
};

/// The times of the detector-on events (82) of the channels that call `phase` under the plan
/// in force at each, in order.
[[nodiscard]] std::vector<Time> DetectorOns(std::span<const Event> events, const ChannelMap& map,
                                            std::uint16_t phase);

/// A detector occupied from `on` to `off`.
struct Activation {
  Time on{};
  Time off{};
};

/// The occupancy of the channels that call `phase`: each channel's on (82) directly followed by
/// its off (81) is an activation; a channel whose first record in the log is an off was on
/// from `window.since`, one whose last is an on stays on to `window.until`; overlapping
/// activations of several channels are merged (UDOT SplitFailPhaseService:
/// AddDetectorActivationsFromList, AddDetectorOnToBeginningIfNecessary,
/// AddDetectorOffToEndIfNecessary, CombineDetectorActivations). In order of `on`.
[[nodiscard]] std::vector<Activation> Activations(std::span<const Event> events,
                                                  const ChannelMap& map, std::uint16_t phase,
                                                  const Window& window);

/// The time the activations occupy inside [from, to). `activations` as `Activations` returns
/// them: in order and not overlapping.
[[nodiscard]] Duration OccupiedTime(std::span<const Activation> activations, Time from, Time to);

/// The phases with a begin green (1) in `window`, ascending.
[[nodiscard]] std::vector<std::uint16_t> PhasesServed(std::span<const Event> events,
                                                      const Window& window);

/// Consecutive bins of `bin` from `window.since`, the last cut at `until` (UDOT bins its
/// 15-minute series from the report's start).
[[nodiscard]] std::vector<Window> Bins(const Window& window, Duration bin);

/// The times of each run of four records of `phase` matching `pattern`, found among its
/// records whose code is in `codes` (UDOT CycleService: GetRedToRedCycles 9-1-8-9,
/// GetGreenToGreenCycles 1-8-9-1, GetYellowRedActivationsCycles 8-9-11-1). A run
/// interrupted by a missing or extra record of those codes is no cycle.
[[nodiscard]] std::vector<std::array<Time, 4>> CodeSequences(
    std::span<const Event> events, std::uint16_t phase, std::span<const std::uint16_t> codes,
    const std::array<std::uint16_t, 4>& pattern);

/// A phase's green (1), begin yellow (8) and end of yellow (9): the records of UDOT's red-to-red
/// and green-to-green cycles.
inline constexpr std::array<std::uint16_t, 3> kGreenYellowRed{
    code::kPhaseBeginGreen, code::kPhaseBeginYellow, code::kPhaseEndYellow};

/// Totals `T` for each of `spans` (plans or bins), all empty.
template <class T, class Span>
[[nodiscard]] std::vector<std::pair<Span, T>> EmptyTotals(const std::vector<Span>& spans) {
  std::vector<std::pair<Span, T>> totals;
  for (const Span& s : spans) totals.push_back({s, T{}});
  return totals;
}

/// Adds `x` (`T::Add`) to the totals of the span that holds `t`.
template <class Span, class T, class X>
void AddAt(std::vector<std::pair<Span, T>>& totals, Time t, const X& x) {
  for (auto& [span, total] : totals) {
    if (span.Contains(t)) total.Add(x);
  }
}

/// UDOT's percentile of a split (SplitMonitorService.GetPercentSplit): the value at rank
/// p * n of the sorted values (1-based), interpolated between neighbours; 0 for two values or
/// fewer. `p` in (0, 1].
[[nodiscard]] Duration Percentile(std::vector<Duration> values, double p);

/// `part` / `whole` in percent; 0 when `whole` is 0.
[[nodiscard]] double Percent(double part, double whole);

}  // namespace autodrive::scm::atspm
