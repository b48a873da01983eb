#pragma once
/// @file
/// The parking case study's own localisation and mapping, on the car's public topics alone: its
/// wheel encoders and IMU heading (odometry), and its LIDAR. From a first fix (the lab's
/// positioning at the start), Hector-style SLAM (slam.h) builds a map of its own from the scans,
/// and a particle filter (particle_filter.h) localises the car against the map SLAM built while
/// the car stood at the fix (the paper's: the world as it stands, walls turned and all), or
/// against the map's own occupancy grid; the agent drives on the particle filter's pose.

#include <deque>
#include <optional>
#include <span>
#include <string>

#include "common/geometry.h"
#include "common/time.h"
#include "examples/parking/particle_filter.h"
#include "examples/parking/slam.h"
#include "maps/occupancy.h"

namespace autodrive::examples {

/// The filter's figures in the agent: beam skipping on (the world's walls may stand a few
/// centimetres from where the map has them: the paper's variability), and beams out to 6 m (the
/// Parking School's far walls, 3.4 m from its start, hold the car's position along the room).
[[nodiscard]] inline ParticleFilterParams AgentFilterParams() {
  ParticleFilterParams p;
  p.max_range_m = 6.0;
  p.beam_skip_distance_m = 0.05;
  p.beam_skip_threshold = 0.6;
  return p;
}

struct LocaliserParams {
  ParticleFilterParams filter = AgentFilterParams();
  double wheel_radius_m = 0.0325;
  double start_sigma_xy_m = 0.03;  ///< the first fix's uncertainty
  double start_sigma_yaw_rad = 0.05;
  /// Scans written into SLAM's map at the first fix (the car standing) before the filter starts
  /// weighing against that map; 0: the filter weighs against the map's own grid from the start.
  int mapping_scans = 0;
  SlamParams slam;  ///< its tunables (its extent and range: the map's and the filter's)

  /// The tunables (the wheel radius comes from the city). See examples/parking/parking.yaml.
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("start_sigma_xy_m", start_sigma_xy_m, config::Range{0.0, 1.0});
    a.Optional("start_sigma_yaw_rad", start_sigma_yaw_rad, config::Range{0.0, 3.2});
    a.Optional("mapping_scans", mapping_scans, config::Range{0, 100});
    a.Optional("filter", filter);
    a.Optional("slam", slam);
  }
};

/// The localiser's figures in the agent: the filter's, and 10 scans mapped standing at the fix.
[[nodiscard]] inline LocaliserParams AgentLocaliserParams() {
  LocaliserParams p;
  p.mapping_scans = 10;
  return p;
}

/// How much of a built map agrees with the map's own grid: over the cells the SLAM saw, the share
/// whose free-or-occupied agrees (the grids must have the same cells).
struct MapAgreement {
  std::size_t seen = 0;
  std::size_t agree = 0;
  [[nodiscard]] double share() const {
    return seen > 0 ? static_cast<double>(agree) / static_cast<double>(seen) : 0.0;
  }
};
[[nodiscard]] MapAgreement CompareMaps(const ScanMatchingSlam& slam,
                                       const maps::OccupancyGrid& truth);

/// Writes SLAM's map in ROS map_server's format: `prefix`.pgm (8-bit, north row first: 0
/// occupied, 254 free, 205 not seen) and `prefix`.yaml (image, resolution, origin, thresholds).
/// @throws InputError naming a file that cannot be written.
void WriteMapServerMap(const ScanMatchingSlam& slam, const std::string& prefix);

/// SLAM's parameters for a map of the grid's extent and resolution.
[[nodiscard]] SlamParams SlamFor(const maps::OccupancyGrid& grid, double lidar_x_m,
                                 double max_range_m, SlamParams tuning = {});

class Localiser {
 public:
  Localiser(const maps::OccupancyGrid& grid, const LocaliserParams& params);

  /// The first fix: the filter starts round it, SLAM from it.
  void Start(const RigidTransform2& X_MV);
  [[nodiscard]] bool started() const { return estimate_.has_value(); }
  /// Started, and the map the filter weighs against built (at once with `mapping_scans` 0).
  [[nodiscard]] bool ready() const { return started() && mapped_scans_ >= params_.mapping_scans; }
  /// The rear wheels' angles (rad, as the encoders give them) and the IMU's heading at time `t`:
  /// the odometry since the last call moves the filter's particles and SLAM's guess.
  void Odometry(Time t, double left_wheel_rad, double right_wheel_rad, double yaw_rad);
  /// A new scan whose beam i was taken at `stamp` + i `increment_s` (a rotating LIDAR: 0 for
  /// one taken at once): each beam is moved by the odometry from where the car was when it was
  /// taken to where it is now, then the scan weighs the particles (which are resampled) and is
  /// matched and written into SLAM's map. While the map is being built (not ready), it is written
  /// at the first fix instead.
  void Scan(Time stamp, double increment_s, std::span<const float> ranges);

  /// The particle filter's estimate (what the car drives on). Precondition: started.
  [[nodiscard]] const RigidTransform2& Estimate() const { return *estimate_; }
  /// SLAM's pose.
  [[nodiscard]] const RigidTransform2& SlamPose() const { return *slam_pose_; }
  [[nodiscard]] const ParticleFilter& filter() const { return filter_; }
  /// How often the mapping began again because the odometry said the car moved while it mapped
  /// (its map is its pose's: a car rolling while it maps smears it).
  [[nodiscard]] int mapping_restarts() const { return mapping_restarts_; }
  /// The map SLAM built at the first fix, once built (`mapping_scans` > 0): what the filter
  /// weighs against, and what the car saw of the world before it moved.
  [[nodiscard]] const std::optional<maps::OccupancyGrid>& built_map() const { return built_; }
  [[nodiscard]] const ScanMatchingSlam& slam() const { return slam_; }

 private:
  // The odometry's pose at `t`, interpolated (held before the first and after the last).
  [[nodiscard]] RigidTransform2 OdometryAt(Time t) const;

  LocaliserParams params_;
  ParticleFilter filter_;
  SlamParams slam_params_;  // SLAM's figures (its map begun again with them)
  ScanMatchingSlam slam_;
  std::optional<RigidTransform2> estimate_, slam_pose_;
  std::optional<RigidTransform2> slam_guess_;     // SLAM's pose moved by the odometry since
  std::optional<Eigen::Vector3d> last_odometry_;  // left, right, yaw
  std::optional<RigidTransform2> fix_;            // the first fix
  // The odometry's own pose (its integral, from the identity) over the last seconds: where the
  // car was when each beam of a scan was taken.
  std::deque<std::pair<Time, RigidTransform2>> odometry_;
  int mapped_scans_ = 0;
  int mapping_restarts_ = 0;
  std::optional<maps::OccupancyGrid> built_;
};

}  // namespace autodrive::examples
