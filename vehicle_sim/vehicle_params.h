#pragma once
/// @file
/// What Nigel (the 1:14 car) is: geometry, masses, suspension, tyres, drive and steering, as
/// one strict config struct whose defaults are the car's published figures. What the car
/// is doing now is `VehicleState` (vehicle.h); the two are never mixed (MuJoCo's mjModel and
/// mjData). See docs/vehicle_sim.md for where each figure comes from.
///
/// Vehicle frame V: origin at the middle of the rear axle, on the ground (at rest on flat
/// ground), x forward, y left, z up; metres, radians. Positive steering turns left.

#include <array>
#include <string_view>
#include <utility>

#include "common/config.h"

namespace autodrive::vehicle_sim {

/// A tyre's force against slip: two cubic pieces (Hermite), from (0, 0) with slope
/// `initial_slope` to the extremum (`extremum_slip`, `extremum_value`) where the slope is zero,
/// then to the asymptote (`asymptote_slip`, `asymptote_value`) where the slope is zero again,
/// constant beyond it, odd in the slip (the paper's section 3.2, as Unity's WheelFrictionCurve).
/// Values are fractions of the friction limit mu N: the force is `mu * N * Value(S)`.
struct TyreCurve {
  double extremum_slip = 0.2;
  double extremum_value = 1.0;
  double asymptote_slip = 0.5;
  double asymptote_value = 0.75;
  /// dValue/dS at S = 0. When unset (0), the vehicle derives it from its cornering stiffness
  /// (`VehicleParams::cornering_stiffness_n_per_rad`) at each wheel's static load.
  double initial_slope = 0.0;

  /// Value(S), odd in S; S may be any finite number.
  [[nodiscard]] double Value(double slip) const;
  /// Value(S) / S, the curve's secant through the origin (its slope at S = 0 when S is 0):
  /// positive, and at most the initial slope for a well-formed curve.
  [[nodiscard]] double Secant(double slip) const;
  /// Throws InputError when the pieces are not ordered (0 < extremum_slip < asymptote_slip),
  /// a value is not in (0, 1], or the first piece would overshoot its extremum (initial_slope
  /// > 3 extremum_value / extremum_slip, where the cubic stops being monotonic).
  void Validate() const;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("extremum_slip", extremum_slip, config::Range{1e-4, 10.0});
    a.Optional("extremum_value", extremum_value, config::Range{1e-3, 1.0});
    a.Optional("asymptote_slip", asymptote_slip, config::Range{1e-4, 100.0});
    a.Optional("asymptote_value", asymptote_value, config::Range{1e-3, 1.0});
    a.Optional("initial_slope", initial_slope, config::Range{0.0, 1e4});
  }
  bool operator==(const TyreCurve&) const = default;
};

/// Which wheels the motors drive.
enum class DriveLayout { kRear, kFront, kAll };
constexpr auto ConfigEnumNames(DriveLayout) {
  return std::array{std::pair{DriveLayout::kRear, std::string_view{"rear"}},
                    std::pair{DriveLayout::kFront, std::string_view{"front"}},
                    std::pair{DriveLayout::kAll, std::string_view{"all"}}};
}

/// Nigel, by default. Every length in metres, mass in kg, angle in radians, time in seconds.
struct VehicleParams {
  // --- geometry ---
  double wheelbase_m = 0.14154;    ///< rear axle to front axle (AutoDRIVE configs)
  double track_width_m = 0.153;    ///< wheel centre to wheel centre (simulator; sys-ID 0.14724)
  double wheel_radius_m = 0.0325;  ///< (simulator)
  double wheel_width_m = 0.025;    ///< for the wheel's inertia and drawing only
  double body_length_m = 0.318;    ///< collision box and drawing (sys-ID)
  double body_width_m = 0.175;     ///< (sys-ID)
  double body_height_m = 0.257;    ///< top of the car above the ground, LIDAR included (sys-ID)
  double body_clearance_m = 0.02;  ///< bottom of the body's collision box above the ground
  /// Centre of the body box ahead of the rear axle: half the wheelbase (equal overhangs).
  double body_centre_ahead_of_rear_axle_m = 0.07077;

