#include "maps/outputs.h"

#include "maps/map_io.h"
#include "maps/mesh.h"
#include "maps/occupancy.h"
#include "maps/render.h"
#include "maps/sumo.h"

namespace autodrive::maps {

std::vector<std::string> WriteOutputs(const Map& map, const std::string& dir,
                                      const OutputOptions& options) {
  std::vector<std::string> written;
  const std::string map_yaml = dir + "/map.yaml";
  SaveMap(map, map_yaml);
  written.push_back(map_yaml);
  const std::string mesh = dir + "/mesh.obj";
  WriteMeshObj(map, mesh);
  written.push_back(mesh);
  const std::string pgm = dir + "/occupancy.pgm";
  const std::string pgm_yaml = dir + "/occupancy.yaml";
  WriteOccupancyGrid(MakeOccupancyGrid(map, options.occupancy_resolution_m), pgm, pgm_yaml);
  written.push_back(pgm);
  written.push_back(pgm_yaml);
  if (options.images) {
    RenderPng(map, dir + "/map.png");
    RenderSvg(map, dir + "/map.svg");
    written.push_back(dir + "/map.png");
    written.push_back(dir + "/map.svg");
  }
  if (options.sumo && !map.lanes.empty()) {
    const SumoExport sumo = ExportSumo(map, dir + "/sumo");
    for (const auto& f : {sumo.node_file, sumo.edge_file, sumo.connection_file, sumo.tll_file,
                          sumo.net_file, sumo.vtype_file}) {
      written.push_back(f);
    }
  }
  return written;
}

}  // namespace autodrive::maps
