#include "examples/parking/localiser.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>

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

SlamParams SlamFor(const maps::OccupancyGrid& grid, double lidar_x_m, double max_range_m,
                   SlamParams tuning) {
  SlamParams p = tuning;
  p.resolution_m = grid.resolution_m;
  p.origin_m = grid.origin_m;
  p.width_m = grid.width * grid.resolution_m;
  p.height_m = grid.height * grid.resolution_m;
  p.lidar_x_m = lidar_x_m;
  p.max_range_m = max_range_m;
  return p;
}

Localiser::Localiser(const maps::OccupancyGrid& grid, const LocaliserParams& params)
    : params_(params),
      filter_(grid, params.filter),
      slam_params_(SlamFor(grid, params.filter.lidar_x_m, params.filter.max_range_m, params.slam)),
      slam_(slam_params_) {}

void Localiser::Start(const RigidTransform2& X_MV) {
  filter_.Init(X_MV, params_.start_sigma_xy_m, params_.start_sigma_yaw_rad);
  estimate_ = filter_.Estimate();
  slam_pose_ = X_MV;
  slam_guess_ = X_MV;
  fix_ = X_MV;
}

void Localiser::Odometry(Time t, double left_wheel_rad, double right_wheel_rad, double yaw_rad) {
  const Eigen::Vector3d now(left_wheel_rad, right_wheel_rad, yaw_rad);
  if (!started() || !last_odometry_) {
    last_odometry_ = now;
    odometry_.assign(1, {t, RigidTransform2::Identity()});
    return;
  }
  const double distance = params_.wheel_radius_m *
                          ((now.x() - last_odometry_->x()) + (now.y() - last_odometry_->y())) / 2;
  const double turn = std::remainder(now.z() - last_odometry_->z(), 2 * std::numbers::pi);
  last_odometry_ = now;
  if (t > odometry_.back().first) {
    // The arc's chord, at half the turn.
    const RigidTransform2 delta = RigidTransform2::FromXyYaw(distance * std::cos(turn / 2),
                                                             distance * std::sin(turn / 2), turn);
    odometry_.emplace_back(t, odometry_.back().second * delta);
    while (odometry_.size() > 2 && t - odometry_[1].first > std::chrono::seconds(2)) {
      odometry_.pop_front();
    }
    if (distance != 0.0 || turn != 0.0) {
      filter_.Predict(delta);
      estimate_ = filter_.Estimate();
      slam_guess_ = *slam_guess_ * delta;
    }
  }
}

RigidTransform2 Localiser::OdometryAt(Time t) const {
  if (odometry_.empty()) return RigidTransform2::Identity();
  if (t <= odometry_.front().first) return odometry_.front().second;
  if (t >= odometry_.back().first) return odometry_.back().second;
  const auto after = std::lower_bound(odometry_.begin(), odometry_.end(), t,
                                      [](const auto& e, Time v) { return e.first < v; });
  const auto before = std::prev(after);
  const double f =
      ToSeconds(t - before->first) / ToSeconds(after->first - before->first);  // in (0, 1]
  const RigidTransform2 step = before->second.inverse() * after->second;
  return before->second * RigidTransform2::FromXyYaw(f * step.translation().x(),
                                                     f * step.translation().y(), f * step.yaw());
}

void Localiser::Scan(Time stamp, double increment_s, std::span<const float> ranges) {
  if (!started()) return;
  // Each beam's end point in the car's frame as it stands now (the odometry's last pose).
  const RigidTransform2 now_inv =
      odometry_.empty() ? RigidTransform2::Identity() : odometry_.back().second.inverse();
  std::vector<Eigen::Vector2d> points;
  const auto n = static_cast<double>(ranges.size());
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    const double r = ranges[i];
    if (!std::isfinite(r) || r < 0.15 || r > params_.filter.max_range_m) continue;
    const double a = 2 * std::numbers::pi * static_cast<double>(i) / n;
    const Time t = stamp + std::chrono::duration_cast<Duration>(
                               std::chrono::duration<double>(static_cast<double>(i) * increment_s));
    points.push_back(now_inv * OdometryAt(t) *
                     Eigen::Vector2d(params_.filter.lidar_x_m + r * std::cos(a), r * std::sin(a)));
  }
  if (!ready()) {
    // Building the map at the fix: the car stands (the agent does not drive before it is ready).
    // Moved since the fix (pushed, or still rolling when the agent began)? Begin again there.
    const RigidTransform2 moved =
        odometry_.empty() ? RigidTransform2::Identity() : odometry_.back().second;
    if (moved.translation().norm() > 0.005 || std::abs(moved.yaw()) > 0.0087) {
      ++mapping_restarts_;
      fix_ = *fix_ * moved;
      odometry_.assign(1, {odometry_.back().first, RigidTransform2::Identity()});
      slam_ = ScanMatchingSlam(slam_params_);
      slam_guess_ = slam_pose_ = fix_;
      mapped_scans_ = 0;
    }
    slam_.Integrate(*fix_, points);
    if (++mapped_scans_ == params_.mapping_scans) {
      built_ = slam_.Grid();
      filter_.SetMap(*built_);
    }
    return;
  }
  filter_.Update(points);
  estimate_ = filter_.Estimate();
  slam_pose_ = slam_.Update(*slam_guess_, points);
  slam_guess_ = slam_pose_;
}

}  // namespace autodrive::examples
