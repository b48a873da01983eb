#pragma once
/// @file
/// Nigel's sensors, each at its own rate and with its mounting (docs/vehicle_sim.md): actuator
/// feedback, rear-wheel encoders, IPS, IMU and the 2-D LIDAR. A `SensorSuite` per car samples
/// them from the world after each physics step and hands out readings as plain values; the DDS
/// service (and anything else: the benchmark, tests) turns them into messages. The cameras
/// are configured here (`front_camera`, `rear_camera`) but rendered by `SimCameras`
/// (cameras.h), which costs milliseconds a frame and so runs apart from the suite.
///
/// Frames: the vehicle frame V (vehicle.h); readings carry their sensor's own frame as the
/// devkit names it (`imu`, `lidar`, `left_encoder`, ...). Times are simulated time since the
/// start of the world.
///
/// Noise: every sensor of every car draws from its own engine, seeded from the simulation's
/// seed, the car's index and the sensor, so a run is reproducible and adding a car or a sensor
/// does not change another's noise.

#include <cstdint>
#include <optional>
#include <random>
#include <span>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/config.h"
#include "common/time.h"
#include "vehicle_sim/camera_config.h"
#include "vehicle_sim/raycast.h"
#include "vehicle_sim/vehicle.h"

namespace autodrive::vehicle_sim {

class World;

struct FeedbackConfig {
  double rate_hz = 50.0;  ///< chosen: the devkit publishes feedback with every data frame
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("rate_hz", rate_hz, config::Range{0.1, 1000.0});
  }
  bool operator==(const FeedbackConfig&) const = default;
};

struct EncoderConfig {
  double rate_hz = 50.0;  ///< chosen
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("rate_hz", rate_hz, config::Range{0.1, 1000.0});
  }
  bool operator==(const EncoderConfig&) const = default;
};

struct IpsConfig {
  double rate_hz = 30.0;  ///< chosen: an overhead camera's frame rate
  double noise_m = 0.0;   ///< standard deviation of each coordinate
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("rate_hz", rate_hz, config::Range{0.1, 1000.0});
    a.Optional("noise_m", noise_m, config::Range{0.0, 10.0});
  }
  bool operator==(const IpsConfig&) const = default;
};

/// The MPU-9250, at the chassis' centre of mass with V's axes. Linear acceleration is what an
/// accelerometer measures: the specific force, acceleration minus gravity, so a car at rest
/// reads +g along its z (ROS's sensor_msgs/Imu convention; `gravity: false` subtracts it).
struct ImuConfig {
  double rate_hz = 100.0;         ///< chosen
  double gyro_noise_radps = 0.0;  ///< standard deviation per axis
  double gyro_bias_radps = 0.0;   ///< constant, on every axis
  double accel_noise_mps2 = 0.0;
  double accel_bias_mps2 = 0.0;
  double orientation_noise_rad = 0.0;  ///< about each axis
  bool gravity = true;
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("rate_hz", rate_hz, config::Range{0.1, 10000.0});
    a.Optional("gyro_noise_radps", gyro_noise_radps, config::Range{0.0, 100.0});
    a.Optional("gyro_bias_radps", gyro_bias_radps, config::Range{-100.0, 100.0});
    a.Optional("accel_noise_mps2", accel_noise_mps2, config::Range{0.0, 1000.0});
    a.Optional("accel_bias_mps2", accel_bias_mps2, config::Range{-1000.0, 1000.0});
    a.Optional("orientation_noise_rad", orientation_noise_rad, config::Range{0.0, 10.0});
    a.Optional("gravity", gravity);
  }
  bool operator==(const ImuConfig&) const = default;
};

/// The RPLIDAR A1: a planar scan of `beams` beams over 360 degrees, mounted at (x, y, z) in V
/// and yawed by `yaw_rad` (NIGEL.md: 0.1445 m ahead of the rear axle, 0.1757 m up, yawed 180
/// degrees, so the LIDAR frame's x points to the car's rear). Beam i points at -pi + i 2 pi /
/// beams in the LIDAR frame: beam 0 points to the car's front, beam beams/2 to its rear.
struct LidarConfig {
  double rate_hz = 7.0;
  int beams = 360;
  double range_min_m = 0.15;
  double range_max_m = 12.0;
  double range_noise_m = 0.0;  ///< standard deviation
  double x_m = 0.1445;         ///< mounting in V (ahead of the rear axle)
  double y_m = 0.0;
  double z_m = 0.1757;
  double yaw_rad = 3.14159265358979323846;
  /// false (the default): each beam is taken at its own time during the sweep, from the pose
  /// of that moment, as a spinning RPLIDAR does; true: the whole scan at one instant.
  bool instantaneous = false;
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("rate_hz", rate_hz, config::Range{0.1, 100.0});
    a.Optional("beams", beams, config::Range{1, 100000});
    a.Optional("range_min_m", range_min_m, config::Range{0.0, 1000.0});
    a.Optional("range_max_m", range_max_m, config::Range{0.01, 1000.0});
    a.Optional("range_noise_m", range_noise_m, config::Range{0.0, 10.0});
    a.Optional("x_m", x_m, config::Range{-10.0, 10.0});
    a.Optional("y_m", y_m, config::Range{-10.0, 10.0});
    a.Optional("z_m", z_m, config::Range{-10.0, 10.0});
    a.Optional("yaw_rad", yaw_rad, config::Range{-10.0, 10.0});
    a.Optional("instantaneous", instantaneous);
  }
  void Validate() const;
  bool operator==(const LidarConfig&) const = default;
};

