#pragma once
/// @file
/// One run of a scenario (`autodrive-scenario run`): composes its city, brings it up in
/// lockstep through `autodrive-city up` (the launcher's machinery: one process manager),
/// takes part in the lockstep itself as the controller `scenario` (so that it records every
/// step and applies each event at its step), ends the run, tears the city down on every exit,
/// computes the metrics from the logs and writes `report.json` and `report.html`
/// (docs/scenarios.md).

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace autodrive::scenarios {

struct RunOptions {
  std::filesystem::path scenario_file;
  std::filesystem::path out_dir;
  std::filesystem::path bin_dir;          ///< the city's programs (autodrive-city, ...)
  std::optional<std::uint64_t> seed;      ///< overrides the scenario's
  std::string partition;                  ///< DDS partition; empty: one made for this run
  std::vector<std::string> command_line;  ///< for the report
  /// Set (by a signal handler) to end the run early: the city is taken down, the report
  /// says so.
  const std::atomic<bool>* stop = nullptr;
  /// One line per simulated 10 s on stderr.
  bool progress = true;
  /// Records the run's topics (cameras aside) into recording.mcap in the run folder
  /// (`autodrive-city up --record`, docs/recording.md).
  bool record = false;
};

struct RunResult {
  /// 0 every expectation held, 1 one failed (named in `failures`), 2 the run could not be
  /// made (the city did not come up, a process failed), 130 interrupted.
  int exit_code = 2;
  std::vector<std::string> failures;
  nlohmann::json report;
};

/// Runs the scenario and writes the run folder (city.yaml, launcher.log, run/, logs/,
/// report.json, report.html). @throws ConfigError / InputError for a bad scenario or base city,
/// before anything starts.
[[nodiscard]] RunResult RunScenario(const RunOptions& options);

/// The keys of report.json that differ between two runs of the same scenario and seed (where
/// and when it ran, how long it took); every other byte is the same.
[[nodiscard]] const std::vector<std::string>& VolatileReportKeys();

}  // namespace autodrive::scenarios
