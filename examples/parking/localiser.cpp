#include "examples/parking/localiser.h"

#include <cmath>
#include <filesystem>
#include <fstream>

#include "common/error.h"

namespace autodrive::examples {

MapAgreement CompareMaps(const ScanMatchingSlam& slam, const maps::OccupancyGrid& truth) {
  const maps::OccupancyGrid built = slam.Grid();
  MapAgreement out;
  if (built.width != truth.width || built.height != truth.height) return out;
  for (int r = 0; r < built.height; ++r) {
    for (int c = 0; c < built.width; ++c) {
      if (!slam.Observed(c, r)) continue;
      ++out.seen;
      if (built.IsFree(c, r) == truth.IsFree(c, r)) ++out.agree;
    }
  }
  return out;
}

void WriteMapServerMap(const ScanMatchingSlam& slam, const std::string& prefix) {
  const maps::OccupancyGrid grid = slam.Grid();
  const std::filesystem::path pgm = prefix + ".pgm", yaml = prefix + ".yaml";
  std::ofstream image(pgm, std::ios::binary);
  image << "P5\n" << grid.width << ' ' << grid.height << "\n255\n";
  for (int r = grid.height - 1; r >= 0; --r) {
    for (int c = 0; c < grid.width; ++c) {
      const char v = !slam.Observed(c, r) ? static_cast<char>(205)
                     : grid.IsFree(c, r)  ? static_cast<char>(254)
                                          : static_cast<char>(0);
      image.put(v);
    }
  }
  image.close();
  AUTODRIVE_THROW_UNLESS(!image.fail(), pgm.string() << ": cannot write the map");
  std::ofstream meta(yaml);
  meta << "image: " << pgm.filename().string() << "\nresolution: " << grid.resolution_m
       << "\norigin: [" << grid.origin_m.x() << ", " << grid.origin_m.y()
       << ", 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
  meta.close();
  AUTODRIVE_THROW_UNLESS(!meta.fail(), yaml.string() << ": cannot write the map's description");
}

SlamParams SlamFor(const maps::OccupancyGrid& grid, double lidar_x_m) {
  SlamParams p;
  p.resolution_m = grid.resolution_m;
  p.origin_m = grid.origin_m;
  p.width_m = grid.width * grid.resolution_m;
  p.height_m = grid.height * grid.resolution_m;
  p.lidar_x_m = lidar_x_m;
  return p;
}

Localiser::Localiser(const maps::OccupancyGrid& grid, const LocaliserParams& params)
    : params_(params),
      filter_(grid, params.filter),
      slam_(SlamFor(grid, params.filter.lidar_x_m)) {}

void Localiser::Start(const RigidTransform2& X_MV) {
  filter_.Init(X_MV, params_.start_sigma_xy_m, params_.start_sigma_yaw_rad);
  estimate_ = filter_.Estimate();
  slam_pose_ = X_MV;
  slam_guess_ = X_MV;
}

void Localiser::Odometry(double left_wheel_rad, double right_wheel_rad, double yaw_rad) {
  const Eigen::Vector3d now(left_wheel_rad, right_wheel_rad, yaw_rad);
  if (!started() || !last_odometry_) {
    last_odometry_ = now;
    return;
  }
  const double distance = params_.wheel_radius_m *
                          ((now.x() - last_odometry_->x()) + (now.y() - last_odometry_->y())) / 2;
  const double turn = std::remainder(now.z() - last_odometry_->z(), 2 * 3.14159265358979323846);
  last_odometry_ = now;
  if (distance == 0.0 && turn == 0.0) return;
  // The arc's chord, at half the turn.
  const RigidTransform2 delta = RigidTransform2::FromXyYaw(distance * std::cos(turn / 2),
                                                           distance * std::sin(turn / 2), turn);
  filter_.Predict(delta);
  estimate_ = filter_.Estimate();
  slam_guess_ = *slam_guess_ * delta;
}

void Localiser::Scan(std::span<const float> ranges) {
  if (!started()) return;
  filter_.Update(ranges);
  estimate_ = filter_.Estimate();
  slam_pose_ = slam_.Update(*slam_guess_, ranges);
  slam_guess_ = slam_pose_;
}

}  // namespace autodrive::examples
