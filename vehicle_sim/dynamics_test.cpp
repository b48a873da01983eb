// Validation of Nigel's dynamics against the paper's figures (issue 9's acceptance list).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <numbers>
#include <vector>

#include "common/error.h"
#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/layout.h"
#include "maps/map.h"
#include "vehicle_sim/raycast.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr double kDeg = std::numbers::pi / 180;

Duration Secs(double s) { return FromSeconds(s); }

// Runs `command` on vehicle 0 for `duration`, calling `each(state)` after every step.
template <typename F>
void Drive(World& world, const VehicleCommand& command, Duration duration, F&& each) {
  world.SetCommand(0, command);
  const Duration end = world.time() + duration;
  while (world.time() < end) {
    world.Step();
    each(world.State(0));
  }
}
void Drive(World& world, const VehicleCommand& command, Duration duration) {
  Drive(world, command, duration, [](const VehicleState&) {});
}

double Speed(const VehicleState& s) { return s.v_V_mps.head<2>().norm(); }

// Least-squares circle through points (Kasa's fit): returns the radius.
double CircleRadius(const std::vector<Eigen::Vector2d>& points) {
  Eigen::MatrixXd A(static_cast<Eigen::Index>(points.size()), 3);
  Eigen::VectorXd b(static_cast<Eigen::Index>(points.size()));
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    A(r, 0) = points[i].x();
    A(r, 1) = points[i].y();
    A(r, 2) = 1;
    b(r) = points[i].squaredNorm();
  }
  const Eigen::Vector3d c = A.colPivHouseholderQr().solve(b);
  const Eigen::Vector2d centre(c(0) / 2, c(1) / 2);
  return std::sqrt(c(2) + centre.squaredNorm());
}

TEST(Dynamics, AtRestOnFlatGroundTheCarSitsStillOnItsWheels) {
  World world;
  world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(1, 2, 0.3));
  Drive(world, {}, seconds(2));
  const VehicleState& s = world.State(0);
  EXPECT_NEAR(s.X_MV.translation().x(), 1, 1e-4);
  EXPECT_NEAR(s.X_MV.translation().y(), 2, 1e-4);
  EXPECT_NEAR(s.X_MV.translation().z(), 0, 1e-3);  // the springs settled at their sag
  EXPECT_NEAR(s.X_MV.yaw(), 0.3, 1e-4);
  EXPECT_LT(s.v_V_mps.norm(), 1e-4);
  EXPECT_LT(s.w_V_radps.norm(), 1e-4);
  EXPECT_LT(s.a_V_mps2.norm(), 1e-2);
  double total = 0;
  for (const WheelState& w : s.wheels) total += w.normal_force_n;
  EXPECT_NEAR(total, 2.68 * 9.81, 0.01 * 2.68 * 9.81);
  // The front carries more: the centre of mass is 0.0623 m behind the front axle of 0.1415.
  EXPECT_NEAR(s.wheels[0].normal_force_n, VehicleParams{}.FrontWheelLoadN(9.81), 0.05);
  EXPECT_NEAR(s.wheels[2].normal_force_n, VehicleParams{}.RearWheelLoadN(9.81), 0.05);
}

TEST(Dynamics, FullThrottleOnFlatGroundSettlesWithinTenPercentOfTopSpeed) {
  World world;
  world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 0, 0));
  Drive(world, {1.0, 0.0}, seconds(3));
  const VehicleState& s = world.State(0);
  std::printf("full throttle: %.4f m/s after 3 s (goal 0.26 +- 10%%)\n", s.v_V_mps.x());
  EXPECT_NEAR(s.v_V_mps.x(), 0.26, 0.026);
  EXPECT_GT(s.X_MV.translation().x(), 0.5);
  EXPECT_NEAR(s.X_MV.translation().y(), 0, 1e-3);  // straight
  // Reverse: its own top speed.
  Drive(world, {-1.0, 0.0}, seconds(3));
  std::printf("full reverse: %.4f m/s (goal -0.23)\n", world.State(0).v_V_mps.x());
  EXPECT_NEAR(world.State(0).v_V_mps.x(), -0.23, 0.023);
}

