#pragma once
/// @file
/// Localisation against a map for the parking case study: a particle filter (Monte Carlo
/// localisation, Thrun, Burgard and Fox, "Probabilistic Robotics", ch. 8) with KLD-sampling
/// (Fox 2003: as many particles as it takes for the sampled belief to stay within `kld_epsilon`
/// of the true one with probability 1 - `kld_delta`, counted over 10 cm x 10 cm x 10° bins,
/// between `min_particles` and `max_particles`).
///
/// - **Motion**: the odometry model: each particle moves by the car-frame displacement measured
///   between two steps (dx, dy, dθ), with Gaussian noise growing with the distance and the turn.
/// - **Measurement**: the likelihood field of the map's occupancy grid (each beam's end point is
///   scored by its distance to the nearest occupied cell: a Gaussian of `hit_sigma_m`, mixed with
///   a uniform `z_random`), every `beam_stride`-th beam of a 360-beam planar scan.
/// - **Resampling**: low-variance, after each measurement, to the KLD-sampling count.

#include <cstdint>
#include <random>
#include <span>
#include <vector>

#include "common/config.h"
#include "common/geometry.h"
#include "maps/occupancy.h"

namespace autodrive::examples {

struct ParticleFilterParams {
  std::size_t min_particles = 100;
  std::size_t max_particles = 5000;
  double kld_epsilon = 0.05;
  double kld_z = 2.326;  ///< the upper 1 - δ quantile of N(0, 1): δ = 0.01
  double bin_xy_m = 0.1;
  double bin_yaw_rad = 0.1745;  ///< 10°
  /// Odometry noise: σ of the translation per metre moved and per radian turned, and of the
  /// rotation per radian turned and per metre moved (Probabilistic Robotics' α1..α4).
  double alpha_trans_per_m = 0.1, alpha_trans_per_rad = 0.02;
  double alpha_rot_per_rad = 0.1, alpha_rot_per_m = 0.2;
  double hit_sigma_m = 0.04;  ///< the likelihood field's σ (the LIDAR's 2.5 cm and the map's)
  double z_random = 0.05;     ///< weight of a beam that matches nothing
  double max_range_m = 3.0;   ///< beams beyond are left out
  int beam_stride = 6;        ///< every 6th beam of 360: 60 beams
  /// Beam skipping (ROS AMCL's): a beam is left out when its end point lies within
  /// `beam_skip_distance_m` of the map for fewer than `beam_skip_threshold` of the particles,
  /// unless more than `beam_skip_error_threshold` of the beams would be. 0: no skipping.
  double beam_skip_distance_m = 0.0;
  double beam_skip_threshold = 0.3;
  double beam_skip_error_threshold = 0.9;
  double lidar_x_m = 0.1445;  ///< the LIDAR ahead of the rear axle
  std::uint64_t seed = 1;

  /// The tunables (the LIDAR's place comes from the city). See examples/parking/parking.yaml.
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("min_particles", min_particles, config::Range<std::size_t>{1, 1'000'000});
    a.Optional("max_particles", max_particles, config::Range<std::size_t>{1, 1'000'000});
    a.Optional("kld_epsilon", kld_epsilon, config::Range{0.001, 1.0});
    a.Optional("kld_z", kld_z, config::Range{0.1, 10.0});
    a.Optional("bin_xy_m", bin_xy_m, config::Range{0.005, 2.0});
    a.Optional("bin_yaw_rad", bin_yaw_rad, config::Range{0.005, 3.2});
    a.Optional("alpha_trans_per_m", alpha_trans_per_m, config::Range{0.0, 10.0});
    a.Optional("alpha_trans_per_rad", alpha_trans_per_rad, config::Range{0.0, 10.0});
    a.Optional("alpha_rot_per_rad", alpha_rot_per_rad, config::Range{0.0, 10.0});
    a.Optional("alpha_rot_per_m", alpha_rot_per_m, config::Range{0.0, 10.0});
    a.Optional("hit_sigma_m", hit_sigma_m, config::Range{0.001, 1.0});
    a.Optional("z_random", z_random, config::Range{0.0, 1.0});
    a.Optional("max_range_m", max_range_m, config::Range{0.2, 50.0});
    a.Optional("beam_stride", beam_stride, config::Range{1, 360});
    a.Optional("beam_skip_distance_m", beam_skip_distance_m, config::Range{0.0, 1.0});
    a.Optional("beam_skip_threshold", beam_skip_threshold, config::Range{0.0, 1.0});
    a.Optional("beam_skip_error_threshold", beam_skip_error_threshold, config::Range{0.0, 1.0});
    a.Optional("seed", seed);
  }
  void Validate() const {
    if (max_particles < min_particles) {
      throw ConfigError("max_particles must be at least min_particles");
    }
  }
};

struct Particle {
  RigidTransform2 X_MV;
  double weight = 1.0;
};

class ParticleFilter {
 public:
  /// The map's grid (occupied: what a LIDAR sees), and the filter's figures.
  ParticleFilter(const maps::OccupancyGrid& grid, const ParticleFilterParams& params = {});

  /// Weighs against another grid from now on (the particles stay where they are).
  void SetMap(const maps::OccupancyGrid& grid);
  /// Starts with `max_particles` drawn around `X_MV` (σ `sigma_xy_m` in x and y and
  /// `sigma_yaw_rad` in heading).
  void Init(const RigidTransform2& X_MV, double sigma_xy_m, double sigma_yaw_rad);
  /// Moves every particle by the odometry's car-frame displacement `delta` (from the last pose
  /// the odometry gave to this one), with the motion model's noise.
  void Predict(const RigidTransform2& delta);
  /// Weighs the particles by `ranges` (beam i at i 2π / n counter-clockwise from the car's front;
  /// not finite: no return), then resamples to the KLD-sampling count.
  void Update(std::span<const float> ranges);
  /// The same for a scan's end points given in the car's frame at the particles' time (e.g. a
  /// rotating LIDAR's beams moved by the odometry to where the car is now): every
  /// `beam_stride`-th point is used.
  void Update(std::span<const Eigen::Vector2d> points);

  /// The weighted mean pose (the heading's mean on the circle).
  [[nodiscard]] RigidTransform2 Estimate() const;
  [[nodiscard]] std::size_t size() const { return particles_.size(); }
  [[nodiscard]] const std::vector<Particle>& particles() const { return particles_; }

 private:
  // Weighs the particles by these end points (car frame) and resamples.
  void Weigh(std::span<const Eigen::Vector2d> used);
  [[nodiscard]] double FieldDistance(const Eigen::Vector2d& p) const;
  [[nodiscard]] std::size_t KldCount(std::size_t bins) const;

  maps::OccupancyGrid grid_;
  ParticleFilterParams params_;
  std::vector<float> distance_;  // per cell: metres to the nearest occupied cell's centre
  std::vector<Particle> particles_;
  std::mt19937_64 rng_;
};

}  // namespace autodrive::examples