struct SensorConfig {
  FeedbackConfig feedback;
  EncoderConfig encoders;
  IpsConfig ips;
  ImuConfig imu;
  LidarConfig lidar;
  /// Rendered by the simulator's cameras (cameras.h), not by the suite.
  OnboardCameraConfig front_camera = DefaultFrontCamera();
  OnboardCameraConfig rear_camera = DefaultRearCamera();
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("feedback", feedback);
    a.Optional("encoders", encoders);
    a.Optional("ips", ips);
    a.Optional("imu", imu);
    a.Optional("lidar", lidar);
    a.Optional("front_camera", front_camera);
    a.Optional("rear_camera", rear_camera);
  }
  bool operator==(const SensorConfig&) const = default;
};

/// Throttle (normalised) and steering (rad, the actuator's equivalent single-wheel angle) as
/// applied.
struct FeedbackReading {
  Duration stamp{0};
  double throttle = 0.0;
  double steering_rad = 0.0;
};

/// The rear-wheel encoders: ticks, and the angle they stand for (ticks x 2 pi / counts per
/// revolution, as the devkit reports it), {left, right}.
struct EncoderReading {
  Duration stamp{0};
  std::array<std::int64_t, 2> ticks{0, 0};
  std::array<double, 2> angle_rad{0.0, 0.0};
};

/// Position of the vehicle frame's origin in the map frame (right-handed, m).
struct IpsReading {
  Duration stamp{0};
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
};

struct ImuReading {
  Duration stamp{0};
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();     ///< of V in M
  Eigen::Vector3d angular_velocity_radps = Eigen::Vector3d::Zero();    ///< in V
  Eigen::Vector3d linear_acceleration_mps2 = Eigen::Vector3d::Zero();  ///< in V, see ImuConfig
};

/// One sweep, as sensor_msgs/LaserScan has it: `ranges[i]` is the range of the beam at angle
/// `angle_min + i * angle_increment` in the LIDAR frame (x along the car's -x when mounted
/// yawed 180 degrees; angles counter-clockwise seen from above), taken at `stamp + i *
/// time_increment`. +infinity: no return within [range_min, range_max).
struct LidarScan {
  Duration stamp{0};  ///< time of the first beam
  double angle_min_rad = 0.0;
  double angle_increment_rad = 0.0;
  double time_increment_s = 0.0;
  double scan_time_s = 0.0;
  double range_min_m = 0.0;
  double range_max_m = 0.0;
  std::vector<float> ranges;
};

/// What a car's sensors produced in one step (most steps produce few or none).
struct SensorReadings {
  std::optional<FeedbackReading> feedback;
  std::optional<EncoderReading> encoders;
  std::optional<IpsReading> ips;
  std::optional<ImuReading> imu;
  std::optional<LidarScan> lidar;  ///< a sweep that completed in this step
  void Clear();
};

/// The sensors of one car. Copy: no; move: yes.
class SensorSuite {
 public:
  /// `vehicle` is the car's index in the world (its box id for the LIDAR is the same).
  SensorSuite(const SensorConfig& config, int vehicle, std::uint64_t seed);

  /// After a world step: samples every sensor that is due at the world's time into
  /// `readings` (cleared first). `scene` and `boxes` are what the LIDAR sees (`boxes` should
  /// include this car's own box: it is excluded by id). With many boxes (background traffic),
  /// the beams of a step are tested only against the boxes whose bounding circle meets the
  /// wedge those beams sweep within their range, so that boxes elsewhere cost one test per
  /// step instead of one per beam.
  void Sample(const World& world, const StaticScene& scene, std::span<const DynamicBox> boxes,
              SensorReadings& readings);

  /// Appends to `out` the boxes of `candidates` that this car's LIDAR may reach within
  /// `horizon` from now: those whose bounding circle comes within the LIDAR's range of where
  /// the car may get at its top speed (and 5 cm). For boxes that stay put for a while (the
  /// background traffic of a control period): the others need not be given to `Sample`.
  void Reachable(const World& world, std::span<const DynamicBox> candidates, Duration horizon,
                 std::vector<DynamicBox>& out) const;

  [[nodiscard]] const SensorConfig& config() const { return config_; }
  /// Rays cast so far (for the benchmark).
  [[nodiscard]] std::int64_t rays_cast() const { return rays_cast_; }

 private:
  void CastBeams(const VehicleState& state, const StaticScene& scene,
                 std::span<const DynamicBox> boxes, int first, int last);
  std::span<const DynamicBox> ReachableBoxes(const Eigen::Isometry3d& X_ML,
                                             std::span<const DynamicBox> boxes, int first,
                                             int last);

  SensorConfig config_;
  int vehicle_;
  std::mt19937_64 ips_rng_, imu_rng_, lidar_rng_;
  // Next sample time of each rate-driven sensor, in whole steps of its period from the start.
  std::int64_t feedback_count_ = 0, encoder_count_ = 0, ips_count_ = 0, imu_count_ = 0;
  // The sweep in progress: its number, the beams cast so far, their ranges.
  std::int64_t sweep_ = 0;
  int beams_done_ = 0;
  LidarScan scan_;
  std::vector<DynamicBox> reachable_;  // scratch: the boxes this step's beams can reach
  std::int64_t rays_cast_ = 0;
};

/// The boxes of every car in `world` (the chassis' collision boxes), with box id = car index.
void VehicleBoxes(const World& world, std::vector<DynamicBox>& boxes);

}  // namespace autodrive::vehicle_sim
