#include "vehicle_sim/variability.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "common/config.h"
#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/layout.h"
#include "maps/polyline.h"
#include "vehicle_sim/raycast.h"

namespace autodrive::vehicle_sim {
namespace {

maps::Map ParkingSchool() {
  return maps::Build(
      maps::LoadLayout((test::SourceDir() / "config" / "maps" / "parking_school.yaml").string()));
}

Eigen::Vector2d Centre(const maps::Obstacle& o) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const auto& p : o.footprint) c += p;
  return c / static_cast<double>(o.footprint.size());
}
double Heading(const maps::Obstacle& o) {
  const Eigen::Vector2d d = o.footprint[1] - o.footprint[0];
  return std::atan2(d.y(), d.x());
}

struct Stats {
  double mean = 0, sd = 0;
};
Stats Of(const std::vector<double>& v) {
  Stats s;
  for (double x : v) s.mean += x;
  s.mean /= static_cast<double>(v.size());
  for (double x : v) s.sd += (x - s.mean) * (x - s.mean);
  s.sd = std::sqrt(s.sd / static_cast<double>(v.size() - 1));
  return s;
}

TEST(Variability, ThePaperPresetHasThePapersFiguresAndAGivenFigureOverridesIt) {
  VariabilityConfig none;
  EXPECT_EQ(none.DriveNoiseMps(), 0.0);
  EXPECT_EQ(none.SteeringNoiseRad(), 0.0);
  EXPECT_EQ(none.WallPositionNoiseM(), 0.0);
  EXPECT_EQ(none.WallHeadingNoiseRad(), 0.0);
  EXPECT_EQ(none.LidarRangeNoiseM(), 0.0);
  const auto paper = config::LoadString<VariabilityConfig>(
      "preset: paper\nlidar_range_noise_m: 0.03\n", "test.yaml");
  EXPECT_EQ(paper.DriveNoiseMps(), 0.013);
  EXPECT_EQ(paper.SteeringNoiseRad(), 0.018);
  EXPECT_EQ(paper.WallPositionNoiseM(), 0.01);
  EXPECT_EQ(paper.WallHeadingNoiseRad(), 0.087);
  EXPECT_EQ(paper.LidarRangeNoiseM(), 0.03);
  EXPECT_THROW((void)config::LoadString<VariabilityConfig>("preset: papr\n", "test.yaml"),
               ConfigError);
}

TEST(Variability, WallModulesMoveAndTurnByTheConfiguredFiguresAndNothingElseMoves) {
  const maps::Map map = ParkingSchool();
  std::size_t walls = 0;
  for (const auto& o : map.obstacles) walls += o.kind == "wall";
  ASSERT_GE(walls, 5u) << "the parking school has wall modules";
  // With no noise the map is the same.
  const maps::Map same = PerturbWalls(map, 0.0, 0.0, 7);
  ASSERT_EQ(same.obstacles.size(), map.obstacles.size());
  for (std::size_t i = 0; i < map.obstacles.size(); ++i) {
    EXPECT_EQ(same.obstacles[i].footprint, map.obstacles[i].footprint);
  }
  // Over many seeds each wall moves by N(0, 0.01) in x and y and turns by N(0, 0.087).
  std::vector<double> dx, dy, dyaw;
  for (std::uint64_t seed = 1; seed <= 100; ++seed) {
    const maps::Map moved = PerturbWalls(map, 0.01, 0.087, seed);
    for (std::size_t i = 0; i < map.obstacles.size(); ++i) {
      const maps::Obstacle &a = map.obstacles[i], &b = moved.obstacles[i];
      if (a.kind != "wall") {
        EXPECT_EQ(a.footprint, b.footprint) << "only walls move";
        continue;
      }
      const Eigen::Vector2d d = Centre(b) - Centre(a);
      dx.push_back(d.x());
      dy.push_back(d.y());
      dyaw.push_back(std::remainder(Heading(b) - Heading(a), 2 * std::numbers::pi));
      // The module keeps its shape.
      EXPECT_NEAR((b.footprint[1] - b.footprint[0]).norm(),
                  (a.footprint[1] - a.footprint[0]).norm(), 1e-12);
    }
  }
  const Stats sx = Of(dx), sy = Of(dy), syaw = Of(dyaw);
  std::printf("walls moved: %zu samples, x mean %.5f sd %.5f, y sd %.5f, yaw sd %.4f\n", dx.size(),
              sx.mean, sx.sd, sy.sd, syaw.sd);
  EXPECT_NEAR(sx.sd, 0.01, 0.001);
  EXPECT_NEAR(sy.sd, 0.01, 0.001);
  EXPECT_NEAR(syaw.sd, 0.087, 0.0087);
  EXPECT_NEAR(sx.mean, 0.0, 0.002);  // 3 standard errors over 600 draws
  // The same seed moves them the same way; another seed another way.
  EXPECT_EQ(PerturbWalls(map, 0.01, 0.087, 3).obstacles[0].footprint,
            PerturbWalls(map, 0.01, 0.087, 3).obstacles[0].footprint);
}

