#pragma once
/// @file
/// What a simulated car is told (`VehicleCommand`) and what it is doing (`VehicleState`). What
/// it is lives in `VehicleParams` (vehicle_params.h); the World (world.h) steps it.

#include <array>
#include <cstdint>
#include <string_view>

#include <Eigen/Core>

#include "common/geometry.h"

namespace autodrive::vehicle_sim {

/// The devkit's commands, normalised: throttle in [-1, 1] (negative is reverse; 0 holds the
/// car with the brake torque) and steering in [-1, 1] of the steering limit (positive left).
/// Values outside [-1, 1] are saturated; a non-finite value is an InputError at `SetCommand`.
struct VehicleCommand {
  double throttle = 0.0;
  double steering = 0.0;
  bool operator==(const VehicleCommand&) const = default;
};

/// The wheels, in this order everywhere.
enum class Wheel { kFrontLeft = 0, kFrontRight = 1, kRearLeft = 2, kRearRight = 3 };
inline constexpr int kWheels = 4;
/// "front_left", ...
[[nodiscard]] std::string_view ToString(Wheel wheel);

/// One wheel now.
struct WheelState {
  double spin_radps = 0.0;         ///< about its axle, positive rolling forward
  double spin_angle_rad = 0.0;     ///< integral of spin_radps since the start (not wrapped)
  double steer_rad = 0.0;          ///< about the chassis' z, positive left (0 for rear wheels)
  double normal_force_n = 0.0;     ///< from the ground, last step (0 in the air)
  double slip_longitudinal = 0.0;  ///< (r w - v_x) / v_ref, last step
  double slip_lateral = 0.0;       ///< v_y / v_ref, last step (positive: sliding to the left)
  bool operator==(const WheelState&) const = default;
};

/// One vehicle now: a snapshot taken after each step.
struct VehicleState {
  /// The vehicle frame V (middle of the rear axle, on the ground at rest; x forward, y left,
  /// z up) in the map frame M.
  RigidTransform3 X_MV;
  Eigen::Vector3d v_V_mps = Eigen::Vector3d::Zero();    ///< velocity of V's origin, in V
  Eigen::Vector3d w_V_radps = Eigen::Vector3d::Zero();  ///< angular velocity, in V
  /// Acceleration of the chassis' centre of mass over the last step, in V (m/s^2; gravity not
  /// included).
  Eigen::Vector3d a_V_mps2 = Eigen::Vector3d::Zero();
  std::array<WheelState, kWheels> wheels{};
  double steering_rad = 0.0;  ///< the steering actuator: the equivalent single-wheel angle
  double throttle = 0.0;      ///< applied, after saturation
  /// Rear-wheel encoders: floor(spin angle / 2 pi * counts per revolution) {left, right}.
  std::array<std::int64_t, 2> encoder_ticks{0, 0};
};

}  // namespace autodrive::vehicle_sim
