#include "vehicle_sim/sensors.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "vehicle_sim/sim_config.h"
#include "vehicle_sim/variability.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr double kLidarX = 0.1445;  // NIGEL.md: ahead of the rear axle

// A world on flat ground with car 0 at the origin facing +x, and the scene its LIDAR sees.
struct Bench {
  World world;
  std::vector<DynamicBox> boxes;
  std::optional<StaticScene> scene;
  std::vector<SensorSuite> suites;
  SensorReadings readings;

  explicit Bench(const SensorConfig& config = {}, std::uint64_t seed = 1) {
    world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 0, 0));
    suites.emplace_back(config, 0, seed);
  }
  void AddCar(const RigidTransform2& pose, const SensorConfig& config = {}) {
    const int index = world.AddVehicle(VehicleParams{}, pose);
    suites.emplace_back(config, index, 1);
  }
  // Steps until car 0 produced a complete LIDAR scan (at most `limit`); returns it.
  LidarScan NextScan(Duration limit = seconds(2)) {
    const Duration end = world.time() + limit;
    while (world.time() < end) {
      Step();
      if (readings.lidar) return *readings.lidar;
    }
    ADD_FAILURE() << "no scan";
    return {};
  }
  void Step() {
    if (!scene) scene = world.Scene();
    world.Step();
    VehicleBoxes(world, boxes);
    suites[0].Sample(world, *scene, boxes, readings);
  }
};

TEST(Lidar, Has360BeamsAndMeasuresAWallAtAKnownDistanceWithinFiveMillimetres) {
  Bench bench;
  bench.world.AddStaticBox(
      {RigidTransform2::FromXyYaw(1.05, 0, 0), {0.1, 2.0, 0.3}});  // face at 1.0
  const LidarScan scan = bench.NextScan();
  ASSERT_EQ(scan.ranges.size(), 360u);
  EXPECT_DOUBLE_EQ(scan.angle_min_rad, -std::numbers::pi);
  EXPECT_NEAR(scan.angle_increment_rad, std::numbers::pi / 180, 1e-15);
  EXPECT_NEAR(scan.scan_time_s, 1 / 7.0, 1e-12);
  EXPECT_NEAR(scan.time_increment_s, 1 / 7.0 / 360, 1e-15);
  // Beam 0 points forward (the LIDAR is yawed 180 degrees and angle_min is -pi).
  EXPECT_NEAR(scan.ranges[0], 1.0 - kLidarX, 0.005);
  // Beam 30: 30 degrees left of forward, the same wall, further by 1/cos 30.
  EXPECT_NEAR(scan.ranges[30], (1.0 - kLidarX) / std::cos(std::numbers::pi / 6), 0.005);
  // Behind the car: nothing within 12 m on open ground.
  EXPECT_TRUE(std::isinf(scan.ranges[180]));
  EXPECT_GT(scan.ranges[180], 0);
}

TEST(Lidar, BeyondTwelveMetresAndUnderFifteenCentimetresGiveInfinity) {
  Bench bench;
  bench.world.AddStaticBox({RigidTransform2::FromXyYaw(12.5, 0, 0), {0.1, 4.0, 0.3}});
  // A thin post 0.10 m to the car's right of the LIDAR, clear of the car's body (0.089 m).
  bench.world.AddStaticBox({RigidTransform2::FromXyYaw(kLidarX, -0.1025, 0), {0.005, 0.005, 0.3}});
  bench.world.AddStaticBox({RigidTransform2::FromXyYaw(-3.0, 0, 0), {0.1, 4.0, 0.3}});
  const LidarScan scan = bench.NextScan();
  EXPECT_TRUE(std::isinf(scan.ranges[0])) << scan.ranges[0];      // wall at 12.36 m
  EXPECT_TRUE(std::isinf(scan.ranges[270])) << scan.ranges[270];  // post at 0.10 m
  EXPECT_NEAR(scan.ranges[180], 3.0 - 0.05 + kLidarX, 0.005);     // the wall behind, for scale
}

