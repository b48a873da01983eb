#include "examples/parking/hybrid_astar.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <queue>
#include <unordered_set>

#include "common/error.h"
#include "examples/parking/grid_distance.h"

namespace autodrive::examples {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Node {
  double x = 0, y = 0, yaw = 0;
  double g = 0;
  std::int64_t parent = -1;
  int gear = 1;
  double steer = 0;  // fraction of full lock
};

}  // namespace

HybridAStar::HybridAStar(maps::OccupancyGrid grid, const HybridAStarParams& params)
    : grid_(std::move(grid)), params_(params) {
  AUTODRIVE_THROW_UNLESS(grid_.width > 0 && grid_.height > 0, "the occupancy grid is empty");
  AUTODRIVE_THROW_UNLESS(
      params_.step_m > 0 && params_.cell_m > 0 && params_.heading_bins >= 8,
      "hybrid A*: step, cell and heading bins must be positive (8 bins or more)");
  ComputeClearance();
  CoverBody();
}

void HybridAStar::SetMargin(double margin_m) {
  AUTODRIVE_THROW_UNLESS(margin_m >= 0, "hybrid A*: the margin must not be negative");
  params_.margin_m = margin_m;
  CoverBody();
}

void HybridAStar::CoverBody() {
  // Four circles along the body (with its margin) cover it.
  circles_.clear();
  const double length = params_.length_m + 2 * params_.margin_m;
  const double width = params_.width_m + 2 * params_.margin_m;
  constexpr int kCircles = 4;
  const double piece = length / kCircles;
  for (int k = 0; k < kCircles; ++k) {
    circles_.emplace_back(params_.centre_ahead_m - length / 2 + piece * (k + 0.5), 0.0);
  }
  circle_radius_ = std::hypot(piece / 2, width / 2);
}

void HybridAStar::ComputeClearance() {
  const std::vector<float> distance = DistanceToOccupied(grid_);
  clearance_.resize(static_cast<std::size_t>(grid_.width) * static_cast<std::size_t>(grid_.height));
  for (int r = 0; r < grid_.height; ++r) {
    for (int c = 0; c < grid_.width; ++c) {
      // Distance to the nearest cell's centre, less that cell's reach (half its diagonal):
      // a lower bound of the distance to what the cell holds.
      const double d =
          distance[static_cast<std::size_t>(r) * static_cast<std::size_t>(grid_.width) +
                   static_cast<std::size_t>(c)] -
          grid_.resolution_m * std::numbers::sqrt2 / 2;
      clearance_[static_cast<std::size_t>(r) * static_cast<std::size_t>(grid_.width) +
                 static_cast<std::size_t>(c)] = grid_.IsFree(c, r) ? std::max(d, 0.0) : 0.0;
    }
  }
}

void HybridAStar::AddObstacles(const std::vector<Eigen::Vector2d>& points, double radius_m) {
  const int reach = static_cast<int>(std::ceil(radius_m / grid_.resolution_m));
  bool changed = false;
  for (const Eigen::Vector2d& q : points) {
    const Eigen::Vector2d cell = (q - grid_.origin_m) / grid_.resolution_m;
    const int c0 = static_cast<int>(std::floor(cell.x()));
    const int r0 = static_cast<int>(std::floor(cell.y()));
    for (int r = r0 - reach; r <= r0 + reach; ++r) {
      for (int c = c0 - reach; c <= c0 + reach; ++c) {
        if (c < 0 || r < 0 || c >= grid_.width || r >= grid_.height) continue;
        if ((grid_.CellCentre(c, r) - q).norm() > radius_m + grid_.resolution_m / 2) continue;
        std::uint8_t& v =
            grid_.cells[static_cast<std::size_t>(r) * static_cast<std::size_t>(grid_.width) +
                        static_cast<std::size_t>(c)];
        changed = changed || v != maps::OccupancyGrid::kOccupied;
        v = maps::OccupancyGrid::kOccupied;
      }
    }
  }
  if (changed) ComputeClearance();
}

double HybridAStar::Clearance(const Eigen::Vector2d& p) const {
  const Eigen::Vector2d cell = (p - grid_.origin_m) / grid_.resolution_m;
  const int c = static_cast<int>(std::floor(cell.x()));
  const int r = static_cast<int>(std::floor(cell.y()));
  if (c < 0 || r < 0 || c >= grid_.width || r >= grid_.height) return 0.0;
  // From p rather than its cell's centre: less up to half a diagonal.
  return std::max(0.0,
                  clearance_[static_cast<std::size_t>(r) * static_cast<std::size_t>(grid_.width) +
                             static_cast<std::size_t>(c)] -
                      grid_.resolution_m * std::numbers::sqrt2 / 2);
}