TEST(Variability, CommandNoiseHasThePapersFiguresInTheDevkitsUnitsAndLeavesAZeroThrottleAlone) {
  VariabilityConfig v;
  v.preset = VariabilityPreset::kPaper;
  const VehicleParams params;
  CommandNoise noise(v, params, 1, 0);
  std::vector<double> throttle, steering;
  for (int i = 0; i < 20000; ++i) {
    const VehicleCommand c = noise.Apply({0.5, 0.0});
    throttle.push_back((c.throttle - 0.5) * params.top_speed_mps);  // m/s
    steering.push_back(c.steering * params.steering_limit_rad);     // rad
  }
  const Stats t = Of(throttle), s = Of(steering);
  std::printf("drive noise sd %.5f m/s (0.013), steering noise sd %.5f rad (0.018)\n", t.sd, s.sd);
  EXPECT_NEAR(t.sd, 0.013, 0.0013 / 2);
  EXPECT_NEAR(s.sd, 0.018, 0.0018 / 2);
  EXPECT_EQ(noise.Apply({0.0, 0.2}).throttle, 0.0);
  EXPECT_EQ(noise.Apply({1.0, 1.0}).throttle <= 1.0, true);
  // The same seed and car give the same draws; another car others.
  CommandNoise a(v, params, 5, 0), b(v, params, 5, 0), c(v, params, 5, 1);
  const VehicleCommand ca = a.Apply({0.5, 0.1}), cb = b.Apply({0.5, 0.1}), cc = c.Apply({0.5, 0.1});
  EXPECT_EQ(ca.throttle, cb.throttle);
  EXPECT_EQ(ca.steering, cb.steering);
  EXPECT_NE(ca.throttle, cc.throttle);
  // No noise: the command as given.
  CommandNoise off(VariabilityConfig{}, params, 1, 0);
  EXPECT_EQ(off.Apply({0.3, -0.2}).throttle, 0.3);
  EXPECT_EQ(off.Apply({0.3, -0.2}).steering, -0.2);
}

TEST(Variability, TheLidarTakesThePresetsNoiseUnlessTheCarSetsItsOwn) {
  SimConfig sim;
  sim.variability.preset = VariabilityPreset::kPaper;
  sim.vehicles.push_back(SimVehicleConfig{"nigel_2", std::nullopt, {}, {}, {}});
  sim.vehicles[1].sensors.lidar.range_noise_m = 0.05;
  EXPECT_EQ(EffectiveSensors(sim, 0).lidar.range_noise_m, 0.025);
  EXPECT_EQ(EffectiveSensors(sim, 1).lidar.range_noise_m, 0.05);
}

TEST(Variability, UnmappedObstaclesStandInTheWorldAndTheLidarSeesThem) {
  SimConfig sim;
  sim.variability = config::LoadString<VariabilityConfig>(
      "obstacles:\n  - {x_m: 1.05, y_m: 0.0, length_m: 0.1, width_m: 0.5, height_m: 0.2}\n",
      "test.yaml");
  World world;
  AddObstacles(UnmappedObstacles(sim, maps::Map{}, {}), world);
  const Hit hit = Cast(world.Scene(), {}, Ray{{0, 0, 0.1}, {1, 0, 0}}, 12.0);
  EXPECT_EQ(hit.what, Hit::What::kStatic);
  EXPECT_NEAR(hit.range_m, 1.0, 1e-9);
}

TEST(Variability, ThePaperPresetScattersThreeSmallObstaclesAwayFromTheCarsAndTheMapsObstacles) {
  const maps::Map map = ParkingSchool();
  SimConfig sim;
  sim.variability.preset = VariabilityPreset::kPaper;
  const std::vector<RigidTransform2> spawns = {RigidTransform2::FromXyYaw(0.5, 0.5, 0)};
  const auto a = UnmappedObstacles(sim, map, spawns);
  ASSERT_EQ(a.size(), 3u);
  const StaticScene mapped = StaticScene::FromMap(map);
  for (const UnmappedObstacle& o : a) {
    EXPECT_EQ(o.length_m, 0.1);
    EXPECT_GT(o.height_m, 0.1757) << "above the LIDAR's plane: a car's LIDAR sees it";
    EXPECT_GE(o.x_m, 0.0);
    EXPECT_LE(o.x_m, map.cols * map.tile_size_m);
    EXPECT_GE((spawns[0].translation() - Eigen::Vector2d(o.x_m, o.y_m)).norm(), 0.5);
    // Not inside a mapped obstacle: a ray straight down from above its centre meets the
    // ground, not a wall or box top.
    const Hit down = Cast(mapped, {}, Ray{{o.x_m, o.y_m, 5.0}, {0, 0, -1}}, 10.0);
    EXPECT_EQ(down.what, Hit::What::kTerrain) << o.x_m << ", " << o.y_m;
  }
  // Drawn from the seed: the same seed places them again; another seed elsewhere.
  const auto b = UnmappedObstacles(sim, map, spawns);
  EXPECT_EQ(a, b);
  sim.seed = 2;
  EXPECT_NE(UnmappedObstacles(sim, map, spawns), a);
  // Given ones come first and a count overrides the preset's.
  sim.variability.random_obstacles = 0;
  UnmappedObstacle box;
  box.x_m = box.y_m = 1;
  box.length_m = box.width_m = box.height_m = 0.2;
  sim.variability.obstacles = {box};
  EXPECT_EQ(UnmappedObstacles(sim, map, spawns).size(), 1u);
}

