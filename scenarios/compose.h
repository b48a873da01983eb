#pragma once
/// @file
/// A scenario's city: the base city file with the scenario's cars, seed, noise, obstacles and
/// SUMO demand, run in lockstep (the lights, then the SCM, then the runner, SUMO and every
/// agent answer each step) and launched without the Eye or the dashboard, written as one city
/// file that `autodrive-city up` runs like any other.

#include <filesystem>
#include <string>
#include <vector>

#include "scenarios/scenario.h"

#include "maps/map.h"

namespace autodrive::scenarios {

/// The lockstep controller name of the runner itself (docs/scenarios.md, "How a run goes").
inline constexpr std::string_view kRunnerController = "scenario";

/// The controller name the agent of car `vehicle` answers the simulator's steps with.
[[nodiscard]] std::string AgentController(const std::string& vehicle);

/// What `ComposeCity` made.
struct ComposedCity {
  std::string yaml;                      ///< the city file's text
  std::string city_name;                 ///< the base city's `name`
  std::string map_path;                  ///< absolute
  std::string operator_name;             ///< the first allowed operator (empty when none)
  std::vector<std::string> controllers;  ///< plain lockstep controllers, the runner first
  bool traffic = false;                  ///< SUMO runs
};

/// Composes the scenario's city, to be written as `city_file` with its run folder `run_dir`,
/// the run's raw logs in `logs_dir` (SUMO writes its trip statistics there, `kTripinfoFile`)
/// and the city's programs in `bin_dir`; `scenario_file` is the scenario's path (for
/// `{scenario}`). Checks what the base city and its map must have for the scenario (its `sim`
/// section, each route's lanes and their order, each event's intersection and plan).
/// @throws ConfigError naming the scenario file, line and key, or the city file.
[[nodiscard]] ComposedCity ComposeCity(const Scenario& scenario,
                                       const std::filesystem::path& scenario_file,
                                       const maps::Map& map, const std::filesystem::path& city_file,
                                       const std::filesystem::path& run_dir,
                                       const std::filesystem::path& logs_dir,
                                       const std::filesystem::path& bin_dir);

}  // namespace autodrive::scenarios
