#include "examples/parking/particle_filter.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <unordered_set>

#include "common/error.h"
#include "examples/parking/grid_distance.h"

namespace autodrive::examples {

ParticleFilter::ParticleFilter(const maps::OccupancyGrid& grid, const ParticleFilterParams& params)
    : grid_(grid), params_(params), rng_(params.seed) {
  AUTODRIVE_THROW_UNLESS(grid_.width > 0 && grid_.height > 0, "the occupancy grid is empty");
  AUTODRIVE_THROW_UNLESS(
      params_.min_particles >= 1 && params_.max_particles >= params_.min_particles,
      "particle filter: 1 <= min_particles <= max_particles");
  distance_ = DistanceToOccupied(grid_);
}

void ParticleFilter::SetMap(const maps::OccupancyGrid& grid) {
  AUTODRIVE_THROW_UNLESS(grid.width > 0 && grid.height > 0, "the occupancy grid is empty");
  grid_ = grid;
  distance_ = DistanceToOccupied(grid_);
}

double ParticleFilter::FieldDistance(const Eigen::Vector2d& p) const {
  const Eigen::Vector2d cell = (p - grid_.origin_m) / grid_.resolution_m;
  const int c = static_cast<int>(std::floor(cell.x()));
  const int r = static_cast<int>(std::floor(cell.y()));
  if (c < 0 || r < 0 || c >= grid_.width || r >= grid_.height) return 1.0;
  return distance_[static_cast<std::size_t>(r) * static_cast<std::size_t>(grid_.width) +
                   static_cast<std::size_t>(c)];
}

void ParticleFilter::Init(const RigidTransform2& X_MV, double sigma_xy_m, double sigma_yaw_rad) {
  std::normal_distribution<double> xy(0.0, sigma_xy_m), yaw(0.0, sigma_yaw_rad);
  particles_.clear();
  for (std::size_t i = 0; i < params_.max_particles; ++i) {
    particles_.push_back(
        {RigidTransform2::FromXyYaw(X_MV.translation().x() + xy(rng_),
                                    X_MV.translation().y() + xy(rng_), X_MV.yaw() + yaw(rng_)),
         1.0 / static_cast<double>(params_.max_particles)});
  }
}

void ParticleFilter::Predict(const RigidTransform2& delta) {
  const double trans = delta.translation().norm();
  const double rot = std::abs(delta.yaw());
  const double sigma_t =
      params_.alpha_trans_per_m * trans + params_.alpha_trans_per_rad * rot + 1e-4;
  const double sigma_r = params_.alpha_rot_per_rad * rot + params_.alpha_rot_per_m * trans + 1e-4;
  std::normal_distribution<double> nt(0.0, sigma_t), nr(0.0, sigma_r);
  for (Particle& p : particles_) {
    const RigidTransform2 noisy =
        RigidTransform2::FromXyYaw(delta.translation().x() + nt(rng_),
                                   delta.translation().y() + nt(rng_), delta.yaw() + nr(rng_));
    p.X_MV = p.X_MV * noisy;
  }
}

std::size_t ParticleFilter::KldCount(std::size_t bins) const {
  if (bins <= 1) return params_.min_particles;
  const double k = static_cast<double>(bins - 1);
  const double a = 2.0 / (9.0 * k);
  const double n =
      k / (2 * params_.kld_epsilon) * std::pow(1 - a + std::sqrt(a) * params_.kld_z, 3);
  return std::clamp(static_cast<std::size_t>(std::ceil(n)), params_.min_particles,
                    params_.max_particles);
}

void ParticleFilter::Update(std::span<const float> ranges) {
  std::vector<Eigen::Vector2d> used;  // every beam_stride-th beam's end point
  const auto beams = static_cast<double>(ranges.size());
  for (std::size_t b = 0; b < ranges.size(); b += static_cast<std::size_t>(params_.beam_stride)) {
    const double r = ranges[b];
    if (!std::isfinite(r) || r < 0.15 || r > params_.max_range_m) continue;
    const double a = 2 * std::numbers::pi * static_cast<double>(b) / beams;
    used.emplace_back(params_.lidar_x_m + r * std::cos(a), r * std::sin(a));
  }
  Weigh(used);
}

void ParticleFilter::Update(std::span<const Eigen::Vector2d> points) {
  std::vector<Eigen::Vector2d> used;
  for (std::size_t b = 0; b < points.size(); b += static_cast<std::size_t>(params_.beam_stride)) {
    if ((points[b] - Eigen::Vector2d(params_.lidar_x_m, 0)).norm() <= params_.max_range_m) {
      used.push_back(points[b]);
    }
  }
  Weigh(used);
}

void ParticleFilter::Weigh(std::span<const Eigen::Vector2d> used) {
  if (particles_.empty() || used.empty()) return;
  const double two_sigma2 = 2 * params_.hit_sigma_m * params_.hit_sigma_m;
  // Each used end point's distance to the map, per particle.
  const std::size_t n = particles_.size(), m = used.size();
  std::vector<float> distance(n * m);
  for (std::size_t i = 0; i < n; ++i) {
    const RigidTransform2& X = particles_[i].X_MV;
    for (std::size_t k = 0; k < m; ++k) {
      distance[i * m + k] = static_cast<float>(FieldDistance(X * used[k]));
    }
  }
  // Beam skipping (as ROS's AMCL does): a beam that ends near the map for too few particles
  // sees something the map has not (an unmapped box, a wall that stands a little elsewhere) and
  // is left out for all of them, unless that would leave out most beams.
  std::vector<bool> skip(m, false);
  if (params_.beam_skip_distance_m > 0) {
    std::size_t skipped = 0;
    for (std::size_t k = 0; k < m; ++k) {
      std::size_t near = 0;
      for (std::size_t i = 0; i < n; ++i)
        near += distance[i * m + k] <= params_.beam_skip_distance_m;
      skip[k] = static_cast<double>(near) < params_.beam_skip_threshold * static_cast<double>(n);
      skipped += skip[k];
    }
    if (static_cast<double>(skipped) > params_.beam_skip_error_threshold * static_cast<double>(m)) {
      std::fill(skip.begin(), skip.end(), false);
    }
  }
  std::vector<double> log_w(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    double sum = 0.0;
    for (std::size_t k = 0; k < m; ++k) {
      if (skip[k]) continue;
      const double d = distance[i * m + k];
      sum += std::log(std::exp(-d * d / two_sigma2) + params_.z_random);
    }
    log_w[i] = sum;
  }
  const double top = *std::max_element(log_w.begin(), log_w.end());
  std::vector<double> w(particles_.size());
  for (std::size_t i = 0; i < w.size(); ++i) w[i] = std::exp(log_w[i] - top);
  // KLD-sampling: draw by weight until the sample is large enough for the bins it fills.
  std::discrete_distribution<std::size_t> pick(w.begin(), w.end());
  std::unordered_set<std::int64_t> bins;
  std::vector<Particle> next;
  while (next.size() < params_.max_particles) {
    const Particle& p = particles_[pick(rng_)];
    next.push_back({p.X_MV, 1.0});
    const auto bx =
        static_cast<std::int64_t>(std::floor(p.X_MV.translation().x() / params_.bin_xy_m));
    const auto by =
        static_cast<std::int64_t>(std::floor(p.X_MV.translation().y() / params_.bin_xy_m));
    const auto bt =
        static_cast<std::int64_t>(std::floor(WrapAngle(p.X_MV.yaw()) / params_.bin_yaw_rad));
    bins.insert((bx * 100'003 + by) * 1'009 + bt + 500);
    if (next.size() >= KldCount(bins.size())) break;
  }
  for (Particle& p : next) p.weight = 1.0 / static_cast<double>(next.size());
  particles_ = std::move(next);
}

RigidTransform2 ParticleFilter::Estimate() const {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
  double s = 0, c = 0, total = 0;
  for (const Particle& p : particles_) {
    xy += p.weight * p.X_MV.translation();
    s += p.weight * std::sin(p.X_MV.yaw());
    c += p.weight * std::cos(p.X_MV.yaw());
    total += p.weight;
  }
  if (total <= 0) return RigidTransform2::FromXyYaw(0, 0, 0);
  xy /= total;
  return RigidTransform2::FromXyYaw(xy.x(), xy.y(), std::atan2(s, c));
}

}  // namespace autodrive::examples
