#include "examples/parking/slam.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Dense>

namespace autodrive::examples {

ScanMatchingSlam::ScanMatchingSlam(const SlamParams& params) : params_(params) {
  for (const double scale : {4.0, 2.0, 1.0}) {
    Level l;
    l.resolution = params_.resolution_m * scale;
    l.width = static_cast<int>(std::ceil(params_.width_m / l.resolution));
    l.height = static_cast<int>(std::ceil(params_.height_m / l.resolution));
    l.log_odds.assign(static_cast<std::size_t>(l.width) * static_cast<std::size_t>(l.height), 0.0f);
    levels_.push_back(std::move(l));
  }
}

double ScanMatchingSlam::Value(const Level& l, const Eigen::Vector2d& p,
                               Eigen::Vector2d* gradient) const {
  // Cell centres at (i + 0.5) resolution: interpolate between the four around p.
  const Eigen::Vector2d g = (p - params_.origin_m) / l.resolution - Eigen::Vector2d(0.5, 0.5);
  const int x0 = static_cast<int>(std::floor(g.x())), y0 = static_cast<int>(std::floor(g.y()));
  const double fx = g.x() - x0, fy = g.y() - y0;
  const auto at = [&](int x, int y) {
    if (x < 0 || y < 0 || x >= l.width || y >= l.height) return 0.0;
    const double lo = l.log_odds[static_cast<std::size_t>(y) * static_cast<std::size_t>(l.width) +
                                 static_cast<std::size_t>(x)];
    return 1.0 - 1.0 / (1.0 + std::exp(lo));  // probability of occupied
  };
  const double m00 = at(x0, y0), m10 = at(x0 + 1, y0), m01 = at(x0, y0 + 1),
               m11 = at(x0 + 1, y0 + 1);
  if (gradient != nullptr) {
    *gradient = Eigen::Vector2d(fy * (m11 - m01) + (1 - fy) * (m10 - m00),
                                fx * (m11 - m10) + (1 - fx) * (m01 - m00)) /
                l.resolution;
  }
  return fy * (fx * m11 + (1 - fx) * m01) + (1 - fy) * (fx * m10 + (1 - fx) * m00);
}

RigidTransform2 ScanMatchingSlam::Match(const Level& l, const RigidTransform2& guess,
                                        std::span<const Eigen::Vector2d> points) const {
  Eigen::Vector3d xi(guess.translation().x(), guess.translation().y(), guess.yaw());
  for (int it = 0; it < params_.iterations; ++it) {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    const double c = std::cos(xi.z()), s = std::sin(xi.z());
    for (const Eigen::Vector2d& q : points) {
      const Eigen::Vector2d p(xi.x() + c * q.x() - s * q.y(), xi.y() + s * q.x() + c * q.y());
      Eigen::Vector2d grad;
      const double m = Value(l, p, &grad);
      const Eigen::Vector3d J(
          grad.x(), grad.y(),
          grad.x() * (-s * q.x() - c * q.y()) + grad.y() * (c * q.x() - s * q.y()));
      H += J * J.transpose();
      b += J * (1.0 - m);
    }
    if (H.determinant() < 1e-9) break;
    const Eigen::Vector3d step = H.ldlt().solve(b);
    if (!step.allFinite()) break;
    xi += step;
    if (step.head<2>().norm() < 1e-4 && std::abs(step.z()) < 1e-4) break;
  }
  return RigidTransform2::FromXyYaw(xi.x(), xi.y(), xi.z());
}

void ScanMatchingSlam::Write(Level& l, const RigidTransform2& X,
                             std::span<const Eigen::Vector2d> points) const {
  const auto cell = [&](const Eigen::Vector2d& p) {
    const Eigen::Vector2d g = (p - params_.origin_m) / l.resolution;
    return Eigen::Vector2i(static_cast<int>(std::floor(g.x())),
                           static_cast<int>(std::floor(g.y())));
  };
  const auto add = [&](const Eigen::Vector2i& c, double v) {
    if (c.x() < 0 || c.y() < 0 || c.x() >= l.width || c.y() >= l.height) return;
    float& lo = l.log_odds[static_cast<std::size_t>(c.y()) * static_cast<std::size_t>(l.width) +
                           static_cast<std::size_t>(c.x())];
    lo = static_cast<float>(std::clamp(lo + v, -params_.log_odds_limit, params_.log_odds_limit));
  };
  const Eigen::Vector2d from = X * Eigen::Vector2d(params_.lidar_x_m, 0.0);
  for (const Eigen::Vector2d& q : points) {
    const Eigen::Vector2d to = X * q;
    const Eigen::Vector2i end = cell(to);
    // The cells the beam crosses before its end: free (sampled every half cell).
    const double length = (to - from).norm();
    const int steps = static_cast<int>(length / (l.resolution / 2));
    Eigen::Vector2i last(-1, -1);
    for (int k = 0; k < steps; ++k) {
      const Eigen::Vector2i c = cell(from + (to - from) * (static_cast<double>(k) / steps));
      if (c == end) break;
      if (c != last) add(c, params_.log_odds_miss);
      last = c;
    }
    add(end, params_.log_odds_hit);
  }
}

std::vector<Eigen::Vector2d> ScanMatchingSlam::EndPoints(std::span<const float> ranges) const {
  std::vector<Eigen::Vector2d> points;  // end points in the car's frame
  const auto n = static_cast<double>(ranges.size());
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    const double r = ranges[i];
    if (!std::isfinite(r) || r < 0.15 || r > params_.max_range_m) continue;
    const double a = 2 * std::numbers::pi * static_cast<double>(i) / n;
    points.emplace_back(params_.lidar_x_m + r * std::cos(a), r * std::sin(a));
  }
  return points;
}

RigidTransform2 ScanMatchingSlam::Update(const RigidTransform2& guess,
                                         std::span<const float> ranges) {
  return Update(guess, EndPoints(ranges));
}

RigidTransform2 ScanMatchingSlam::Update(const RigidTransform2& guess,
                                         std::span<const Eigen::Vector2d> points) {
  RigidTransform2 X = guess;
  if (started_) {
    for (const Level& l : levels_) X = Match(l, X, points);
  }
  for (Level& l : levels_) Write(l, X, points);
  started_ = true;
  return X;
}

void ScanMatchingSlam::Integrate(const RigidTransform2& X,
                                 std::span<const Eigen::Vector2d> points) {
  for (Level& l : levels_) Write(l, X, points);
  started_ = true;
}

bool ScanMatchingSlam::Observed(int col, int row) const {
  const Level& l = levels_.back();
  return std::abs(l.log_odds[static_cast<std::size_t>(row) * static_cast<std::size_t>(l.width) +
                             static_cast<std::size_t>(col)]) > 0.5f;
}

maps::OccupancyGrid ScanMatchingSlam::Grid() const {
  const Level& l = levels_.back();
  maps::OccupancyGrid g;
  g.resolution_m = l.resolution;
  g.origin_m = params_.origin_m;
  g.width = l.width;
  g.height = l.height;
  g.cells.resize(l.log_odds.size());
  for (std::size_t i = 0; i < l.log_odds.size(); ++i) {
    g.cells[i] = l.log_odds[i] > 0.0f ? maps::OccupancyGrid::kOccupied : maps::OccupancyGrid::kFree;
  }
  return g;
}

}  // namespace autodrive::examples