TEST(Lidar, SeesAnotherCarAndAConstructionBoxAtTheirBearingAndRange) {
  Bench bench;
  // Another car 1.2 m ahead, side on (facing +y): its body's near side at 1.2 - 0.089.
  bench.AddCar(RigidTransform2::FromXyYaw(1.2, -0.0708, std::numbers::pi / 2));
  // A 0.1 m construction box 1 m to the left of the LIDAR.
  bench.world.AddStaticBox({RigidTransform2::FromXyYaw(kLidarX, 1.0, 0), {0.1, 0.1, 0.2}});
  const LidarScan scan = bench.NextScan();
  Eigen::Isometry3d X_MB;
  Eigen::Vector3d half;
  bench.world.VehicleBox(1, X_MB, half);
  const double near_face = X_MB.translation().x() - half.y();
  EXPECT_NEAR(scan.ranges[0], near_face - kLidarX, 0.005);
  EXPECT_NEAR(scan.ranges[90], 0.95, 0.005);  // beam 90 points left
  // Neither is seen where it is not.
  EXPECT_TRUE(std::isinf(scan.ranges[45]));
  EXPECT_TRUE(std::isinf(scan.ranges[270]));
}

TEST(Lidar, ThePaperPresetsRangeNoiseHasAStandardDeviationOf25MillimetresWithinTenPercent) {
  // The car's sensors as a city with `variability: {preset: paper}` gives them.
  SimConfig sim;
  sim.variability.preset = VariabilityPreset::kPaper;
  const SensorConfig config = EffectiveSensors(sim, 0);
  ASSERT_EQ(config.lidar.range_noise_m, 0.025);
  Bench noisy(config, 7);
  Bench exact;
  for (Bench* b : {&noisy, &exact}) {
    // A ring of walls all around, so that every beam returns.
    b->world.AddStaticBox({RigidTransform2::FromXyYaw(2, 0, 0), {0.1, 4.2, 0.3}});
    b->world.AddStaticBox({RigidTransform2::FromXyYaw(-2, 0, 0), {0.1, 4.2, 0.3}});
    b->world.AddStaticBox({RigidTransform2::FromXyYaw(0, 2, 0), {4.2, 0.1, 0.3}});
    b->world.AddStaticBox({RigidTransform2::FromXyYaw(0, -2, 0), {4.2, 0.1, 0.3}});
  }
  double sum = 0, sum2 = 0;
  int n = 0;
  for (int scan = 0; scan < 10; ++scan) {
    const LidarScan a = noisy.NextScan();
    const LidarScan b = exact.NextScan();
    for (std::size_t i = 0; i < a.ranges.size(); ++i) {
      ASSERT_TRUE(std::isfinite(a.ranges[i]) && std::isfinite(b.ranges[i])) << i;
      const double e = static_cast<double>(a.ranges[i]) - b.ranges[i];
      sum += e;
      sum2 += e * e;
      ++n;
    }
  }
  const double mean = sum / n;
  const double sd = std::sqrt(sum2 / n - mean * mean);
  std::printf("LIDAR range error over %d beams: mean %.5f m, standard deviation %.5f m\n", n, mean,
              sd);
  EXPECT_NEAR(sd, 0.025, 0.0025);
  EXPECT_NEAR(mean, 0, 0.002);
}

TEST(Lidar, ASweepScansAlongTheCarsMotionUnlessTakenAtOneInstant) {
  // Driving at top speed towards a wall: beam 359 (1 degree right of forward) is taken at the
  // end of the sweep, 0.14 s after beam 0, when the car is 0.26 x 0.14 = 3.7 cm closer.
  for (bool instantaneous : {false, true}) {
    SensorConfig config;
    config.lidar.instantaneous = instantaneous;
    Bench bench(config);
    bench.world.AddStaticBox({RigidTransform2::FromXyYaw(3.05, 0, 0), {0.1, 4.0, 0.3}});
    bench.world.SetCommand(0, {1.0, 0.0});
    bench.world.StepUntil(seconds(2));  // at speed
    LidarScan scan = bench.NextScan();
    scan = bench.NextScan();
    const double closer = scan.ranges[0] - scan.ranges[359] * std::cos(std::numbers::pi / 180);
    std::printf("%s: beam 0 %.4f m, beam 359 %.4f m: %.4f m closer\n",
                instantaneous ? "instantaneous" : "sweeping", scan.ranges[0], scan.ranges[359],
                closer);
    if (instantaneous) {
      EXPECT_NEAR(closer, 0.0, 0.002);
      EXPECT_EQ(scan.time_increment_s, 0.0);
    } else {
      EXPECT_NEAR(closer, 0.26 / 7 * 359 / 360, 0.004);
    }
  }
}

