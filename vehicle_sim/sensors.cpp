#include "vehicle_sim/sensors.h"

#include <cmath>
#include <limits>
#include <numbers>

#include "common/error.h"
#include "vehicle_sim/variability.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim {

namespace {

// Whether a rate-driven sensor is due at `now`: its `count`-th sample is at count / rate.
bool Due(Duration now, double rate_hz, std::int64_t& count) {
  if (ToSeconds(now) + 1e-12 < static_cast<double>(count) / rate_hz) return false;
  count = static_cast<std::int64_t>(std::floor(ToSeconds(now) * rate_hz + 1e-9)) + 1;
  return true;
}

}  // namespace

void SensorReadings::Clear() {
  feedback.reset();
  encoders.reset();
  ips.reset();
  imu.reset();
  lidar.reset();
}

SensorSuite::SensorSuite(const SensorConfig& config, int vehicle, std::uint64_t seed)
    : config_(config),
      vehicle_(vehicle),
      ips_rng_(StreamSeed(seed, vehicle, 1)),
      imu_rng_(StreamSeed(seed, vehicle, 2)),
      lidar_rng_(StreamSeed(seed, vehicle, 3)) {
  config_.lidar.Validate();
  const LidarConfig& l = config_.lidar;
  scan_.angle_min_rad = -std::numbers::pi;
  scan_.angle_increment_rad = 2 * std::numbers::pi / l.beams;
  scan_.scan_time_s = 1.0 / l.rate_hz;
  scan_.time_increment_s = l.instantaneous ? 0.0 : scan_.scan_time_s / l.beams;
  scan_.range_min_m = l.range_min_m;
  scan_.range_max_m = l.range_max_m;
  scan_.ranges.assign(static_cast<std::size_t>(l.beams), 0.0F);
}

std::span<const DynamicBox> SensorSuite::ReachableBoxes(const Eigen::Isometry3d& X_ML,
                                                        std::span<const DynamicBox> boxes,
                                                        int first, int last) {
  // A few boxes (the other cars) are cheaper to test with every beam.
  constexpr std::size_t kFewBoxes = 16;
  if (boxes.size() <= kFewBoxes) return boxes;
  const LidarConfig& l = config_.lidar;
  const Eigen::Vector2d o = X_ML.translation().head<2>();
  // The ground projections of the first and last beams' directions. The beams between them
  // turn monotonically from one to the other (the projection of the scan plane keeps its
  // orientation while the LIDAR is tilted less than 60 degrees: det > 0.5); the wedge test
  // is used for a sweep of at most 90 degrees, else only the range.
  const Eigen::Matrix2d A = X_ML.linear().topLeftCorner<2, 2>();
  const double a0 = scan_.angle_min_rad + first * scan_.angle_increment_rad;
  const double a1 = scan_.angle_min_rad + (last - 1) * scan_.angle_increment_rad;
  const bool wedge = a1 - a0 <= std::numbers::pi / 2 && A.determinant() > 0.5;
  Eigen::Vector2d u0 = A * Eigen::Vector2d(std::cos(a0), std::sin(a0));
  Eigen::Vector2d u1 = A * Eigen::Vector2d(std::cos(a1), std::sin(a1));
  u0.normalize();
  u1.normalize();
  const Eigen::Vector2d mid = (u0 + u1).normalized();
  reachable_.clear();
  for (const DynamicBox& b : boxes) {
    // A box is kept when its bounding sphere's shadow on the ground may meet the sector:
    // within range, not wholly clockwise of the first beam's line nor counter-clockwise of the
    // last's, nor wholly behind the wedge.
    const Eigen::Vector2d p = b.X_MB.translation().head<2>() - o;
    const double r = b.half_extents_m.norm();
    const double reach = l.range_max_m + r;
    if (p.squaredNorm() > reach * reach) continue;
    if (wedge && (u0.x() * p.y() - u0.y() * p.x() < -r || p.x() * u1.y() - p.y() * u1.x() < -r ||
                  p.dot(mid) < -r)) {
      continue;
    }
    reachable_.push_back(b);
  }
  return reachable_;
}

void SensorSuite::CastBeams(const VehicleState& state, const StaticScene& scene,
                            std::span<const DynamicBox> all_boxes, int first, int last) {
  const LidarConfig& l = config_.lidar;
  const Eigen::Isometry3d X_MV =
      Eigen::Translation3d(state.X_MV.translation()) * state.X_MV.rotation();
  const Eigen::Isometry3d X_VL = Eigen::Translation3d(l.x_m, l.y_m, l.z_m) *
                                 Eigen::AngleAxisd(l.yaw_rad, Eigen::Vector3d::UnitZ());
  const Eigen::Isometry3d X_ML = X_MV * X_VL;
  const Eigen::Matrix3d R_ML = X_ML.linear();
  const std::span<const DynamicBox> boxes = ReachableBoxes(X_ML, all_boxes, first, last);
  Ray ray;
  ray.origin_M = X_ML.translation();
  const BoxId self(static_cast<std::uint32_t>(vehicle_));
  for (int i = first; i < last; ++i) {
    const double a = scan_.angle_min_rad + i * scan_.angle_increment_rad;
    ray.direction_M = R_ML * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0);
    const Hit hit = Cast(scene, boxes, ray, l.range_max_m, self);
    double range = hit.range_m;
    if (std::isfinite(range)) range += Gaussian(lidar_rng_, l.range_noise_m);
    if (!(range >= l.range_min_m && range < l.range_max_m)) {
      range = std::numeric_limits<double>::infinity();
    }
    scan_.ranges[static_cast<std::size_t>(i)] = static_cast<float>(range);
  }
  rays_cast_ += last - first;
}

