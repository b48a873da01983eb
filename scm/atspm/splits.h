#pragma once
/// @file
/// Purdue Phase Termination and Split Monitor (docs/atspm.md): how each phase's greens ended
/// and how long each phase was served, from begin green (1) to end of red clearance (11), as
/// UDOT's ATSPM computes them (utahudot/udot-atspm `Atspm/Application/Business/Common/
/// AnalysisPhaseService.cs`, `AnalysisPhaseCycleCollection.cs`, `SplitMonitor/
/// SplitMonitorService.cs`). Pure functions.

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "common/time.h"
#include "scm/atspm/event_log.h"

namespace autodrive::scm::atspm {

/// How a green ended: the code logged with its green termination (7). UDOT reads 4, 5 and 6;
/// the SCM also ends greens for V2I requests with 19 and 20, which UDOT would leave unknown.
enum class Termination : std::uint8_t {
  kUnknown,             ///< a 7 alone
  kGapOut,              ///< 4
  kMaxOut,              ///< 5
  kForceOff,            ///< 6
  kTspEarlyForceOff,    ///< 19
  kPreemptionForceOff,  ///< 20
};
inline constexpr std::size_t kTerminationTypes = 6;
/// "unknown", "gap_out", "max_out", "force_off", "tsp_early_force_off", "preemption_force_off".
[[nodiscard]] std::string_view ToString(Termination t);
/// The termination a code logs (4, 5, 6, 19, 20), or nothing.
[[nodiscard]] std::optional<Termination> TerminationOf(std::uint16_t code);

/// One service of a phase: begin green (1) to end of red clearance (11).
struct PhaseCycle {
  Time green{};
  std::optional<Time> yellow;         ///< begin yellow (8)
  std::optional<Time> red_clearance;  ///< begin red clearance (10; end yellow, 9, without it)
  Time end{};
  Termination termination = Termination::kUnknown;  ///< the last 4/5/6/19/20 in the green
  /// Walk (21) to solid don't walk (23) inside the service (UDOT SetPedTimesForCycle); zero
  /// length when only one of them is there.
  std::optional<Time> walk;
  Duration walk_time{0};

  [[nodiscard]] Duration split() const { return end - green; }
  [[nodiscard]] Duration green_time() const { return yellow.value_or(end) - green; }
  [[nodiscard]] Duration yellow_time() const;
  [[nodiscard]] Duration red_clearance_time() const {
    return red_clearance ? end - *red_clearance : Duration::zero();
  }
};

/// The services of `phase` that touch `window` (UDOT's rule, `Window::Touches`), in order. A
/// begin green without its end of red clearance (the log ends, a record is missing, a
/// fail-safe cut it) is no service; an end without its begin green (the log starts
/// mid-cycle) neither.
[[nodiscard]] std::vector<PhaseCycle> PhaseCycles(std::span<const Event> events,
                                                  std::uint16_t phase, const Window& window);

/// A termination of a green.
struct TerminationEvent {
  Time at{};
  Termination type = Termination::kUnknown;
  /// The `consecutive`-th or later of a run of its type among the phase's terminations.
  bool consecutive = false;
};

/// A phase's terminations in the window.
struct PhaseTerminations {
  std::uint16_t phase = 0;
  std::vector<TerminationEvent> events;
  std::array<int, kTerminationTypes> counts{};              ///< by Termination
  std::array<int, kTerminationTypes> consecutive_counts{};  ///< those marked consecutive
  [[nodiscard]] int count(Termination t) const { return counts[static_cast<std::size_t>(t)]; }
  /// Share of `t` among the known terminations (all but unknown), percent.
  [[nodiscard]] double percent(Termination t) const;
};

/// Purdue Phase Termination.
struct PhaseTerminationResult {
  int consecutive = 1;
  std::vector<PlanSpan> plans;
  std::vector<PhaseTerminations> phases;  ///< ascending phase number
};

/// Purdue Phase Termination over `window`: each phase's terminations (4, 5, 6, and 19, 20),
/// a green termination (7) logged at the same instant as one of them dropped, one alone kept as
/// unknown (UDOT CleanTerminationEvents); a termination is consecutive when it is at least the
/// `consecutive`-th of a run of its type (UDOT FindConsecutiveEvents; its default is 1: all).
/// The phases are those with a begin green or a termination in the window. Throws InputError
/// when `consecutive` < 1.
[[nodiscard]] PhaseTerminationResult PhaseTermination(std::span<const Event> events,
                                                      const Window& window, int consecutive = 1);

/// A plan's statistics of one phase's splits.
struct SplitPlanStats {
  PlanSpan plan;
  int cycles = 0;  ///< services wholly inside the plan
  Duration average{0};
  Duration min{0};
  Duration max{0};
  Duration p50{0};  ///< UDOT's percentiles (`Percentile`): 0 for 2 services or fewer
  Duration p85{0};
  /// Per service of the phase most served in the plan ("high cycle count"), percent.
  double percent_gap_outs = 0;
  double percent_max_outs = 0;
  double percent_force_offs = 0;
  double percent_skips = 0;
  /// The split a coordination pattern programs (134..149 within 2 s of the plan's start).
  std::optional<Duration> programmed;
};

/// One phase's split monitor.
struct SplitMonitorPhase {
  std::uint16_t phase = 0;
  std::vector<PhaseCycle> cycles;
  std::vector<SplitPlanStats> plans;
};

/// Split Monitor.
struct SplitMonitorResult {
  std::vector<PlanSpan> plans;
  std::vector<SplitMonitorPhase> phases;  ///< ascending phase number
};

/// Split Monitor over `window`: each served phase's services (`PhaseCycles`) and, per plan,
/// their statistics (UDOT SplitMonitorService.GetSplitMonitorPlansWithStatistics).
[[nodiscard]] SplitMonitorResult SplitMonitor(std::span<const Event> events, const Window& window);

}  // namespace autodrive::scm::atspm
