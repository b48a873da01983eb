#pragma once
/// @file
/// The ATSPM measures by name, computed and written out for `scmctl atspm` (docs/atspm.md): a
/// table for people and a JSON object for programs, from the same result.

#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/time.h"
#include "scm/atspm/event_log.h"

namespace autodrive::scm::atspm {

/// The measures `scmctl atspm --measure` computes.
enum class Measure : std::uint8_t {
  kPhaseTermination,
  kSplitMonitor,
  kPcd,
  kArrivals,  ///< the PCD's arrivals on green/yellow/red and approach delay, by bin
  kYellowRed,
  kSplitFailure,
  kPedDelay,
  kPreemption,
};
/// The command line's names: "phase-termination", "split-monitor", "pcd", "arrivals",
/// "yellow-red", "split-failure", "ped-delay", "preemption".
[[nodiscard]] std::string_view ToString(Measure m);
/// The measure called `name`, or nothing.
[[nodiscard]] std::optional<Measure> ParseMeasure(std::string_view name);
/// Every measure's name, in the order above.
[[nodiscard]] std::vector<std::string> MeasureNames();
/// True for the measures that read vehicle detectors (81/82) and so need a `ChannelMap`.
[[nodiscard]] bool ReadsDetectors(Measure m);

/// The measures' parameters, UDOT's defaults (its MeasureOptionsConfiguration seed data).
struct MeasureOptions {
  int consecutive = 1;                                  ///< phase termination
  Duration severe_after = std::chrono::seconds(5);      ///< yellow-red: severe violation
  Duration first_of_red = std::chrono::seconds(5);      ///< split failure
  Duration bin = std::chrono::minutes(15);              ///< pcd, arrivals, split failure
  Duration ped_time_buffer = std::chrono::seconds(15);  ///< pedestrian unique detections
  Duration ped_bin = std::chrono::hours(1);             ///< pedestrian delay
};

/// A measure as a table and as JSON.
struct Report {
  nlohmann::json json;
  std::string text;
};

/// Computes `measure` over `window` of `events` (time-ordered; checked, `CheckInput`) and
/// writes it out. Throws InputError on bad input or options.
[[nodiscard]] Report Compute(Measure measure, std::span<const Event> events, const Window& window,
                             const ChannelMap& map, const MeasureOptions& options = {});

/// A time as ATSPM's files write it: local "YYYY-MM-DD HH:MM:SS.s" (the host's TZ), to the tenth.
[[nodiscard]] std::string LocalTime(Time t);

}  // namespace autodrive::scm::atspm
