#pragma once
/// @file
/// The parking agent's local planner: which points of a LIDAR scan are something the maps have
/// not (an unmapped box, a wall standing elsewhere than mapped), and whether any lies on the
/// path ahead. The agent then stops, marks those points in the planner's grid and plans again
/// (examples/parking/README.md).

#include <span>
#include <vector>

#include "common/config.h"
#include "common/geometry.h"
#include "examples/parking/hybrid_astar.h"
#include "maps/occupancy.h"

namespace autodrive::examples {

/// What a LIDAR point must be to be news, and what is done with it.
struct ObstacleParams {
  double range_m = 1.5;         ///< points from beams shorter than this are looked at
  double off_map_m = 0.08;      ///< news: further than this from everything the city map has
  double off_own_map_m = 0.05;  ///< ... and from everything its own map has (--pose pf)
  double cluster_m = 0.05;      ///< ... with `cluster_points` - 1 others within this
  int cluster_points = 3;
  double ahead_m = 0.4;  ///< in the car's body (and margin) along this much of the path: stop
  double mark_radius_m = 0.03;  ///< marked occupied round each point for the next plan
  double body_clear_m = 0.06;   ///< points this close round its own body are not marked

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("range_m", range_m, config::Range{0.2, 12.0});
    a.Optional("off_map_m", off_map_m, config::Range{0.0, 1.0});
    a.Optional("off_own_map_m", off_own_map_m, config::Range{0.0, 1.0});
    a.Optional("cluster_m", cluster_m, config::Range{0.0, 1.0});
    a.Optional("cluster_points", cluster_points, config::Range{1, 360});
    a.Optional("ahead_m", ahead_m, config::Range{0.0, 5.0});
    a.Optional("mark_radius_m", mark_radius_m, config::Range{0.0, 0.5});
    a.Optional("body_clear_m", body_clear_m, config::Range{0.0, 0.5});
  }
};

/// Whether `q` is more than `reach` from every occupied cell of `grid` (something the map has
/// not: a wall seen through the LIDAR's noise stays the wall's). Outside the grid: false.
[[nodiscard]] bool Unmapped(const maps::OccupancyGrid& grid, const Eigen::Vector2d& q,
                            double reach);

/// The points with at least `min_points` - 1 others within `reach` (m): what stands there, not
/// a lone return far out in the LIDAR's noise.
[[nodiscard]] std::vector<Eigen::Vector2d> Clustered(const std::vector<Eigen::Vector2d>& points,
                                                     double reach, int min_points);

/// The points of `scan` (beam i at i 2π / n from the car's front, the LIDAR `lidar_x_m` ahead of
/// the rear axle, the car at `X_MV`) that are news: within `range_m`, off the city map and off
/// its own map (when given), in clusters (map frame).
[[nodiscard]] std::vector<Eigen::Vector2d> NewObstacles(
    std::span<const float> scan, const RigidTransform2& X_MV, double lidar_x_m,
    const maps::OccupancyGrid& city, const maps::OccupancyGrid* own, const ObstacleParams& params);

/// Whether any of `points` lies in the car's body plus `body.margin_m` at a pose of `ahead`
/// within `ahead_m` along it.
[[nodiscard]] bool InTheWay(std::span<const Eigen::Vector2d> points,
                            std::span<const PathPose> ahead, const HybridAStarParams& body,
                            double ahead_m);

/// Whether `q` lies within `clear_m` round the car's body at `X_MV` (not to be marked: its noise,
/// or a box it passes close by).
[[nodiscard]] bool AgainstBody(const Eigen::Vector2d& q, const RigidTransform2& X_MV,
                               const HybridAStarParams& body, double clear_m);

}  // namespace autodrive::examples
