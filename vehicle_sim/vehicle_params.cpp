#include "vehicle_sim/vehicle_params.h"

#include <cmath>

#include "common/error.h"

namespace autodrive::vehicle_sim {

namespace {

// Cubic Hermite on [0, 1] from p0 (slope m0 * h) to p1 (slope m1 * h), h the interval length.
double Hermite(double t, double p0, double m0, double p1, double m1, double h) {
  const double t2 = t * t;
  const double t3 = t2 * t;
  return (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + t) * h * m0 + (-2 * t3 + 3 * t2) * p1 +
         (t3 - t2) * h * m1;
}

}  // namespace

double TyreCurve::Value(double slip) const {
  const double s = std::abs(slip);
  double v = 0.0;
  if (s <= extremum_slip) {
    v = Hermite(s / extremum_slip, 0.0, initial_slope, extremum_value, 0.0, extremum_slip);
  } else if (s < asymptote_slip) {
    v = Hermite((s - extremum_slip) / (asymptote_slip - extremum_slip), extremum_value, 0.0,
                asymptote_value, 0.0, asymptote_slip - extremum_slip);
  } else {
    v = asymptote_value;
  }
  return std::copysign(v, slip);
}

double TyreCurve::Secant(double slip) const {
  const double s = std::abs(slip);
  if (s < 1e-9 * extremum_slip) return initial_slope;
  return Value(s) / s;
}

void TyreCurve::Validate() const {
  AUTODRIVE_THROW_UNLESS(extremum_slip > 0 && extremum_slip < asymptote_slip,
                         "the slips must grow: 0 < extremum_slip < asymptote_slip, got "
                             << extremum_slip << " and " << asymptote_slip);
  AUTODRIVE_THROW_UNLESS(
      extremum_value > 0 && extremum_value <= 1 && asymptote_value > 0 && asymptote_value <= 1,
      "values are fractions of mu N in (0, 1], got extremum_value "
          << extremum_value << ", asymptote_value " << asymptote_value);
  AUTODRIVE_THROW_UNLESS(initial_slope * extremum_slip <= 3 * extremum_value + 1e-12,
                         "initial_slope " << initial_slope << " overshoots the extremum: at most "
                                          << 3 * extremum_value / extremum_slip
                                          << " (3 extremum_value / extremum_slip)");
}

double VehicleParams::FrontWheelLoadN(double gravity_mps2) const {
  return mass_kg * gravity_mps2 * (com_ahead_of_rear_axle_m / wheelbase_m) / 2;
}

double VehicleParams::RearWheelLoadN(double gravity_mps2) const {
  return mass_kg * gravity_mps2 * (1 - com_ahead_of_rear_axle_m / wheelbase_m) / 2;
}

std::array<TyreCurve, 4> VehicleParams::ResolvedTyres(double gravity_mps2) const {
  const auto resolve = [&](TyreCurve curve, double stiffness, double load_n) {
    if (curve.initial_slope == 0.0) {
      curve.initial_slope = stiffness / (friction_coefficient * load_n);
    }
    return curve;
  };
  const double front = FrontWheelLoadN(gravity_mps2);
  const double rear = RearWheelLoadN(gravity_mps2);
  return {resolve(longitudinal, longitudinal_stiffness_n, front),
          resolve(lateral, cornering_stiffness_n_per_rad, front),
          resolve(longitudinal, longitudinal_stiffness_n, rear),
          resolve(lateral, cornering_stiffness_n_per_rad, rear)};
}

void VehicleParams::Validate() const {
  AUTODRIVE_THROW_UNLESS(com_ahead_of_rear_axle_m > 0 && com_ahead_of_rear_axle_m < wheelbase_m,
                         "com_ahead_of_rear_axle_m " << com_ahead_of_rear_axle_m
                                                     << " must lie between the axles (0, "
                                                     << wheelbase_m << ")");
  AUTODRIVE_THROW_UNLESS(4 * wheel_mass_kg < 0.9 * mass_kg, "four wheels of wheel_mass_kg "
                                                                << wheel_mass_kg
                                                                << " leave too little of mass_kg "
                                                                << mass_kg << " for the chassis");
  AUTODRIVE_THROW_UNLESS(body_clearance_m < wheel_radius_m,
                         "body_clearance_m " << body_clearance_m
                                             << " must be below the axle (wheel_radius_m "
                                             << wheel_radius_m << ")");
  AUTODRIVE_THROW_UNLESS(
      body_height_m > body_clearance_m,
      "body_height_m " << body_height_m << " must exceed body_clearance_m " << body_clearance_m);
  AUTODRIVE_THROW_UNLESS(com_height_m > body_clearance_m && com_height_m < body_height_m,
                         "com_height_m " << com_height_m << " must lie inside the body ("
                                         << body_clearance_m << ", " << body_height_m << ")");
  AUTODRIVE_THROW_UNLESS(track_width_m * std::tan(steering_limit_rad) < 2 * wheelbase_m,
                         "steering_limit_rad "
                             << steering_limit_rad
                             << " turns the inner wheel past 90 degrees for this track and "
                                "wheelbase");
  for (const TyreCurve& curve : ResolvedTyres(9.81)) curve.Validate();
}

std::array<double, 2> AckermannAngles(double delta_rad, double wheelbase_m, double track_width_m) {
  const double t = std::tan(delta_rad);
  const double l2 = 2 * wheelbase_m;
  const double wt = track_width_m * t;
  return {std::atan(l2 * t / (l2 - wt)), std::atan(l2 * t / (l2 + wt))};
}

}  // namespace autodrive::vehicle_sim