TEST(Dynamics, AtFullLockAndLowSpeedTheTurningRadiusIsTheAckermannGeometrys) {
  const VehicleParams p;
  for (double steering : {1.0, -1.0}) {
    World world;
    world.AddVehicle(p, RigidTransform2::FromXyYaw(0, 0, 0));
    Drive(world, {0.3, steering}, seconds(3));  // settle into the circle
    std::vector<Eigen::Vector2d> points;
    double yaw_rate = 0;
    Drive(world, {0.3, steering}, seconds(10), [&](const VehicleState& s) {
      points.push_back(s.X_MV.translation().head<2>());
      yaw_rate = s.w_V_radps.z();
    });
    const double expected = p.wheelbase_m / std::tan(p.steering_limit_rad);  // 0.2452 m
    const double radius = CircleRadius(points);
    std::printf("full lock %+.0f: radius %.4f m at the rear axle (Ackermann %.4f)\n", steering,
                radius, expected);
    EXPECT_NEAR(radius, expected, 0.05 * expected);
    EXPECT_GT(yaw_rate * steering, 0);  // positive steering turns left
  }
}

TEST(Dynamics, TheSimulatedFrontWheelsTakeTheAckermannAnglesAtFullLock) {
  World world;
  world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 0, 0));
  Drive(world, {0.0, 1.0}, milliseconds(500));
  const VehicleState& s = world.State(0);
  std::printf("full lock left: wheels %.3f / %.3f deg\n", s.wheels[0].steer_rad / kDeg,
              s.wheels[1].steer_rad / kDeg);
  EXPECT_NEAR(s.wheels[0].steer_rad / kDeg, 40.0, 0.1);
  EXPECT_NEAR(s.wheels[1].steer_rad / kDeg, 23.8, 0.1);
  Drive(world, {0.0, -1.0}, milliseconds(500));
  EXPECT_NEAR(world.State(0).wheels[0].steer_rad / kDeg, -23.8, 0.1);
  EXPECT_NEAR(world.State(0).wheels[1].steer_rad / kDeg, -40.0, 0.1);
}

TEST(Dynamics, SteeringSlewsAtItsConfiguredRate) {
  for (double rate : {5.5118, 0.42}) {
    VehicleParams p;
    p.steering_rate_radps = rate;
    World world;
    world.AddVehicle(p, RigidTransform2::FromXyYaw(0, 0, 0));
    // Time for the actuator, and for the wheels, to go from straight to full lock.
    double actuator_at = -1;
    double wheels_at = -1;
    const double full = AckermannAngles(p.steering_limit_rad, p.wheelbase_m, p.track_width_m)[0];
    Drive(world, {0.0, 1.0}, Secs(2 + p.steering_limit_rad / rate), [&](const VehicleState& s) {
      const double t = ToSeconds(world.time());
      if (actuator_at < 0 && s.steering_rad >= p.steering_limit_rad - 1e-12) actuator_at = t;
      if (wheels_at < 0 && s.wheels[0].steer_rad >= full - 0.1 * kDeg) wheels_at = t;
    });
    const double expected = p.steering_limit_rad / rate;
    std::printf(
        "steering at %.4f rad/s: actuator at full lock after %.4f s, wheels %.4f s "
        "(expected %.4f s)\n",
        rate, actuator_at, wheels_at, expected);
    EXPECT_NEAR(actuator_at, expected, 0.0021);  // within a step
    EXPECT_NEAR(wheels_at, expected, 0.01);
  }
}