  // --- masses ---
  double mass_kg = 2.68;                     ///< whole car, wheels included (sys-ID)
  double wheel_mass_kg = 0.05;               ///< each wheel: a solid disc, I = m r^2 / 2
  double com_ahead_of_rear_axle_m = 0.0793;  ///< whole car (sys-ID: 0.0623 m behind the front)
  double com_height_m = 0.0993;              ///< whole car, above the ground (sys-ID)
  double yaw_inertia_kgm2 = 0.01944;         ///< whole car about its centre of mass (sys-ID)

  // --- suspension: a spring-damper per corner on its sprung mass ---
  double suspension_frequency_hz = 10.0;  ///< natural frequency of each corner (stiff)
  double suspension_damping_ratio = 0.7;

  // --- tyres ---
  double friction_coefficient = 0.4;             ///< mu, polished concrete (sys-ID)
  double cornering_stiffness_n_per_rad = 22.48;  ///< per tyre at its static load (sys-ID)
  /// Per tyre at its static load, N per unit longitudinal slip. No measured figure: taken
  /// equal to the cornering stiffness.
  double longitudinal_stiffness_n = 22.48;
  TyreCurve longitudinal{0.2, 1.0, 0.5, 0.75, 0.0};
  TyreCurve lateral{0.2, 1.0, 0.5, 0.75, 0.0};
  /// Slip is (r w - v_x) / v_ref and v_y / v_ref with v_ref = sqrt(v_x^2 + guard^2): smooth
  /// through zero speed, where the tyre holds like stiff static friction (m/s).
  double slip_speed_guard_mps = 1e-4;

  // --- drive ---
  DriveLayout drive = DriveLayout::kRear;
  double top_speed_mps = 0.26;          ///< at full forward throttle, flat ground (paper)
  double reverse_top_speed_mps = 0.23;  ///< at full reverse throttle (paper)
  double drive_torque_nm = 2.352;       ///< per driven wheel at full throttle (simulator)
  /// Holding torque of each driven wheel at zero throttle (the paper: the idle holding torque
  /// equals the brake torque); no figure: taken equal to the drive torque.
  double brake_torque_nm = 2.352;
  /// Rotational damping of every wheel (rolling resistance), N m per rad/s.
  double rolling_resistance_nms = 2e-5;

  // --- steering ---
  double steering_limit_rad = 0.5236;  ///< +-30 degrees of the equivalent single wheel (paper)
  /// Slew rate of the steering actuator (rad/s): 315.8 deg/s, the AutoDRIVE simulator's. The
  /// paper's "~0.42 rad/s for steering" would take 1.25 s from straight to full lock, far
  /// slower than the 9.4 kgf cm servo; set it here to use it.
  double steering_rate_radps = 5.5118;
  double steering_torque_nm = 0.92;  ///< servo stall torque, 9.4 kgf cm (paper)