// On a road map the random obstacles stand beside the road: a lane follower, which must stop
// for what is on its lane, would stop for ever; one is put on a lane on purpose instead.
TEST(Variability, ThePaperPresetsObstaclesStandOffEveryLaneAndPath) {
  const maps::Map map =
      maps::Build(maps::LoadLayout((test::SourceDir() / "config/maps/small_town.yaml").string()));
  SimConfig sim;
  sim.variability.preset = VariabilityPreset::kPaper;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    sim.seed = seed;
    for (const UnmappedObstacle& o : UnmappedObstacles(sim, map, {})) {
      const Eigen::Vector2d p(o.x_m, o.y_m);
      for (const maps::Lane& lane : map.lanes) {
        EXPECT_GE(maps::NearestOnPolyline(lane.centreline, p).distance_m, lane.width_m / 2 + 0.0707)
            << "seed " << seed << ": an obstacle at (" << p.x() << ", " << p.y() << ") on "
            << lane.name;
      }
      for (const maps::Movement& m : map.movements) {
        EXPECT_GE(maps::NearestOnPolyline(m.path, p).distance_m, 0.15 + 0.0707)
            << "seed " << seed << ": an obstacle on " << m.name;
      }
    }
  }
}

// The cloning preset: the paper's command noise, the light and the start varied, nothing else.
// The light is drawn once per run (every camera the same), the start per car; over 400 seeds the
// figures are what the preset says.
TEST(Variability, TheCloningPresetVariesTheLightAndTheStartAcrossSeeds) {
  const auto cloning = config::LoadString<VariabilityConfig>("preset: cloning\n", "test.yaml");
  EXPECT_EQ(cloning.DriveNoiseMps(), 0.013);
  EXPECT_EQ(cloning.WallPositionNoiseM(), 0.0);
  EXPECT_EQ(cloning.LidarRangeNoiseM(), 0.0);
  EXPECT_EQ(cloning.RandomObstacles(), 0);
  EXPECT_EQ(cloning.LightIntensitySpread(), 0.4);
  EXPECT_EQ(cloning.StartPositionNoiseM(), 0.03);

  const maps::Map map = ParkingSchool();
  SimConfig sim;
  sim.vehicles[0].spawn = SpawnConfig{std::nullopt, 0.0, 1.0, 2.0, 0.5};
  const FilmOptions film;
  EXPECT_EQ(LitFilm(film, sim), film) << "no variability: the film as configured";
  sim.variability = cloning;
  std::vector<double> exposure, azimuth, x, yaw;
  for (std::uint64_t seed = 1; seed <= 400; ++seed) {
    sim.seed = seed;
    const FilmOptions lit = LitFilm(film, sim);
    EXPECT_EQ(LitFilm(film, sim), lit) << "one light per run";
    EXPECT_EQ(lit.ambient, film.ambient);
    EXPECT_GE(lit.light_elevation_rad, 0.2);
    EXPECT_LE(lit.light_elevation_rad, 1.5);
    exposure.push_back(lit.exposure);
    azimuth.push_back(lit.light_azimuth_rad - film.light_azimuth_rad);
    const RigidTransform2 start = SpawnPoses(sim, map)[0];
    x.push_back(start.translation().x() - 1.0);
    yaw.push_back(start.yaw() - 0.5);
  }
  // Uniform in [0.6, 1.4] and [-pi, pi]: standard deviations 0.4 / sqrt(3) and pi / sqrt(3).
  EXPECT_NEAR(*std::min_element(exposure.begin(), exposure.end()), 0.6, 0.02);
  EXPECT_NEAR(*std::max_element(exposure.begin(), exposure.end()), 1.4, 0.02);
  EXPECT_NEAR(Of(exposure).sd, 0.4 / std::sqrt(3.0), 0.02);
  EXPECT_NEAR(Of(azimuth).sd, std::numbers::pi / std::sqrt(3.0), 0.15);
  EXPECT_NEAR(Of(x).sd, 0.03, 0.004);
  EXPECT_NEAR(Of(yaw).sd, 0.087, 0.01);
  EXPECT_NEAR(Of(x).mean, 0.0, 0.006);
}

}  // namespace
}  // namespace autodrive::vehicle_sim