TEST(Dynamics, EncodersCount1920TicksPerRevolutionOfTheRearWheels) {
  const VehicleParams p;
  World world;
  world.AddVehicle(p, RigidTransform2::FromXyYaw(0, 0, 0));
  // Drive until the rear left wheel has turned exactly five revolutions.
  world.SetCommand(0, {0.2, 0.0});
  std::int64_t ticks_before = 0;
  while (world.State(0).wheels[2].spin_angle_rad < 10 * std::numbers::pi) {
    ticks_before = world.State(0).encoder_ticks[0];
    world.Step();
  }
  const VehicleState& s = world.State(0);
  EXPECT_LT(ticks_before, 5 * 1920);
  EXPECT_GE(s.encoder_ticks[0], 5 * 1920);
  // Rolling without slip at low speed: five revolutions move the car 5 x 2 pi r.
  const double distance = s.X_MV.translation().x();
  std::printf("5 revolutions: %lld ticks, %.4f m travelled (5 x 2 pi r = %.4f m)\n",
              static_cast<long long>(s.encoder_ticks[0]), distance,
              10 * std::numbers::pi * p.wheel_radius_m);
  EXPECT_NEAR(distance, 10 * std::numbers::pi * p.wheel_radius_m, 0.01 * distance);
  EXPECT_NEAR(static_cast<double>(s.encoder_ticks[1]), static_cast<double>(s.encoder_ticks[0]),
              5);  // straight: both rear wheels alike
}

// A kinematic bicycle about the rear axle, driven by the simulator's own speed and steering
// actuator: x' = v cos th, y' = v sin th, th' = v tan(d) / L.
TEST(Dynamics, AtLowSpeedTheTrajectoryFollowsTheKinematicBicycleOverATwoMetreSCurve) {
  const VehicleParams p;
  World world;
  world.AddVehicle(p, RigidTransform2::FromXyYaw(0, 0, 0));
  Drive(world, {0.4, 0.0}, seconds(1));  // up to speed
  Eigen::Vector3d bike(world.State(0).X_MV.translation().x(), world.State(0).X_MV.translation().y(),
                       world.State(0).X_MV.yaw());
  const Eigen::Vector2d start = bike.head<2>();
  double travelled = 0;
  double worst = 0;
  const double h = ToSeconds(world.options().step);
  while (travelled < 2.0) {
    // An S: steer left, then right, then left, as a sine over the 2 m.
    const double steering = 0.8 * std::sin(2 * std::numbers::pi * travelled / 1.4);
    world.SetCommand(0, {0.4, steering});
    const VehicleState before = world.State(0);
    world.Step();
    const VehicleState& s = world.State(0);
    const double v = 0.5 * (before.v_V_mps.x() + s.v_V_mps.x());
    const double d = 0.5 * (before.steering_rad + s.steering_rad);
    const double th_mid = bike.z() + 0.5 * h * v * std::tan(d) / p.wheelbase_m;
    bike.x() += h * v * std::cos(th_mid);
    bike.y() += h * v * std::sin(th_mid);
    bike.z() += h * v * std::tan(d) / p.wheelbase_m;
    travelled += h * std::abs(v);
    worst = std::max(worst, (s.X_MV.translation().head<2>() - bike.head<2>()).norm());
  }
  std::printf(
      "S-curve of %.2f m (%.2f m from the start): largest gap to the kinematic "
      "bicycle %.4f m\n",
      travelled, (bike.head<2>() - start).norm(), worst);
  EXPECT_LT(worst, 0.02);
}

