#include "maps/outputs.h"

#include "maps/map_io.h"
#include "maps/mesh.h"

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
  (void)options;
  return written;
}

}  // namespace autodrive::maps
