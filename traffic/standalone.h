#pragma once
/// @file
/// The city's network and demand for SUMO alone (`autodrive-traffic export`): what
/// `CoSimulation` runs, as files that `sumo -c` runs with no lab attached, e.g. to study the
/// traffic in sumo-gui or to check the network with SUMO's own tools. Circulating vehicles get
/// routes long enough for `duration` (the co-simulation extends them as they go instead); the
/// traffic lights keep the export's fixed program (maps/sumo.h), since no lamps drive them.

#include <filesystem>
#include <map>
#include <string>

#include "traffic/traffic_config.h"

#include "common/ids.h"
#include "common/time.h"
#include "maps/sumo.h"

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

/// Writes the network (into `dir`/network) and the demand for `duration` into `dir`. With
/// `plan`, every signalised intersection's lights run that fixed-time plan of the city's
/// (`PlanPrograms`) instead of the export's default program.
/// @throws InputError as CoSimulation's demand checks and maps::ExportSumo.
StandaloneFiles ExportStandalone(const scm::City& city, const TrafficConfig& config,
                                 const std::filesystem::path& dir, Duration duration,
                                 const std::string& plan = "");

/// The SUMO programs of the city's fixed-time plan `plan` at each signalised intersection: per
/// phase its groups' movements green for its green, then the yellow and the red clearance of the
/// groups it ends (the longest of each), with the plan's offset. @throws InputError naming the
/// intersection when it has no plan `plan` or that plan is not fixed-time.
[[nodiscard]] std::map<IntersectionId, maps::SumoSignalProgram> PlanPrograms(
    const scm::City& city, const std::string& plan);

}  // namespace autodrive::traffic