TEST(Dynamics, AtHigherSpeedAndLateralAccelerationTheCarUndersteers) {
  // A faster Nigel (top speed 1.5 m/s) at a fixed steering angle: the steady radius grows
  // above the kinematic L / tan(d) with the lateral acceleration a_y, as the linear slip model
  // predicts: d = L / R + K a_y with the understeer gradient K = (m_f - m_r) / (2 C), m_f and
  // m_r the masses on each axle and C a tyre's cornering stiffness. The centre of mass nearer
  // the front axle (0.0623 vs 0.0793 m) makes K positive: understeer.
  VehicleParams p;
  p.top_speed_mps = 1.5;
  const double steering = 0.5;  // of 30 degrees
  const double delta = steering * p.steering_limit_rad;
  const double kinematic = p.wheelbase_m / std::tan(delta);
  const double front_share = p.com_ahead_of_rear_axle_m / p.wheelbase_m;
  const double gradient =
      p.mass_kg * (2 * front_share - 1) / (2 * p.cornering_stiffness_n_per_rad);  // rad/(m/s^2)
  std::vector<double> radii;
  for (double throttle : {0.1, 0.4, 0.7}) {
    World world;
    world.AddVehicle(p, RigidTransform2::FromXyYaw(0, 0, 0));
    Drive(world, {throttle, steering}, seconds(4));
    std::vector<Eigen::Vector2d> points;
    double speed = 0;
    Drive(world, {throttle, steering}, seconds(4), [&](const VehicleState& s) {
      points.push_back(s.X_MV.translation().head<2>());
      speed = Speed(s);
    });
    const double radius = CircleRadius(points);
    const double a_y = speed * speed / radius;
    const double predicted = p.wheelbase_m / std::tan(delta - gradient * a_y);
    std::printf(
        "steering 15 deg, %.3f m/s: radius %.4f m, %.1f%% wider than kinematic %.4f m; "
        "a_y %.3f m/s^2; linear understeer model (K = %.4f rad per m/s^2) predicts "
        "%.4f m, %.1f%% wider\n",
        speed, radius, 100 * (radius / kinematic - 1), kinematic, a_y, gradient, predicted,
        100 * (predicted / kinematic - 1));
    radii.push_back(radius);
    if (throttle > 0.1) {
      EXPECT_NEAR(radius - kinematic, predicted - kinematic, 0.3 * (predicted - kinematic));
    }
  }
  EXPECT_NEAR(radii[0], kinematic, 0.01 * kinematic);  // slow: kinematic
  EXPECT_GT(radii[1], radii[0]);
  EXPECT_GT(radii[2], radii[1]);
  EXPECT_GT(radii[2], 1.03 * kinematic);  // fast: clearly wider
}

TEST(Dynamics, TwoRunsWithTheSameCommandsAreBitIdentical) {
  const auto run = [] {
    World world;
    world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 0, 0));
    world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0.6, 0.05, std::numbers::pi));
    std::vector<double> log;
    for (int i = 0; i < 2000; ++i) {
      world.SetCommand(0, {1.0, std::sin(i * 0.01)});
      world.SetCommand(1, {1.0, -0.3});
      world.Step();
      for (int v = 0; v < 2; ++v) {
        const VehicleState& s = world.State(v);
        log.insert(log.end(),
                   {s.X_MV.translation().x(), s.X_MV.translation().y(), s.X_MV.translation().z(),
                    s.X_MV.yaw(), s.v_V_mps.x(), s.w_V_radps.z(), s.wheels[2].spin_angle_rad});
      }
    }
    return log;
  };
  const std::vector<double> a = run();
  const std::vector<double> b = run();
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(double)), 0);
}

// A diverged state is reported with the vehicle, the step and the quantity before ODE sees it
// (ODE aborts the process on a state that overflows inside its step), and the world stays
// failed.
TEST(Dynamics, ADivergedStateIsReportedWithTheVehicleTheStepAndTheQuantity) {
  World world;
  world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 0, 0));
  world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 1, 0));
  for (int i = 0; i < 10; ++i) world.Step();
  world.SetVelocity(1, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 1e300));
  std::string message;
  try {
    world.Step();
  } catch (const NumericalError& e) {
    message = e.what();
  }
  std::printf("%s\n", message.c_str());
  EXPECT_EQ(message,
            "vehicle 1: chassis angular velocity (1e+300 rad/s) is beyond any plausible value "
            "before step 11 (t = 0.02 s)");
  EXPECT_THROW(world.Step(), NumericalError) << "a failed world is not stepped further";
  EXPECT_EQ(world.steps(), 10);
  EXPECT_THROW(world.SetVelocity(0, Eigen::Vector3d(NAN, 0, 0), Eigen::Vector3d::Zero()),
               InputError);
}

TEST(Dynamics, ACarSetGoingAtTopSpeedCoastsAndIsStoppedByItsBrake) {
  World world;
  world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 0, 0));
  for (int i = 0; i < 100; ++i) world.Step();
  world.SetVelocity(0, Eigen::Vector3d(0.26, 0, 0), Eigen::Vector3d::Zero());
  world.Step();
  EXPECT_NEAR(world.State(0).v_V_mps.x(), 0.26, 0.03);
  world.StepUntil(world.time() + std::chrono::seconds(3));
  EXPECT_LT(std::abs(world.State(0).v_V_mps.x()), 0.005) << "zero throttle holds the car";
  EXPECT_GT(world.State(0).X_MV.translation().x(), 0.0);
}

