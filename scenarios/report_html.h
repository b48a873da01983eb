#pragma once
/// @file
/// The scenario runner's HTML reports (docs/scenarios.md, "The reports"): `report.html` of one
/// run and `summary.html` of a sweep. Each page is one self-contained file: its data as JSON in
/// a `<script type="application/json">`, the vendored uPlot 1.6.32
/// (scenarios/vendor/uplot-1.6.32/) and the page's own script and style inline, and no URL to
/// load (not even a font or an icon), so that it opens as a file:// with the network off and
/// prints. The pages draw themselves in the browser (scenarios/report_web/): every chart is
/// uPlot's; the map is a uPlot chart in x/y mode (`mode: 2`) with one scale on both axes, its
/// road surfaces, marks and the cars' bodies drawn on uPlot's canvas in its draw hooks.

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

namespace autodrive::scenarios {

/// report.html of the run folder `run_dir` whose report.json is `report`: the scenario and its
/// verdict with each expectation, every car's metrics, the map with the cars' tracks and where
/// each infraction happened, each car's speed over time above the lamps of the heads on its
/// route, and the events of the run on a time line (docs/scenarios.md). Reads `run_dir/logs/`
/// (world.json, ground_truth.csv, lamps.csv, spat.jsonl, events.jsonl, requests.jsonl,
/// scenario_events.jsonl); a missing log is named on the page, not an error.
/// @throws InputError for a log that cannot be parsed, naming the file and line.
[[nodiscard]] std::string ReportHtml(const nlohmann::json& report,
                                     const std::filesystem::path& run_dir);

/// summary.html of a sweep from its summary.json (docs/scenarios.md): the sweep and its counts,
/// the variants side by side (per metric mean ± std, worst, n), each metric's values per
/// variant run by run, and every run with a link to its report.html (the run's `report` path
/// with `.html`, relative to the summary's folder as given) and whether it failed (an
/// expectation, or the run could not be made: end reason `failed`).
/// @throws InputError when `summary` is not an object with a list of `variants`, each with a
/// list of `runs`.
[[nodiscard]] std::string SummaryHtml(const nlohmann::json& summary);

}  // namespace autodrive::scenarios