bool HybridAStar::Free(const RigidTransform2& X_MV) const {
  for (const Eigen::Vector2d& c : circles_) {
    if (Clearance(X_MV * c) < circle_radius_) return false;
  }
  return true;
}

bool HybridAStar::BodyClear(const RigidTransform2& X_MV) const {
  const double hl = params_.length_m / 2, hw = params_.width_m / 2;
  const double reach = grid_.resolution_m * std::numbers::sqrt2 / 2;
  const RigidTransform2 inv = X_MV.inverse();
  Eigen::Vector2d lo(kInf, kInf), hi(-kInf, -kInf);
  for (const auto& [u, v] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}) {
    const Eigen::Vector2d corner = X_MV * Eigen::Vector2d(params_.centre_ahead_m + u * hl, v * hw);
    lo = lo.cwiseMin(corner);
    hi = hi.cwiseMax(corner);
  }
  const Eigen::Vector2d a = (lo - grid_.origin_m) / grid_.resolution_m;
  const Eigen::Vector2d b = (hi - grid_.origin_m) / grid_.resolution_m;
  const int c0 = static_cast<int>(std::floor(a.x())) - 1;
  const int c1 = static_cast<int>(std::floor(b.x())) + 1;
  const int r0 = static_cast<int>(std::floor(a.y())) - 1;
  const int r1 = static_cast<int>(std::floor(b.y())) + 1;
  for (int r = r0; r <= r1; ++r) {
    for (int c = c0; c <= c1; ++c) {
      const bool outside = c < 0 || r < 0 || c >= grid_.width || r >= grid_.height;
      if (!outside && grid_.IsFree(c, r)) continue;
      const Eigen::Vector2d q = inv * grid_.CellCentre(c, r);
      if (std::abs(q.x() - params_.centre_ahead_m) <= hl + reach && std::abs(q.y()) <= hw + reach) {
        return false;
      }
    }
  }
  return true;
}

std::vector<double> HybridAStar::GridDistances(const Eigen::Vector2d& goal) const {
  const int w = grid_.width, h = grid_.height;
  std::vector<double> dist(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), kInf);
  const auto index = [&](int c, int r) {
    return static_cast<std::size_t>(r) * static_cast<std::size_t>(w) + static_cast<std::size_t>(c);
  };
  const double half = params_.width_m / 2;
  using Item = std::pair<double, std::size_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> open;
  const Eigen::Vector2d g = (goal - grid_.origin_m) / grid_.resolution_m;
  const int gc = std::clamp(static_cast<int>(g.x()), 0, w - 1);
  const int gr = std::clamp(static_cast<int>(g.y()), 0, h - 1);
  dist[index(gc, gr)] = 0;
  open.push({0, index(gc, gr)});
  while (!open.empty()) {
    const auto [d, i] = open.top();
    open.pop();
    if (d > dist[i]) continue;
    const int c = static_cast<int>(i % static_cast<std::size_t>(w));
    const int r = static_cast<int>(i / static_cast<std::size_t>(w));
    for (int dr = -1; dr <= 1; ++dr) {
      for (int dc = -1; dc <= 1; ++dc) {
        if (dc == 0 && dr == 0) continue;
        const int nc = c + dc, nr = r + dr;
        if (nc < 0 || nr < 0 || nc >= w || nr >= h) continue;
        if (clearance_[index(nc, nr)] < half) continue;
        const double nd =
            d + grid_.resolution_m * ((dc != 0 && dr != 0) ? std::numbers::sqrt2 : 1.0);
        if (nd < dist[index(nc, nr)]) {
          dist[index(nc, nr)] = nd;
          open.push({nd, index(nc, nr)});
        }
      }
    }
  }
  return dist;
}