TEST(Dynamics, ACarAtTopSpeedStopsAtAWallWithoutPassingThroughIt) {
  World world;
  const double wall_x = 1.0;  // near face of a 2 cm wall
  world.AddStaticBox({RigidTransform2::FromXyYaw(wall_x + 0.01, 0, 0), {0.02, 1.0, 0.2}});
  world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 0, 0));
  double furthest_front = 0;
  const VehicleParams p;
  const double front_overhang = p.body_centre_ahead_of_rear_axle_m + p.body_length_m / 2;
  Drive(world, {1.0, 0.0}, seconds(8), [&](const VehicleState& s) {
    furthest_front = std::max(furthest_front, s.X_MV.translation().x() + front_overhang);
  });
  const VehicleState& s = world.State(0);
  std::printf("wall at x = %.3f m: front of the car reached %.4f m, now at %.4f m/s\n", wall_x,
              furthest_front, s.v_V_mps.x());
  EXPECT_LT(furthest_front, wall_x + 0.005);  // contact, at most a few mm of penetration
  EXPECT_GT(furthest_front, wall_x - 0.01);   // it did reach the wall
  EXPECT_LT(std::abs(s.v_V_mps.x()), 0.02);   // pushing against it, not through it
}

TEST(Dynamics, ATimedBoxStopsTheCarAndIsSeenOnlyWhileItStands) {
  World world;
  const double wall_x = 1.0;  // near face of a 2 cm wall, placed at 1 s, removed at 6 s
  world.AddTimedBox({{RigidTransform2::FromXyYaw(wall_x + 0.01, 0, 0), {0.02, 1.0, 0.2}},
                     seconds(1),
                     seconds(6)});
  ASSERT_EQ(world.TimedBoxes().size(), 1u);
  world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 0, 0));
  const auto seen = [&] {
    const Hit h = Cast(world.Scene(), {}, Ray{{0.5, 0, 0.1}, {1, 0, 0}}, 5.0);
    return h.what == Hit::What::kStatic;
  };
  EXPECT_FALSE(seen()) << "not yet placed";
  world.StepUntil(seconds(1) - milliseconds(2));
  EXPECT_FALSE(seen());
  world.Step();
  EXPECT_TRUE(seen()) << "placed at 1 s";
  // The car drives into it and is held there while it stands.
  const VehicleParams p;
  const double front_overhang = p.body_centre_ahead_of_rear_axle_m + p.body_length_m / 2;
  double furthest_front = 0;
  Drive(world, {1.0, 0.0}, seconds(4), [&](const VehicleState& s) {
    furthest_front = std::max(furthest_front, s.X_MV.translation().x() + front_overhang);
  });
  EXPECT_LT(furthest_front, wall_x + 0.005);
  EXPECT_GT(furthest_front, wall_x - 0.01);
  EXPECT_TRUE(seen());
  world.StepUntil(seconds(6));
  EXPECT_FALSE(seen()) << "removed at 6 s";
  // Removed: the car drives on through where it stood.
  Drive(world, {1.0, 0.0}, seconds(3));
  EXPECT_GT(world.State(0).X_MV.translation().x(), wall_x + 0.1);
  EXPECT_THROW(
      world.AddTimedBox(
          {{RigidTransform2::FromXyYaw(3, 0, 0), {0.1, 0.1, 0.1}}, seconds(2), seconds(2)}),
      InputError);
  // A box due where the car is cannot be put there: the step that would place it says so.
  const double x = world.State(0).X_MV.translation().x();
  world.AddTimedBox({{RigidTransform2::FromXyYaw(x, 0, 0), {0.1, 0.1, 0.1}},
                     world.time() + milliseconds(10),
                     std::nullopt});
  world.StepUntil(world.time() + milliseconds(8));
  try {
    world.Step();
    ADD_FAILURE() << "a box placed onto the car";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("would stand where vehicle 0's body is"),
              std::string::npos)
        << e.what();
  }
}

