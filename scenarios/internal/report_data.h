#pragma once
/// @file
/// What the report pages draw (scenarios/report_html.h), as the JSON they carry: report.json
/// with the run folder's logs made ready to chart (the cars' tracks thinned, each head's lamp
/// as bands of one aspect, the events of every log on one time line, where each infraction
/// happened), and a sweep's summary.json checked for what summary.html reads. Pure: files in,
/// JSON out, no DDS.

#include <filesystem>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "scenarios/internal/lamp_bands.h"

namespace autodrive::scenarios::internal {

/// The most samples of one car's track a page carries: a longer track is thinned to every n-th
/// step (its last sample kept), so that a page stays a few MB for an hour's run of many cars.
inline constexpr std::size_t kMaxTrackSamples = 3000;

/// The data report.html draws: `report` (report.json) with, from `run_dir`'s `logs/`:
/// `world` (lanes, statics, stop lines, bounds; null without world.json), `cars` (each car's
/// thinned track t/x/y/yaw/v, body, route, the stop lines on its route with their heads and
/// when its front crossed each, and `marks`: each collision, violation, departure and its goal
/// with where it happened), `heads` (each head's `bands`), `timeline` (`rows` and `marks`: the
/// scenario's events applied, SPaT plan and status changes, the SCM's events, V2I requests and
/// their answers, each car's infractions) and `notes` (a log that was missing).
/// @throws InputError for a log that cannot be parsed, naming the file and line.
[[nodiscard]] nlohmann::json ReportPageData(const nlohmann::json& report,
                                            const std::filesystem::path& run_dir);

/// The data summary.html draws: `summary` (summary.json, docs/scenarios.md) with, for each run,
/// `html` (its report.html: the `report` path with `.html` for `.json`, relative as given), and
/// for each variant `stats` completed (n, mean, std, min, max) for a metric the summary gives no
/// statistics of; `metrics` is the summary's list, or every metric a run has.
/// @throws InputError when `summary` is not an object with a list of `variants`, or a variant
/// has no list of `runs`.
[[nodiscard]] nlohmann::json SummaryPageData(const nlohmann::json& summary);

}  // namespace autodrive::scenarios::internal
