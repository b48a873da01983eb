#include "examples/parking/local_planner.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace autodrive::examples {

bool Unmapped(const maps::OccupancyGrid& grid, const Eigen::Vector2d& q, double reach) {
  const int n = static_cast<int>(std::ceil(reach / grid.resolution_m));
  const Eigen::Vector2d cell = (q - grid.origin_m) / grid.resolution_m;
  const int c0 = static_cast<int>(std::floor(cell.x()));
  const int r0 = static_cast<int>(std::floor(cell.y()));
  if (c0 < 0 || r0 < 0 || c0 >= grid.width || r0 >= grid.height) return false;
  for (int r = std::max(0, r0 - n); r <= std::min(grid.height - 1, r0 + n); ++r) {
    for (int c = std::max(0, c0 - n); c <= std::min(grid.width - 1, c0 + n); ++c) {
      if (!grid.IsFree(c, r) && (grid.CellCentre(c, r) - q).norm() <= reach) return false;
    }
  }
  return true;
}

std::vector<Eigen::Vector2d> Clustered(const std::vector<Eigen::Vector2d>& points, double reach,
                                       int min_points) {
  std::vector<Eigen::Vector2d> out;
  for (const Eigen::Vector2d& p : points) {
    const auto near = std::count_if(points.begin(), points.end(), [&](const Eigen::Vector2d& q) {
      return (q - p).squaredNorm() <= reach * reach;
    });
    if (near >= min_points) out.push_back(p);
  }
  return out;
}

std::vector<Eigen::Vector2d> NewObstacles(std::span<const float> scan, const RigidTransform2& X_MV,
                                          double lidar_x_m, const maps::OccupancyGrid& city,
                                          const maps::OccupancyGrid* own,
                                          const ObstacleParams& params) {
  std::vector<Eigen::Vector2d> news;
  const auto n = static_cast<double>(scan.size());
  for (std::size_t i = 0; i < scan.size(); ++i) {
    const double r = scan[i];
    if (!std::isfinite(r) || r > params.range_m) continue;
    const double a = 2 * std::numbers::pi * static_cast<double>(i) / n;
    const Eigen::Vector2d q = X_MV * Eigen::Vector2d(lidar_x_m + r * std::cos(a), r * std::sin(a));
    if (Unmapped(city, q, params.off_map_m) &&
        (own == nullptr || Unmapped(*own, q, params.off_own_map_m))) {
      news.push_back(q);
    }
  }
  return Clustered(news, params.cluster_m, params.cluster_points);
}

namespace {
bool InBody(const Eigen::Vector2d& q, const RigidTransform2& X_MV, const HybridAStarParams& body,
            double around_m) {
  const Eigen::Vector2d b = X_MV.inverse() * q;
  return std::abs(b.x() - body.centre_ahead_m) <= body.length_m / 2 + around_m &&
         std::abs(b.y()) <= body.width_m / 2 + around_m;
}
}  // namespace

bool InTheWay(std::span<const Eigen::Vector2d> points, std::span<const PathPose> ahead,
              const HybridAStarParams& body, double ahead_m) {
  double along = 0.0;
  for (std::size_t k = 0; k < ahead.size() && along < ahead_m; ++k) {
    if (k > 0) along += (ahead[k].X_MV.translation() - ahead[k - 1].X_MV.translation()).norm();
    for (const Eigen::Vector2d& q : points) {
      if (InBody(q, ahead[k].X_MV, body, body.margin_m)) return true;
    }
  }
  return false;
}

bool AgainstBody(const Eigen::Vector2d& q, const RigidTransform2& X_MV,
                 const HybridAStarParams& body, double clear_m) {
  return InBody(q, X_MV, body, clear_m);
}

}  // namespace autodrive::examples