TEST(Dynamics, ACarDrivingIntoAStandingOnePushesItWithoutPassingThroughIt) {
  World world;
  world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 0, 0));
  world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(1.2, 0, std::numbers::pi));
  world.SetCommand(1, {0.0, 0.0});
  // Car 0 drives into car 1, which stands braked; then car 0 lets go.
  bool touched = false;
  Drive(world, {1.0, 0.0}, seconds(6), [&](const VehicleState&) {
    touched = touched || world.State(1).X_MV.translation().x() > 1.2 + 1e-3;
  });
  const double gap = world.State(1).X_MV.translation().x() - world.State(0).X_MV.translation().x();
  std::printf("after the crash: rear axles %.4f m apart, car 1 pushed %.4f m\n", gap,
              world.State(1).X_MV.translation().x() - 1.2);
  EXPECT_TRUE(touched);  // car 1 was pushed
  const VehicleParams p;
  // The bodies do not pass through each other: the fronts (0.2297 m ahead of each rear axle)
  // meet.
  EXPECT_GT(gap, 2 * (p.body_centre_ahead_of_rear_axle_m + p.body_length_m / 2) - 0.01);
}

TEST(Dynamics, FromTopSpeedZeroThrottleStopsTheCarAndHoldsItOnTheSteepestShippedRamp) {
  // The steepest ramp of the shipped maps.
  double steepest = 0;
  maps::Map steepest_map;
  maps::TileIndex ramp;
  int rotation = 0;
  for (const char* name : {"parking_school", "driving_school", "small_town"}) {
    const maps::Map m = maps::Build(maps::LoadLayout(
        (test::SourceDir() / "config" / "maps" / (std::string(name) + ".yaml")).string()));
    for (int r = 0; r < m.rows; ++r) {
      for (int c = 0; c < m.cols; ++c) {
        const std::size_t k = static_cast<std::size_t>(r * m.cols + c);
        const double slope = m.terrain.tile_rise_m[k] / m.tile_size_m;
        if (slope > steepest) {
          steepest = slope;
          steepest_map = m;
          ramp = {r, c};
          rotation = m.terrain.tile_rotation_deg[k];
        }
      }
    }
  }
  ASSERT_GT(steepest, 0) << "no shipped map has a ramp";
  World world(steepest_map);
  // Face down the ramp (it rises along its local +x), start above it and drive down at full
  // throttle, then let go on the ramp.
  const double uphill = rotation * kDeg;
  const Eigen::Vector2d centre = steepest_map.TileCentre(ramp);
  const Eigen::Vector2d up_dir(std::cos(uphill), std::sin(uphill));
  const Eigen::Vector2d start = centre + 0.35 * steepest_map.tile_size_m * up_dir;
  world.AddVehicle(VehicleParams{}, RigidTransform2(start, uphill + std::numbers::pi));
  Drive(world, {1.0, 0.0}, seconds(2));
  const double speed_before = world.State(0).v_V_mps.x();
  Drive(world, {0.0, 0.0}, seconds(1));
  const Eigen::Vector3d stopped = world.State(0).X_MV.translation();
  Drive(world, {0.0, 0.0}, seconds(10));
  const Eigen::Vector3d later = world.State(0).X_MV.translation();
  std::printf(
      "ramp %.1f%% (%s %s): %.3f m/s, stopped on the ramp at z = %.4f m; moved "
      "%.2e m in the next 10 s\n",
      100 * steepest, steepest_map.name.c_str(), ramp.Name().c_str(), speed_before, stopped.z(),
      (later - stopped).norm());
  EXPECT_GT(speed_before, 0.2);
  EXPECT_GT(stopped.z(), 1e-3);  // still on the ramp, above its foot
  EXPECT_LT(std::abs(world.State(0).v_V_mps.x()), 1e-3);
  EXPECT_LT((later - stopped).norm(), 1e-3);
}

}  // namespace
}  // namespace autodrive::vehicle_sim