void SensorSuite::Sample(const World& world, const StaticScene& scene,
                         std::span<const DynamicBox> boxes, SensorReadings& readings) {
  readings.Clear();
  const Duration now = world.time();
  const VehicleState& s = world.State(vehicle_);
  const VehicleParams& p = world.Params(vehicle_);

  if (Due(now, config_.feedback.rate_hz, feedback_count_)) {
    readings.feedback = FeedbackReading{now, s.throttle, s.steering_rad};
  }
  if (Due(now, config_.encoders.rate_hz, encoder_count_)) {
    EncoderReading e{now, s.encoder_ticks, {}};
    for (std::size_t k = 0; k < 2; ++k) {
      e.angle_rad[k] =
          static_cast<double>(e.ticks[k]) * 2 * std::numbers::pi / p.encoder_counts_per_rev;
    }
    readings.encoders = e;
  }
  if (Due(now, config_.ips.rate_hz, ips_count_)) {
    IpsReading r{now, s.X_MV.translation()};
    for (int k = 0; k < 3; ++k) r.position_m[k] += Gaussian(ips_rng_, config_.ips.noise_m);
    readings.ips = r;
  }
  if (Due(now, config_.imu.rate_hz, imu_count_)) {
    const ImuConfig& c = config_.imu;
    ImuReading r;
    r.stamp = now;
    Eigen::Quaterniond q = s.X_MV.rotation();
    if (c.orientation_noise_rad > 0) {
      const Eigen::Vector3d e(Gaussian(imu_rng_, c.orientation_noise_rad),
                              Gaussian(imu_rng_, c.orientation_noise_rad),
                              Gaussian(imu_rng_, c.orientation_noise_rad));
      q = q * Eigen::Quaterniond(Eigen::AngleAxisd(e.norm(), e.normalized()));
    }
    r.orientation = q;
    // Gravity in V from the true attitude: the accelerometer feels it whatever the estimate.
    const Eigen::Vector3d g_V = s.X_MV.rotation().toRotationMatrix().transpose() *
                                Eigen::Vector3d(0, 0, -world.options().gravity_mps2);
    const Eigen::Vector3d specific = c.gravity ? Eigen::Vector3d(s.a_V_mps2 - g_V) : s.a_V_mps2;
    for (int k = 0; k < 3; ++k) {
      r.angular_velocity_radps[k] =
          s.w_V_radps[k] + c.gyro_bias_radps + Gaussian(imu_rng_, c.gyro_noise_radps);
      r.linear_acceleration_mps2[k] =
          specific[k] + c.accel_bias_mps2 + Gaussian(imu_rng_, c.accel_noise_mps2);
    }
    readings.imu = r;
  }

  // LIDAR: the beams whose time has come.
  const LidarConfig& l = config_.lidar;
  const double t = ToSeconds(now);
  const auto current = static_cast<std::int64_t>(std::floor(t * l.rate_hz + 1e-9));
  if (l.instantaneous) {
    if (current >= sweep_) {
      scan_.stamp = now;
      CastBeams(s, scene, boxes, 0, l.beams);
      readings.lidar = scan_;
      sweep_ = current + 1;
    }
    return;
  }
  // A sweep whose time is long past (the suite was not sampled for a while) is skipped: the
  // scan starts with the current sweep, so that its beams are taken along the motion.
  if (beams_done_ == 0 && current > sweep_) sweep_ = current;
  const double sweep_start = static_cast<double>(sweep_) / l.rate_hz;
  if (t + 1e-12 < sweep_start) return;
  if (beams_done_ == 0) scan_.stamp = FromSeconds(sweep_start);
  // Beam i is due at sweep_start + i * time_increment.
  const int due = std::min(
      l.beams, static_cast<int>(std::floor((t - sweep_start) / scan_.time_increment_s + 1e-9)) + 1);
  if (due > beams_done_) {
    CastBeams(s, scene, boxes, beams_done_, due);
    beams_done_ = due;
  }
  if (beams_done_ == l.beams) {
    readings.lidar = scan_;
    beams_done_ = 0;
    ++sweep_;
  }
}

void SensorSuite::Reachable(const World& world, std::span<const DynamicBox> candidates,
                            Duration horizon, std::vector<DynamicBox>& out) const {
  const LidarConfig& l = config_.lidar;
  const VehicleParams& p = world.Params(vehicle_);
  const Eigen::Vector2d at = world.State(vehicle_).X_MV.translation().head<2>();
  const double reach = l.range_max_m + std::hypot(l.x_m, l.y_m) +
                       std::max(p.top_speed_mps, p.reverse_top_speed_mps) * ToSeconds(horizon) +
                       0.05;
  for (const DynamicBox& b : candidates) {
    const double r = reach + b.half_extents_m.norm();
    if ((b.X_MB.translation().head<2>() - at).squaredNorm() <= r * r) out.push_back(b);
  }
}

void VehicleBoxes(const World& world, std::vector<DynamicBox>& boxes) {
  boxes.clear();
  for (int i = 0; i < world.vehicles(); ++i) {
    DynamicBox b{BoxId(static_cast<std::uint32_t>(i)), Eigen::Isometry3d::Identity(),
                 Eigen::Vector3d::Zero()};
    world.VehicleBox(i, b.X_MB, b.half_extents_m);
    boxes.push_back(b);
  }
}

}  // namespace autodrive::vehicle_sim
