#pragma once
/// @file
/// The city's network and demand for SUMO alone (`autodrive-traffic export`): what
/// `CoSimulation` runs, as files that `sumo -c` runs with no lab attached, e.g. to study the
/// traffic in sumo-gui or to check the network with SUMO's own tools. Circulating vehicles get
/// routes long enough for `duration` (the co-simulation extends them as they go instead); the
/// traffic lights keep the export's fixed program (maps/sumo.h), since no lamps drive them.

#include <filesystem>

#include "traffic/traffic_config.h"

#include "common/time.h"

namespace autodrive::scm {
struct City;
}

namespace autodrive::traffic {

struct StandaloneFiles {
  std::filesystem::path config_file;  ///< `<city>.sumocfg`: network, vehicle types, routes
  std::filesystem::path route_file;   ///< `<city>.rou.xml`
  std::filesystem::path net_file;
  int vehicles = 0;
};

/// Writes the network (into `dir`/network) and the demand for `duration` into `dir`.
/// @throws InputError as CoSimulation's demand checks and maps::ExportSumo.
StandaloneFiles ExportStandalone(const scm::City& city, const TrafficConfig& config,
                                 const std::filesystem::path& dir, Duration duration);

}  // namespace autodrive::traffic
