#pragma once
/// @file
/// A car-like global planner that can reverse, for the parking case study: hybrid A* (Dolgov,
/// Thrun, Montemerlo and Diebel, "Path Planning for Autonomous Vehicles in Unknown Semi-structured
/// Environments", 2010) on an occupancy grid.
///
/// - **States** are the rear axle's pose (x, y, heading), binned into cells of `cell_m` and
///   headings of `heading_bins` for the closed set, kept continuous along the path.
/// - **Motion** is Reeds–Shepp's: from each state, arcs of `step_m` forward and backward at full
///   lock left and right, half lock, and straight (exact arcs of the bicycle model with the
///   car's wheelbase and steering limit: the turning radius L / tan(δmax), 0.245 m for Nigel).
///   Costs are the length driven, backwards weighed by `reverse_cost`, a change of gear adding
///   `gear_change_cost_m`, steering adding `steer_cost` times its fraction of full lock per metre.
/// - **Heuristic**: the larger of the straight-line distance and the shortest 8-connected path
///   on the grid from the goal (obstacles inflated by the car's half width): admissible enough in
///   practice, and it finds its way round the boxes.
/// - **Goal**: a state in the goal's cell and heading bin, then within `goal_tolerance_m` and
///   `goal_tolerance_rad` of the goal (the search goes on until one is). This stands in for the
///   analytic Reeds–Shepp expansion of the paper: the same primitives, searched to the goal.
/// - **Collisions**: the car's body (a rectangle, its centre `centre_ahead_m` ahead of the rear
///   axle) plus `margin_m` on every side, covered by circles checked against the grid's distance
///   to the nearest occupied cell; everything outside the grid is occupied.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/config.h"
#include "common/geometry.h"
#include "maps/occupancy.h"

namespace autodrive::examples {

struct HybridAStarParams {
  double wheelbase_m = 0.14154;
  double steering_limit_rad = 0.5236;
  double length_m = 0.318;          ///< the body
  double width_m = 0.175;           ///< the body
  double centre_ahead_m = 0.07077;  ///< the body's centre ahead of the rear axle
  double margin_m = 0.03;           ///< kept clear around the body
  double step_m = 0.05;             ///< arc length of one motion primitive
  double cell_m = 0.05;
  int heading_bins = 72;  ///< 5°
  double reverse_cost = 1.5;
  double gear_change_cost_m = 0.5;
  double steer_cost = 0.05;
  double goal_tolerance_m = 0.02;
  double goal_tolerance_rad = 0.0524;  ///< 3°: the controller has the rest of 5 cm and 5°
  double leave_m = 0.2;  ///< driven from the start, within which the margin is not kept
  std::size_t max_expansions = 2'000'000;

  /// The tunables (the car's figures come from its city). See examples/parking/parking.yaml.
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("margin_m", margin_m, config::Range{0.0, 0.3});
    a.Optional("step_m", step_m, config::Range{0.005, 0.5});
    a.Optional("cell_m", cell_m, config::Range{0.005, 0.5});
    a.Optional("heading_bins", heading_bins, config::Range{8, 720});
    a.Optional("reverse_cost", reverse_cost, config::Range{1.0, 100.0});
    a.Optional("gear_change_cost_m", gear_change_cost_m, config::Range{0.0, 100.0});
    a.Optional("steer_cost", steer_cost, config::Range{0.0, 100.0});
    a.Optional("goal_tolerance_m", goal_tolerance_m, config::Range{0.001, 1.0});
    a.Optional("goal_tolerance_rad", goal_tolerance_rad, config::Range{0.001, 1.0});
    a.Optional("leave_m", leave_m, config::Range{0.0, 2.0});
    a.Optional("max_expansions", max_expansions, config::Range<std::size_t>{1, 100'000'000});
  }
};

/// One pose of the path, with the gear it is driven in (+1 forward, -1 backward) to reach it.
struct PathPose {
  RigidTransform2 X_MV;
  int gear = 1;
};

struct PlanResult {
  std::vector<PathPose> path;  ///< from the start to the goal; empty when none was found
  std::size_t expansions = 0;
  double length_m = 0.0;
  int gear_changes = 0;
  std::string failure;  ///< why there is no path
};

class HybridAStar {
 public:
  /// Takes a copy of `grid` (occupied cells: obstacles) and computes its distance field.
  HybridAStar(maps::OccupancyGrid grid, const HybridAStarParams& params = {});

  /// A path from `start` to `goal` (rear-axle poses in the map frame).
  [[nodiscard]] PlanResult Plan(const RigidTransform2& start, const RigidTransform2& goal) const;

  /// Marks the cells within `radius_m` of each of `points` (map frame) occupied: unmapped
  /// obstacles seen by the LIDAR, for the next `Plan`. Points outside the grid are skipped.
  void AddObstacles(const std::vector<Eigen::Vector2d>& points, double radius_m);

  /// The grid as planned on (the map's and what `AddObstacles` added).
  [[nodiscard]] const maps::OccupancyGrid& grid() const { return grid_; }

  /// Whether the car's body with the margin at rear-axle pose `X_MV` is clear of the grid's
  /// occupied cells and inside the grid (its cover of circles on the distance field: fast and
  /// conservative, by up to about 9 cm at the bumpers).
  [[nodiscard]] bool Free(const RigidTransform2& X_MV) const;
  /// Whether the body itself, without the margin, is clear: no occupied cell's square within
  /// its rectangle (conservative by half a cell's diagonal). A plan may start within the margin
  /// of an obstacle (the car stopped close to one it just saw): within `leave_m` of its start
  /// its poses need only this.
  [[nodiscard]] bool BodyClear(const RigidTransform2& X_MV) const;

  [[nodiscard]] const HybridAStarParams& params() const { return params_; }
  /// Keeps `margin_m` clear round the body from the next `Plan` on.
  void SetMargin(double margin_m);

 private:
  void ComputeClearance();
  void CoverBody();  // the circles, from the body and its margin
  // Distance (m) from the centre of cell (col, row) to the nearest occupied cell's centre, 0 on
  // an occupied cell and outside the grid.
  [[nodiscard]] double Clearance(const Eigen::Vector2d& p) const;
  // The 8-connected shortest distance (m) from every cell to the goal's, over cells whose
  // clearance is at least the car's half width.
  [[nodiscard]] std::vector<double> GridDistances(const Eigen::Vector2d& goal) const;

  maps::OccupancyGrid grid_;
  HybridAStarParams params_;
  std::vector<double> clearance_;         // per cell
  std::vector<Eigen::Vector2d> circles_;  // centres in the car's frame
  double circle_radius_ = 0.0;
};

}  // namespace autodrive::examples
