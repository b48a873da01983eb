#pragma once
/// @file
/// Occupancy-grid SLAM from the LIDAR in the style of Hector SLAM (Kohlbrecher, von Stryk, Meyer
/// and Klingauf, "A Flexible and Scalable SLAM System with Full 3D Motion Estimation", 2011):
/// each scan is matched to the map built so far by Gauss-Newton on the map's bilinearly
/// interpolated occupancy and its gradient (from the odometry's guess, coarse to fine over three
/// resolutions), then written into every resolution's log-odds grid (its end points occupied,
/// the cells its beams cross free). No loop closure: Hector's front end.

#include <span>
#include <vector>

#include "common/config.h"
#include "common/geometry.h"
#include "maps/occupancy.h"

namespace autodrive::examples {

struct SlamParams {
  double resolution_m = 0.025;  ///< the finest grid; the others are 2x and 4x
  Eigen::Vector2d origin_m = Eigen::Vector2d::Zero();
  double width_m = 4.0, height_m = 4.0;
  double max_range_m = 3.0;
  double log_odds_hit = 0.85, log_odds_miss = -0.4, log_odds_limit = 5.0;
  int iterations = 6;  ///< Gauss-Newton steps per resolution
  double lidar_x_m = 0.1445;

  /// The tunables (its extent is the map's, its range the filter's). See
  /// examples/parking/parking.yaml.
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("log_odds_hit", log_odds_hit, config::Range{0.01, 10.0});
    a.Optional("log_odds_miss", log_odds_miss, config::Range{-10.0, -0.01});
    a.Optional("log_odds_limit", log_odds_limit, config::Range{0.1, 100.0});
    a.Optional("iterations", iterations, config::Range{1, 100});
  }
};

class ScanMatchingSlam {
 public:
  explicit ScanMatchingSlam(const SlamParams& params = {});
  /// Matches `ranges` (beam i at i 2π / n from the car's front) to the map from `guess` (the
  /// first scan is taken at `guess`), writes the scan into the map, and returns the pose found.
  RigidTransform2 Update(const RigidTransform2& guess, std::span<const float> ranges);
  /// The same for a scan's end points in the car's frame (e.g. a rotating LIDAR's beams moved
  /// by the odometry to one pose of the car).
  RigidTransform2 Update(const RigidTransform2& guess, std::span<const Eigen::Vector2d> points);
  /// Writes end points (in the car's frame) into the map as seen from `X`, without matching (a
  /// pose known otherwise).
  void Integrate(const RigidTransform2& X, std::span<const Eigen::Vector2d> points);
  /// A scan's end points in the car's frame (beams with a return within range).
  [[nodiscard]] std::vector<Eigen::Vector2d> EndPoints(std::span<const float> ranges) const;
  /// The finest map as a grid: occupied where the log-odds say so, free where they say so or
  /// nothing was seen (see `Observed`).
  [[nodiscard]] maps::OccupancyGrid Grid() const;
  /// Whether cell (col, row) of the finest grid was seen (its log-odds away from 0).
  [[nodiscard]] bool Observed(int col, int row) const;

 private:
  struct Level {
    double resolution = 0.0;
    int width = 0, height = 0;
    std::vector<float> log_odds;
  };
  // The occupancy probability at p and its gradient (bilinear), on level l.
  [[nodiscard]] double Value(const Level& l, const Eigen::Vector2d& p,
                             Eigen::Vector2d* gradient) const;
  RigidTransform2 Match(const Level& l, const RigidTransform2& guess,
                        std::span<const Eigen::Vector2d> points) const;
  void Write(Level& l, const RigidTransform2& X, std::span<const Eigen::Vector2d> points) const;

  SlamParams params_;
  std::vector<Level> levels_;  // coarse to fine
  bool started_ = false;
};

}  // namespace autodrive::examples
