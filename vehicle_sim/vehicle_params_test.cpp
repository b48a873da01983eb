#include "vehicle_sim/vehicle_params.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "common/config.h"
#include "common/test_support.h"

namespace autodrive::vehicle_sim {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

TEST(AckermannAngles, AtThirtyDegreesMatchThePapersFormulaWithTheInnerWheelOnTheInside) {
  const VehicleParams p;
  // The paper's formula (Unity's frame: positive steers right, so its delta_l is the outer
  // wheel): outer = atan(2 l tan d / (2 l + w tan d)), inner = atan(2 l tan d / (2 l - w tan d)).
  const double t = std::tan(30 * kDeg);
  const double l = p.wheelbase_m;
  const double w = p.track_width_m;
  const double outer = std::atan(2 * l * t / (2 * l + w * t));
  const double inner = std::atan(2 * l * t / (2 * l - w * t));
  EXPECT_NEAR(inner / kDeg, 40.0, 0.05);
  EXPECT_NEAR(outer / kDeg, 23.8, 0.05);
  const auto left_turn = AckermannAngles(30 * kDeg, l, w);
  EXPECT_NEAR(left_turn[0], inner, 0.1 * kDeg);  // left wheel inside a left turn
  EXPECT_NEAR(left_turn[1], outer, 0.1 * kDeg);
  const auto right_turn = AckermannAngles(-30 * kDeg, l, w);
  EXPECT_NEAR(right_turn[0], -outer, 0.1 * kDeg);
  EXPECT_NEAR(right_turn[1], -inner, 0.1 * kDeg);
  const auto straight = AckermannAngles(0.0, l, w);
  EXPECT_EQ(straight[0], 0.0);
  EXPECT_EQ(straight[1], 0.0);
}

TEST(AckermannAngles, BothWheelsTurnAboutOnePointOnTheRearAxle) {
  const VehicleParams p;
  for (double d : {0.05, 0.2, 0.5236, -0.3}) {
    const auto a = AckermannAngles(d, p.wheelbase_m, p.track_width_m);
    const double radius = p.wheelbase_m / std::tan(d);  // to the centreline, signed
    // Each wheel's axle line passes through (0, radius) in V.
    EXPECT_NEAR(p.wheelbase_m / std::tan(a[0]) + p.track_width_m / 2, radius, 1e-12);
    EXPECT_NEAR(p.wheelbase_m / std::tan(a[1]) - p.track_width_m / 2, radius, 1e-12);
  }
}

TEST(TyreCurve, RisesToItsExtremumThenFallsToItsAsymptoteContinuouslyAndOddly) {
  TyreCurve c{0.2, 1.0, 0.5, 0.75, 7.0};
  EXPECT_EQ(c.Value(0.0), 0.0);
  EXPECT_NEAR(c.Value(0.2), 1.0, 1e-12);
  EXPECT_NEAR(c.Value(0.5), 0.75, 1e-12);
  EXPECT_EQ(c.Value(3.0), 0.75);
  EXPECT_NEAR(c.Value(-0.2), -1.0, 1e-12);
  // Slope at the origin is the initial slope; the secant tends to it.
  EXPECT_NEAR(c.Value(1e-7) / 1e-7, 7.0, 1e-5);
  EXPECT_EQ(c.Secant(0.0), 7.0);
  // Monotonic up to the extremum, then down to the asymptote, and continuous everywhere.
  double last = 0.0;
  for (double s = 1e-4; s <= 0.2; s += 1e-4) {
    EXPECT_GE(c.Value(s), last - 1e-12) << s;
    last = c.Value(s);
  }
  for (double s = 0.2; s <= 0.5; s += 1e-4) {
    EXPECT_LE(c.Value(s), last + 1e-12) << s;
    EXPECT_LE(std::abs(c.Value(s) - last), 1e-3) << s;
    last = c.Value(s);
  }
  EXPECT_NEAR(c.Value(0.5 + 1e-9), c.Value(0.5 - 1e-9), 1e-8);
}

TEST(TyreCurve, AnOvershootingFirstPieceIsRefusedNamingTheLimit) {
  TyreCurve c{0.2, 1.0, 0.5, 0.75, 16.0};
  const std::string message = test::ErrorMessage([&] { c.Validate(); });
  EXPECT_NE(message.find("initial_slope 16"), std::string::npos) << message;
  EXPECT_NE(message.find("at most 15"), std::string::npos) << message;
}

TEST(VehicleParams, NigelsDefaultsAreValidAndGiveTheMeasuredCorneringStiffness) {
  const VehicleParams p;
  EXPECT_NO_THROW(p.Validate());
  EXPECT_NEAR(p.wheelbase_m - p.com_ahead_of_rear_axle_m, 0.0623, 1e-4);  // sys-ID, from front
  const auto tyres = p.ResolvedTyres(9.81);
  // Slope at zero slip times mu N is the cornering stiffness, front and rear.
  EXPECT_NEAR(tyres[1].initial_slope * p.friction_coefficient * p.FrontWheelLoadN(9.81), 22.48,
              1e-9);
  EXPECT_NEAR(tyres[3].initial_slope * p.friction_coefficient * p.RearWheelLoadN(9.81), 22.48,
              1e-9);
  EXPECT_NEAR(2 * (p.FrontWheelLoadN(9.81) + p.RearWheelLoadN(9.81)), 2.68 * 9.81, 1e-9);
}

TEST(VehicleParams, RoundTripsThroughYamlAndRefusesUnknownKeysAndBadValues) {
  VehicleParams p;
  p.drive = DriveLayout::kAll;
  p.track_width_m = 0.14724;
  p.lateral.extremum_slip = 0.25;
  EXPECT_EQ(config::LoadString<VehicleParams>(config::SaveString(p)), p);
  const std::string unknown =
      test::ErrorMessage([] { (void)config::LoadString<VehicleParams>("wheel_base_m: 0.2\n"); });
  EXPECT_NE(unknown.find("wheel_base_m"), std::string::npos) << unknown;
  const std::string com = test::ErrorMessage(
      [] { (void)config::LoadString<VehicleParams>("com_ahead_of_rear_axle_m: 0.2\n"); });
  EXPECT_NE(com.find("between the axles"), std::string::npos) << com;
  const std::string drive =
      test::ErrorMessage([] { (void)config::LoadString<VehicleParams>("drive: four\n"); });
  EXPECT_NE(drive.find("rear"), std::string::npos) << drive;
}

}  // namespace
}  // namespace autodrive::vehicle_sim