PlanResult HybridAStar::Plan(const RigidTransform2& start, const RigidTransform2& goal) const {
  PlanResult result;
  if (!BodyClear(start)) {
    result.failure = "the start pose is not clear of the obstacles";
    return result;
  }
  if (!Free(goal)) {
    result.failure = "the goal pose is not clear of the obstacles";
    return result;
  }
  const std::vector<double> to_goal = GridDistances(goal.translation());
  const auto heuristic = [&](double x, double y) {
    const Eigen::Vector2d cell = (Eigen::Vector2d(x, y) - grid_.origin_m) / grid_.resolution_m;
    const int c = std::clamp(static_cast<int>(cell.x()), 0, grid_.width - 1);
    const int r = std::clamp(static_cast<int>(cell.y()), 0, grid_.height - 1);
    const double grid =
        to_goal[static_cast<std::size_t>(r) * static_cast<std::size_t>(grid_.width) +
                static_cast<std::size_t>(c)];
    const double straight = (Eigen::Vector2d(x, y) - goal.translation()).norm();
    return std::isfinite(grid) ? std::max(grid, straight) : straight;
  };
  const double bin = 2 * std::numbers::pi / params_.heading_bins;
  const auto key = [&](double x, double y, double yaw, double cell, double heading_bin) {
    const auto ix = static_cast<std::int64_t>(std::floor(x / cell));
    const auto iy = static_cast<std::int64_t>(std::floor(y / cell));
    const auto it = static_cast<std::int64_t>(std::floor(WrapAngle(yaw) / heading_bin + 1000.5));
    return (ix * 100'003 + iy) * 100'019 + it;
  };
  // Near the goal, finer bins: states the coarse bins would merge can each still end in it.
  const double near_goal = 3 * params_.cell_m;
  const auto key_of = [&](const Node& n) {
    const bool near = (Eigen::Vector2d(n.x, n.y) - goal.translation()).norm() < near_goal;
    return near ? -key(n.x, n.y, n.yaw, params_.cell_m / 5, bin / 5) - 1
                : key(n.x, n.y, n.yaw, params_.cell_m, bin);
  };
  std::vector<Node> nodes;
  nodes.push_back(Node{start.translation().x(), start.translation().y(), start.yaw(), 0, -1, 1, 0});
  // Driven from the start (metres), per node: the margin is kept from `leave_m` on.
  std::vector<double> driven{0.0};
  using Item = std::pair<double, std::int64_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> open;
  open.push({heuristic(nodes[0].x, nodes[0].y), 0});
  std::unordered_set<std::int64_t> closed;
  const double turn = std::tan(params_.steering_limit_rad) / params_.wheelbase_m;  // curvature
  constexpr double kSteers[] = {-1.0, -0.5, 0.0, 0.5, 1.0};
  std::int64_t found = -1;
  while (!open.empty() && result.expansions < params_.max_expansions) {
    const std::int64_t at = open.top().second;
    open.pop();
    const Node n = nodes[static_cast<std::size_t>(at)];
    if (!closed.insert(key_of(n)).second) continue;
    ++result.expansions;
    if ((Eigen::Vector2d(n.x, n.y) - goal.translation()).norm() <= params_.goal_tolerance_m &&
        std::abs(WrapAngle(n.yaw - goal.yaw())) <= params_.goal_tolerance_rad) {
      found = at;
      break;
    }
    for (const int gear : {1, -1}) {
      for (const double steer : kSteers) {
        const double k = steer * turn;
        const double s = gear * params_.step_m;
        Node m;
        m.yaw = n.yaw + s * k;
        if (std::abs(k) < 1e-9) {
          m.x = n.x + s * std::cos(n.yaw);
          m.y = n.y + s * std::sin(n.yaw);
        } else {
          m.x = n.x + (std::sin(m.yaw) - std::sin(n.yaw)) / k;
          m.y = n.y - (std::cos(m.yaw) - std::cos(n.yaw)) / k;
        }
        m.yaw = WrapAngle(m.yaw);
        if (closed.contains(key_of(m))) continue;
        const double from_start = driven[static_cast<std::size_t>(at)] + params_.step_m;
        const RigidTransform2 M = RigidTransform2::FromXyYaw(m.x, m.y, m.yaw);
        if (from_start >= params_.leave_m ? !Free(M) : !BodyClear(M)) continue;
        m.gear = gear;
        m.steer = steer;
        m.parent = at;
        m.g = n.g + params_.step_m * (gear < 0 ? params_.reverse_cost : 1.0) +
              params_.steer_cost * std::abs(steer) * params_.step_m +
              (at != 0 && gear != n.gear ? params_.gear_change_cost_m : 0.0);
        nodes.push_back(m);
        driven.push_back(from_start);
        open.push({m.g + heuristic(m.x, m.y), static_cast<std::int64_t>(nodes.size() - 1)});
      }
    }
  }
  if (found < 0) {
    result.failure =
        result.expansions >= params_.max_expansions
            ? "no path within " + std::to_string(params_.max_expansions) + " expansions"
            : "no path: the goal cannot be reached from the start";
    return result;
  }
  for (std::int64_t i = found; i >= 0; i = nodes[static_cast<std::size_t>(i)].parent) {
    const Node& n = nodes[static_cast<std::size_t>(i)];
    result.path.push_back({RigidTransform2::FromXyYaw(n.x, n.y, n.yaw), n.gear});
  }
  std::reverse(result.path.begin(), result.path.end());
  if (result.path.size() > 1) result.path.front().gear = result.path[1].gear;
  for (std::size_t i = 1; i < result.path.size(); ++i) {
    result.length_m +=
        (result.path[i].X_MV.translation() - result.path[i - 1].X_MV.translation()).norm();
    if (i > 1 && result.path[i].gear != result.path[i - 1].gear) ++result.gear_changes;
  }
  return result;
}

}  // namespace autodrive::examples
