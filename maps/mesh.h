#pragma once
/// @file
/// The map's terrain and static obstacles as a triangulated surface mesh.

#include <string>

#include "maps/map.h"

namespace autodrive::maps {

/// Height of the ground (m) at map point (x, y): the tile's elevation, plus for a ramp the
/// fraction of its rise reached along its local +x. Throws `InputError` outside the map.
[[nodiscard]] double TerrainHeight(const Map& map, double x_m, double y_m);

/// Counts of what `WriteMeshObj` wrote.
struct MeshStats {
  std::size_t vertices = 0;
  std::size_t faces = 0;
};

/// Writes the terrain (two triangles per tile, following ramps; tiles at different heights
/// meet in vertical steps) and every obstacle as a closed box, as one CGAL `Surface_mesh`, to
/// a Wavefront OBJ file. Throws `InputError` when the file cannot be written.
MeshStats WriteMeshObj(const Map& map, const std::string& path);

}  // namespace autodrive::maps
