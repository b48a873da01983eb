#pragma once
/// @file
/// Builds a `Map` from a `Layout`.

#include "maps/layout.h"
#include "maps/map.h"

namespace autodrive::maps {

/// Builds the map. Throws `InputError` for a bad layout, naming the tile (row, column, cell)
/// or obstacle and the reason: a road that meets an edge without a road, mismatched lane
/// counts, an intersection next to an intersection or on the map boundary, a road that ends in
/// a wall, overlapping obstacles, an obstacle outside the map, mismatched ramp heights.
Map Build(const Layout& layout, const BuildOptions& options = {});

}  // namespace autodrive::maps
