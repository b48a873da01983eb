#pragma once
/// @file
/// The distance from each cell of an occupancy grid to the nearest occupied cell, centre to
/// centre (exact Euclidean, OpenCV's distance transform), in metres, row-major like the grid.
/// Shared by the planner's collision checks and the particle filter's likelihood field.

#include <vector>

#include "maps/occupancy.h"

namespace autodrive::examples {

[[nodiscard]] std::vector<float> DistanceToOccupied(const maps::OccupancyGrid& grid);

}  // namespace autodrive::examples
