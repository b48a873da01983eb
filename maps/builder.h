#pragma once
/// @file
/// Builds a `Map` from a `Layout`.

#include "maps/layout.h"
#include "maps/map.h"

namespace autodrive::maps {

/// Parameters of the build that are not part of a layout.
struct BuildOptions {
  /// Spacing of points along lane centrelines and movement paths (m).
  double sample_step_m = 0.02;
  /// Smallest turning radius of any lane or path the builder makes (m). Nigel's is 0.245 m
  /// (wheelbase / tan 30 deg); dead ends and parking loops use this radius.
  double min_turn_radius_m = 0.3;
  /// Two movements whose paths come closer than this conflict (m): Nigel's width 0.175 m plus
  /// a margin.
  double vehicle_clearance_m = 0.2;
};

/// Builds the map. Throws `InputError` for a bad layout, naming the tile (row, column, cell)
/// or obstacle and the reason: a road that meets an edge without a road, mismatched lane
/// counts, an intersection next to an intersection or on the map boundary, a road that ends in
/// a wall, overlapping obstacles, an obstacle outside the map, mismatched ramp heights.
Map Build(const Layout& layout, const BuildOptions& options = {});

}  // namespace autodrive::maps
