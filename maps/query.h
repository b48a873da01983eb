#pragma once
/// @file
/// Spatial queries on a built map: which lane a point is on or nearest to, and whether a
/// point is drivable. Used to place vehicles on the map (fleet state: lane, approach,
/// distance to the stop line).

#include <memory>
#include <optional>

#include <Eigen/Core>

#include "maps/map.h"

namespace autodrive::maps {

/// The nearest point of a lane's centreline to a query point.
struct LaneMatch {
  LaneId lane{0};
  double distance_m = 0.0;  ///< from the query point to the centreline
  double along_m = 0.0;     ///< arc length from the lane's start to the nearest point
  Eigen::Vector2d point = Eigen::Vector2d::Zero();  ///< the nearest point
};

/// An index over a map's lanes (a CGAL AABB tree of centreline segments) and drivable regions.
/// Holds a reference to the map, which must outlive it. Not copyable; queries are const and
/// thread-safe.
class MapIndex {
 public:
  explicit MapIndex(const Map& map);
  ~MapIndex();
  MapIndex(const MapIndex&) = delete;
  MapIndex& operator=(const MapIndex&) = delete;

  /// The lane whose centreline passes nearest to `p_M`, if any lane is within `max_distance_m`.
  [[nodiscard]] std::optional<LaneMatch> NearestLane(
      const Eigen::Vector2d& p_M,
      double max_distance_m = std::numeric_limits<double>::infinity()) const;
  /// The lane nearest to `p_M`, within `max_distance_m`, that runs the way of `yaw_rad`: its
  /// centreline's direction there within `max_angle_rad` of it. A car's lane, where the lane
  /// beside it (the other way) may be nearer: a car cutting a curve, or near a tile's join.
  [[nodiscard]] std::optional<LaneMatch> NearestLaneHeading(const Eigen::Vector2d& p_M,
                                                            double yaw_rad, double max_distance_m,
                                                            double max_angle_rad) const;
  /// True when `p_M` lies in the drivable area (road surface minus obstacles), boundary
  /// included.
  [[nodiscard]] bool IsDrivable(const Eigen::Vector2d& p_M) const;

 private:
  struct Impl;
  const Map& map_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace autodrive::maps
