#pragma once
/// @file
/// Everything `autodrive-map build` writes for a built map.

#include <string>
#include <vector>

#include "maps/map.h"

namespace autodrive::maps {

/// Which outputs to write.
struct OutputOptions {
  double occupancy_resolution_m = 0.05;
  bool sumo = true;
  bool images = true;
};

/// Writes into `dir` (which must exist): map.yaml, mesh.obj, and, as they are available, the
/// occupancy grid (occupancy.pgm + occupancy.yaml), map.png and map.svg, and the SUMO network
/// (sumo/, for maps that have lanes).
/// Returns the paths written. Throws `InputError` / `ConfigError` on failure.
std::vector<std::string> WriteOutputs(const Map& map, const std::string& dir,
                                      const OutputOptions& options);

}  // namespace autodrive::maps
