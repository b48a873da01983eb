#pragma once
/// @file
/// Points on a polyline (a lane's centreline, a movement's path): the one nearest to a point,
/// and the one at an arc length. Brute force over the segments: for one line at a time (a
/// whole map's lanes go through `MapIndex`).

#include <limits>
#include <utility>

#include <Eigen/Core>

#include "maps/map.h"

namespace autodrive::maps {

/// The point of a polyline nearest to a query point.
struct PolylinePoint {
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
  double along_m = 0.0;  ///< its arc length from the line's start
  double distance_m = std::numeric_limits<double>::infinity();  ///< from the query point
  double direction_rad = 0.0;                                   ///< of the line's segment there
  double length_m = 0.0;                                        ///< the whole line's
};

/// The point of `line` nearest to `p` (the first of equally near ones); distance infinite for
/// a line of fewer than two distinct points.
[[nodiscard]] PolylinePoint NearestOnPolyline(const Polyline& line, const Eigen::Vector2d& p);

/// The point `along` metres along `line` (clamped to its ends) and the line's direction there.
[[nodiscard]] std::pair<Eigen::Vector2d, double> PointAlong(const Polyline& line, double along);

/// The line's length (m).
[[nodiscard]] double PolylineLength(const Polyline& line);

}  // namespace autodrive::maps