TEST(Imu, AtRestReadsNoRotationAndGravityUpAsTheMpu9250Does) {
  Bench bench;
  std::optional<ImuReading> last;
  int readings = 0;
  const Duration end = seconds(1);
  while (bench.world.time() < end) {
    bench.Step();
    if (bench.readings.imu) {
      last = bench.readings.imu;
      ++readings;
    }
  }
  EXPECT_EQ(readings, 101);  // 100 Hz: at 0 (the first step), 0.01, ..., 1.0 s
  ASSERT_TRUE(last.has_value());
  EXPECT_LT(last->angular_velocity_radps.norm(), 1e-6);
  EXPECT_NEAR(last->linear_acceleration_mps2.x(), 0, 1e-3);
  EXPECT_NEAR(last->linear_acceleration_mps2.y(), 0, 1e-3);
  EXPECT_NEAR(last->linear_acceleration_mps2.z(), 9.81, 1e-3);
  EXPECT_NEAR(last->orientation.angularDistance(Eigen::Quaterniond::Identity()), 0, 1e-4);
}

TEST(Imu, NoiseAndBiasAreThoseConfigured) {
  SensorConfig config;
  config.imu.gyro_noise_radps = 0.01;
  config.imu.gyro_bias_radps = 0.002;
  config.imu.accel_noise_mps2 = 0.05;
  Bench bench(config, 3);
  std::vector<double> gz, az;
  while (bench.world.time() < seconds(20)) {
    bench.Step();
    if (bench.readings.imu) {
      gz.push_back(bench.readings.imu->angular_velocity_radps.z());
      az.push_back(bench.readings.imu->linear_acceleration_mps2.z());
    }
  }
  const auto stats = [](const std::vector<double>& v) {
    double s = 0, s2 = 0;
    for (double x : v) s += x;
    const double mean = s / static_cast<double>(v.size());
    for (double x : v) s2 += (x - mean) * (x - mean);
    return std::pair{mean, std::sqrt(s2 / static_cast<double>(v.size()))};
  };
  const auto [g_mean, g_sd] = stats(gz);
  const auto [a_mean, a_sd] = stats(az);
  EXPECT_NEAR(g_mean, 0.002, 0.0015);
  EXPECT_NEAR(g_sd, 0.01, 0.001);
  EXPECT_NEAR(a_mean, 9.81, 0.01);
  EXPECT_NEAR(a_sd, 0.05, 0.005);
}

TEST(Sensors, EachRunsAtItsOwnRateAndEncodersReportTheirTicksAsAnAngle) {
  Bench bench;
  bench.world.SetCommand(0, {0.5, 0.0});
  int feedback = 0, encoders = 0, ips = 0, imu = 0, lidar = 0;
  while (bench.world.time() < seconds(2)) {
    bench.Step();
    const SensorReadings& r = bench.readings;
    feedback += r.feedback.has_value();
    ips += r.ips.has_value();
    imu += r.imu.has_value();
    lidar += r.lidar.has_value();
    if (r.encoders) {
      ++encoders;
      for (std::size_t k = 0; k < 2; ++k) {
        EXPECT_DOUBLE_EQ(r.encoders->angle_rad[k],
                         static_cast<double>(r.encoders->ticks[k]) * 2 * std::numbers::pi / 1920);
      }
    }
    if (r.ips) {
      EXPECT_EQ(r.ips->position_m, bench.world.State(0).X_MV.translation());
    }
  }
  // Samples due at 0 (taken at the first step), 1 / rate, ..., 2 s: 2 rate + 1.
  EXPECT_EQ(feedback, 101);
  EXPECT_EQ(encoders, 101);
  EXPECT_EQ(ips, 61);
  EXPECT_EQ(imu, 201);
  EXPECT_EQ(lidar, 14);  // sweep k, started at k / 7 s, completes 359/360 of a sweep later
  EXPECT_GT(bench.world.State(0).encoder_ticks[0], 1920);
}

TEST(Sensors, TheSameSeedGivesTheSameNoiseAndAnotherSeedOther) {
  SensorConfig config;
  config.lidar.range_noise_m = 0.025;
  config.ips.noise_m = 0.01;
  const auto run = [&](std::uint64_t seed) {
    Bench bench(config, seed);
    bench.world.AddStaticBox({RigidTransform2::FromXyYaw(1.05, 0, 0), {0.1, 2.0, 0.3}});
    std::vector<double> values;
    while (bench.world.time() < seconds(1)) {
      bench.Step();
      if (bench.readings.lidar) values.push_back(bench.readings.lidar->ranges[0]);
      if (bench.readings.ips) values.push_back(bench.readings.ips->position_m.x());
    }
    return values;
  };
  EXPECT_EQ(run(5), run(5));
  EXPECT_NE(run(5), run(6));
}

}  // namespace
}  // namespace autodrive::vehicle_sim