  // --- sensors carried by the model ---
  int encoder_counts_per_rev = 1920;  ///< rear wheels (paper)

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("wheelbase_m", wheelbase_m, config::Range{0.01, 10.0});
    a.Optional("track_width_m", track_width_m, config::Range{0.01, 10.0});
    a.Optional("wheel_radius_m", wheel_radius_m, config::Range{0.001, 2.0});
    a.Optional("wheel_width_m", wheel_width_m, config::Range{0.001, 2.0});
    a.Optional("body_length_m", body_length_m, config::Range{0.01, 20.0});
    a.Optional("body_width_m", body_width_m, config::Range{0.01, 10.0});
    a.Optional("body_height_m", body_height_m, config::Range{0.01, 10.0});
    a.Optional("body_clearance_m", body_clearance_m, config::Range{0.0, 1.0});
    a.Optional("body_centre_ahead_of_rear_axle_m", body_centre_ahead_of_rear_axle_m,
               config::Range{-10.0, 10.0});
    a.Optional("mass_kg", mass_kg, config::Range{0.01, 10000.0});
    a.Optional("wheel_mass_kg", wheel_mass_kg, config::Range{0.001, 1000.0});
    a.Optional("com_ahead_of_rear_axle_m", com_ahead_of_rear_axle_m, config::Range{0.0, 10.0});
    a.Optional("com_height_m", com_height_m, config::Range{0.0, 10.0});
    a.Optional("yaw_inertia_kgm2", yaw_inertia_kgm2, config::Range{1e-6, 1e5});
    a.Optional("suspension_frequency_hz", suspension_frequency_hz, config::Range{0.5, 100.0});
    a.Optional("suspension_damping_ratio", suspension_damping_ratio, config::Range{0.0, 5.0});
    a.Optional("friction_coefficient", friction_coefficient, config::Range{0.01, 5.0});
    a.Optional("cornering_stiffness_n_per_rad", cornering_stiffness_n_per_rad,
               config::Range{0.01, 1e6});
    a.Optional("longitudinal_stiffness_n", longitudinal_stiffness_n, config::Range{0.01, 1e6});
    a.Optional("longitudinal", longitudinal);
    a.Optional("lateral", lateral);
    a.Optional("slip_speed_guard_mps", slip_speed_guard_mps, config::Range{1e-5, 1.0});
    a.Optional("drive", drive);
    a.Optional("top_speed_mps", top_speed_mps, config::Range{0.01, 100.0});
    a.Optional("reverse_top_speed_mps", reverse_top_speed_mps, config::Range{0.0, 100.0});
    a.Optional("drive_torque_nm", drive_torque_nm, config::Range{1e-4, 1e4});
    a.Optional("brake_torque_nm", brake_torque_nm, config::Range{0.0, 1e4});
    a.Optional("rolling_resistance_nms", rolling_resistance_nms, config::Range{0.0, 1.0});
    a.Optional("steering_limit_rad", steering_limit_rad, config::Range{0.01, 1.2});
    a.Optional("steering_rate_radps", steering_rate_radps, config::Range{0.01, 100.0});
    a.Optional("steering_torque_nm", steering_torque_nm, config::Range{1e-4, 1e4});
    a.Optional("encoder_counts_per_rev", encoder_counts_per_rev, config::Range{1, 1 << 20});
  }
  /// Cross-field rules: the centre of mass between the axles, the wheels lighter than the car,
  /// the clearance below the axle, the tyre curves well formed with the slopes derived from
  /// the stiffnesses, the inner wheel's Ackermann angle below 90 degrees.
  void Validate() const;
  bool operator==(const VehicleParams&) const = default;

  /// Static load of one front / one rear wheel on flat ground (N).
  [[nodiscard]] double FrontWheelLoadN(double gravity_mps2) const;
  [[nodiscard]] double RearWheelLoadN(double gravity_mps2) const;
  /// The tyre curves with `initial_slope` filled in from the stiffnesses at each axle's static
  /// load, where it was left 0: {front longitudinal, front lateral, rear longitudinal, rear
  /// lateral}.
  [[nodiscard]] std::array<TyreCurve, 4> ResolvedTyres(double gravity_mps2) const;
};

/// Per-wheel steering angles (rad, positive left) of Ackermann steering for the equivalent
/// single-wheel angle `delta_rad` (the paper's formula, in the right-handed frame where
/// positive is a left turn, so the left wheel is the inner one): left = atan(2 l tan d /
/// (2 l - w tan d)), right = atan(2 l tan d / (2 l + w tan d)). At d = 30 degrees with Nigel's
/// l and w: 40.0 degrees inner, 23.8 degrees outer. Returns {left, right}.
[[nodiscard]] std::array<double, 2> AckermannAngles(double delta_rad, double wheelbase_m,
                                                    double track_width_m);

}  // namespace autodrive::vehicle_sim
