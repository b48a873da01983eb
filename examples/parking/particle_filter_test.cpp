// The particle filter on the Parking School: a car's true poses along a planned path (forward,
// then backing into the bay), its odometry with noise, and 360-beam scans cast by the
// simulator's own ray caster (vehicle_sim/raycast.h) against the map's walls and boxes, with the
// paper's LIDAR noise (2.5 cm). The filter's estimate is compared with the true poses.
#include "examples/parking/particle_filter.h"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <numbers>
#include <random>

#include "common/test_support.h"
#include "examples/parking/hybrid_astar.h"
#include "examples/parking/localiser.h"
#include "examples/parking/slam.h"
#include "maps/builder.h"
#include "maps/layout.h"
#include "maps/occupancy.h"
#include "vehicle_sim/raycast.h"
#include "vehicle_sim/variability.h"

namespace autodrive::examples {
namespace {

const maps::Map& ParkingSchool() {
  static const maps::Map map = maps::Build(
      maps::LoadLayout((test::SourceDir() / "config/maps/parking_school.yaml").string()));
  return map;
}

// A 360-beam scan of the map, beam b cast from rear-axle pose `pose_of(b)` by the simulator's ray
// caster from the LIDAR's place (0.1445 m ahead, 0.1757 m up), with the paper's range noise
// (2.5 cm).
template <typename PoseOf>
std::vector<float> ScanAlong(const vehicle_sim::StaticScene& scene, const PoseOf& pose_of,
                             std::mt19937_64& rng) {
  std::normal_distribution<double> noise(0.0, 0.025);
  std::vector<float> ranges(360);
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    const RigidTransform2 X = pose_of(i);
    const Eigen::Vector2d lidar_at = X * Eigen::Vector2d(0.1445, 0.0);
    const double a = X.yaw() + 2 * std::numbers::pi * static_cast<double>(i) / 360.0;
    const vehicle_sim::Hit hit = vehicle_sim::Cast(
        scene, {}, {{lidar_at.x(), lidar_at.y(), 0.1757}, {std::cos(a), std::sin(a), 0}}, 12.0);
    ranges[i] = std::isfinite(hit.range_m) ? static_cast<float>(hit.range_m + noise(rng))
                                           : std::numeric_limits<float>::infinity();
  }
  return ranges;
}

// The same, every beam from X.
std::vector<float> Scan(const vehicle_sim::StaticScene& scene, const RigidTransform2& X,
                        std::mt19937_64& rng) {
  return ScanAlong(
      scene, [&](std::size_t) { return X; }, rng);
}

// The odometry's measure of the car-frame motion `d`: 3% on the distance, a little sideways and
// in heading.
RigidTransform2 Odometry(const RigidTransform2& d, std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return RigidTransform2::FromXyYaw(d.translation().x() * (1 + 0.03 * n(rng)),
                                    d.translation().y() + 0.002 * n(rng), d.yaw() + 0.01 * n(rng));
}

struct Track {
  double rms_m = 0, max_m = 0, max_yaw_rad = 0;
  std::size_t first_size = 0, last_size = 0;
};

// Runs the filter along the path from `init` (its spread `sigma_xy`, `sigma_yaw`); errors from
// step `settle` on.
Track Follow(const std::vector<PathPose>& path, const RigidTransform2& init, double sigma_xy,
             double sigma_yaw, std::size_t settle, std::uint64_t walls_seed = 0,
             const ParticleFilterParams& fp = {}) {
  const vehicle_sim::StaticScene scene = vehicle_sim::StaticScene::FromMap(
      walls_seed == 0 ? ParkingSchool()
                      : vehicle_sim::PerturbWalls(ParkingSchool(), 0.01, 0.087, walls_seed));
  ParticleFilter filter(maps::MakeOccupancyGrid(ParkingSchool(), 0.025, false), fp);
  filter.Init(init, sigma_xy, sigma_yaw);
  std::mt19937_64 rng(7);
  Track t;
  double sum2 = 0;
  std::size_t n = 0;
  for (std::size_t k = 0; k < path.size(); ++k) {
    const RigidTransform2& X = path[k].X_MV;
    if (k > 0) {
      const RigidTransform2 d = path[k - 1].X_MV.inverse() * X;  // the true car-frame motion
      filter.Predict(Odometry(d, rng));
    }
    filter.Update(Scan(scene, X, rng));
    if (k == 0) t.first_size = filter.size();
    t.last_size = filter.size();
    if (k < settle) continue;
    const RigidTransform2 e = filter.Estimate();
    const double err = (e.translation() - X.translation()).norm();
    sum2 += err * err;
    ++n;
    t.max_m = std::max(t.max_m, err);
    t.max_yaw_rad = std::max(t.max_yaw_rad, std::abs(WrapAngle(e.yaw() - X.yaw())));
  }
  t.rms_m = std::sqrt(sum2 / static_cast<double>(std::max<std::size_t>(n, 1)));
  std::printf(
      "localisation over %zu poses: RMS %.1f mm, max %.1f mm, heading max %.2f deg; "
      "particles %zu first, %zu last\n",
      n, t.rms_m * 1000, t.max_m * 1000, t.max_yaw_rad * 180 / std::numbers::pi, t.first_size,
      t.last_size);
  return t;
}

std::vector<PathPose> BayPath() {
  const HybridAStar planner(maps::MakeOccupancyGrid(ParkingSchool(), 0.025, false));
  const PlanResult plan = planner.Plan(RigidTransform2::FromXyYaw(0.6, 2.0, 0.0),
                                       RigidTransform2::FromXyYaw(3.6, 2.0, std::numbers::pi));
  EXPECT_FALSE(plan.path.empty()) << plan.failure;
  return plan.path;
}

TEST(ParticleFilter, TracksTheCarIntoTheBayWithinCentimetres) {
  const std::vector<PathPose> path = BayPath();
  ASSERT_GT(path.size(), 50U);
  const Track t = Follow(path, path.front().X_MV, 0.05, 0.05, 5);
  EXPECT_LT(t.rms_m, 0.03) << "max " << t.max_m;
  EXPECT_LT(t.max_m, 0.08);
  EXPECT_LT(t.max_yaw_rad, 5 * std::numbers::pi / 180);
  EXPECT_LT(t.last_size, t.first_size) << "KLD-sampling: fewer particles once it is sure";
}

TEST(ParticleFilter, FindsTheCarFromAStartThirtyCentimetresOff) {
  const std::vector<PathPose> path = BayPath();
  const RigidTransform2 off = RigidTransform2::FromXyYaw(
      path.front().X_MV.translation().x() + 0.2, path.front().X_MV.translation().y() - 0.2, 0.2);
  const Track t = Follow(path, off, 0.3, 0.3, 30);
  EXPECT_LT(t.rms_m, 0.04) << "max " << t.max_m;
  EXPECT_LT(t.max_yaw_rad, 8 * std::numbers::pi / 180);
}

// Hector-style SLAM along the same path, from the odometry's guesses: its poses stay within
// centimetres of the truth, and the map it builds agrees with the map's own grid on the cells it
// saw (but for the bay's 0.15 m dividers, under the LIDAR's plane: it sees the floor there).
TEST(ScanMatchingSlam, BuildsTheMapAlongThePathAndKeepsItsPose) {
  const std::vector<PathPose> path = BayPath();
  const vehicle_sim::StaticScene scene = vehicle_sim::StaticScene::FromMap(ParkingSchool());
  ScanMatchingSlam slam;
  std::mt19937_64 rng(11);
  RigidTransform2 estimate = path.front().X_MV;
  double sum2 = 0, worst = 0, odometry_worst = 0;
  RigidTransform2 dead_reckoning = path.front().X_MV;
  for (std::size_t k = 0; k < path.size(); ++k) {
    const RigidTransform2& X = path[k].X_MV;
    RigidTransform2 guess = estimate;
    if (k > 0) {
      const RigidTransform2 odo = Odometry(path[k - 1].X_MV.inverse() * X, rng);
      guess = estimate * odo;
      dead_reckoning = dead_reckoning * odo;
    }
    estimate = slam.Update(guess, Scan(scene, X, rng));
    const double err = (estimate.translation() - X.translation()).norm();
    sum2 += err * err;
    worst = std::max(worst, err);
    odometry_worst =
        std::max(odometry_worst, (dead_reckoning.translation() - X.translation()).norm());
  }
  const double rms = std::sqrt(sum2 / static_cast<double>(path.size()));
  const MapAgreement a = CompareMaps(slam, maps::MakeOccupancyGrid(ParkingSchool(), 0.025, false));
  const std::size_t seen = a.seen;
  const double agreement = a.share();
  std::printf(
      "SLAM over %zu poses: RMS %.1f mm, worst %.1f mm (odometry alone: worst %.1f mm); "
      "map: %.1f%% of %zu cells seen agree with the map's grid\n",
      path.size(), rms * 1000, worst * 1000, odometry_worst * 1000, agreement * 100, seen);
  EXPECT_LT(rms, 0.03);
  EXPECT_LT(worst, 0.06);
  EXPECT_GT(seen, 5000U);
  EXPECT_GT(agreement, 0.9);
}

// The paper's variability moves and turns every wall module (1 cm, 5 degrees): the world the
// LIDAR sees is no longer the map the filter weighs it against, by up to 4 cm at a module's ends.
// Over 6 such worlds the filter's error grows to centimetres; beam skipping (the beams that end
// near the map for too few particles left out) takes the worst of it off.
TEST(ParticleFilter, BeamSkippingKeepsItCloserWhenTheWallsStandElsewhereThanMapped) {
  const auto run = [](double skip_m) {
    ParticleFilterParams fp;
    fp.beam_skip_distance_m = skip_m;
    fp.beam_skip_threshold = 0.6;
    double rms = 0, worst = 0;
    for (std::uint64_t seed = 1; seed <= 6; ++seed) {
      const Track t = Follow(BayPath(), BayPath().front().X_MV, 0.02, 0.02, 10, seed, fp);
      rms += t.rms_m / 6;
      worst = std::max(worst, t.max_m);
    }
    std::printf("perturbed walls, beam skipping %.2f m: mean RMS %.1f mm, worst %.1f mm\n", skip_m,
                rms * 1000, worst * 1000);
    return std::pair{rms, worst};
  };
  const auto [plain_rms, plain_worst] = run(0.0);
  const auto [skip_rms, skip_worst] = run(0.05);
  EXPECT_LT(skip_rms, plain_rms);
  EXPECT_LT(skip_worst, plain_worst);
  EXPECT_LT(skip_rms, 0.035);
  EXPECT_LT(skip_worst, 0.1);
}

// The agent's localiser driven along the path in the simulated world: poses every 100 ms (5 cm
// apart: 0.5 m/s), wheel angles from the true car-frame motion (3% off in distance) and the IMU's
// heading. Each scan is cast as a turning LIDAR takes it: beam i from where the car is at
// `stamp` + i / (7 x 360) s, over 1/7 s along the path; the localiser is told that timing when
// `tell_timing`, else that the beams were taken at once. The first fix is the true start; with
// `params.mapping_scans` it first maps standing there (every beam from the start). Returns the RMS
// and worst error (m).
std::pair<double, double> Drive(const std::vector<PathPose>& path,
                                const vehicle_sim::StaticScene& scene,
                                const maps::OccupancyGrid& grid, const LocaliserParams& params,
                                bool tell_timing) {
  const auto at = [](double s) {
    return Time{} + std::chrono::duration_cast<Duration>(std::chrono::duration<double>(s));
  };
  constexpr double kStep = 0.1;
  // The true pose at time s: between path poses, the car-frame motion interpolated.
  const auto pose = [&](double s) {
    const double k = std::clamp(s / kStep, 0.0, static_cast<double>(path.size() - 1));
    const auto i = static_cast<std::size_t>(std::floor(k));
    if (i + 1 >= path.size()) return path.back().X_MV;
    const RigidTransform2 d = path[i].X_MV.inverse() * path[i + 1].X_MV;
    const double f = k - static_cast<double>(i);
    return path[i].X_MV * RigidTransform2::FromXyYaw(f * d.translation().x(),
                                                     f * d.translation().y(), f * d.yaw());
  };
  constexpr double kIncrement = 1.0 / (7.0 * 360.0);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  const auto scan = [&](double stamp, bool standing) {
    return ScanAlong(
        scene,
        [&](std::size_t b) {
          return pose(standing ? 0.0 : stamp + static_cast<double>(b) * kIncrement);
        },
        rng);
  };
  Localiser localiser(grid, params);
  localiser.Start(path.front().X_MV);
  double wheel = 0;
  localiser.Odometry(at(0), wheel, wheel, path.front().X_MV.yaw());
  for (int m = 0; m < params.mapping_scans; ++m) localiser.Scan(at(0), kIncrement, scan(0, true));
  EXPECT_TRUE(localiser.ready());
  double sum2 = 0, worst = 0, last_scan = -1;
  std::size_t count = 0;
  const double end = kStep * static_cast<double>(path.size() - 1);
  for (double t = 0.02; t <= end + 1e-9; t += 0.02) {
    const RigidTransform2 d = pose(t - 0.02).inverse() * pose(t);
    wheel += (d.translation().x() >= 0 ? 1 : -1) * d.translation().norm() * (1 + 0.03 * n(rng)) /
             params.wheel_radius_m;
    localiser.Odometry(at(t), wheel, wheel, pose(t).yaw());
    // A scan is published once its last beam is taken: the one begun 1/7 s ago.
    const double begun = std::floor((t - 1.0 / 7) * 7) / 7;
    if (begun >= 0 && begun > last_scan) {
      last_scan = begun;
      localiser.Scan(at(begun), tell_timing ? kIncrement : 0.0, scan(begun, false));
      const double err = (localiser.Estimate().translation() - pose(t).translation()).norm();
      sum2 += err * err;
      worst = std::max(worst, err);
      ++count;
    }
  }
  const double rms = std::sqrt(sum2 / static_cast<double>(std::max<std::size_t>(count, 1)));
  std::printf("localiser over %zu scans (%s, beams %s): RMS %.1f mm, worst %.1f mm\n", count,
              params.mapping_scans > 0 ? "its own map" : "the map's grid",
              tell_timing ? "moved to the car's pose now" : "as if taken at once", rms * 1000,
              worst * 1000);
  return {rms, worst};
}

// The paper's way, the agent's: map first, standing at the fix, then localise against that map.
// In 6 worlds whose walls the paper's variability moved and turned, the filter on its own map
// stays within about a centimetre, where on the map's grid (the walls where they were meant to
// stand) it strays by centimetres.
TEST(Localiser, OnTheMapItBuiltStandingItStaysWithinACentimetreWhereTheWallsAreTurned) {
  const std::vector<PathPose> path = BayPath();
  const maps::OccupancyGrid grid = maps::MakeOccupancyGrid(ParkingSchool(), 0.025, false);
  double built_rms = 0, built_worst = 0, city_rms = 0;
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const vehicle_sim::StaticScene scene = vehicle_sim::StaticScene::FromMap(
        vehicle_sim::PerturbWalls(ParkingSchool(), 0.01, 0.087, seed));
    LocaliserParams own;
    own.mapping_scans = 10;
    const auto [rms, worst] = Drive(path, scene, grid, own, true);
    built_rms += rms / 6;
    built_worst = std::max(built_worst, worst);
    city_rms += Drive(path, scene, grid, LocaliserParams{}, true).first / 6;
  }
  std::printf(
      "turned walls: mean RMS %.1f mm on its own map (worst %.1f mm), %.1f mm on the grid\n",
      built_rms * 1000, built_worst * 1000, city_rms * 1000);
  EXPECT_LT(built_rms, 0.015);
  EXPECT_LT(built_worst, 0.04);
  EXPECT_LT(built_rms, city_rms / 2);
}

// A turning LIDAR takes its beams over 1/7 s as the car moves; weighed as if taken at once, the
// scan pulls the estimate back towards where the car was. Moved by the odometry to where the car
// is, the beams keep it closer.
TEST(Localiser, MovesATurningLidarsBeamsToWhereTheCarIsNow) {
  const std::vector<PathPose> path = BayPath();
  const maps::OccupancyGrid grid = maps::MakeOccupancyGrid(ParkingSchool(), 0.025, false);
  const vehicle_sim::StaticScene scene = vehicle_sim::StaticScene::FromMap(ParkingSchool());
  const auto [moved_rms, moved_worst] = Drive(path, scene, grid, LocaliserParams{}, true);
  const auto [still_rms, still_worst] = Drive(path, scene, grid, LocaliserParams{}, false);
  EXPECT_LT(moved_rms, still_rms);
  EXPECT_LT(moved_rms, 0.015) << "worst " << moved_worst;
  (void)still_worst;
}

// Its map is its first fix's: a car that rolls while it maps (still moving when the agent began,
// or pushed) would smear it. The odometry says so, and the mapping begins again where the car
// then stands; the filter then finds the car where it is.
TEST(Localiser, BeginsItsMapAgainWhenTheCarMovesWhileMapping) {
  const maps::OccupancyGrid grid = maps::MakeOccupancyGrid(ParkingSchool(), 0.025, false);
  const vehicle_sim::StaticScene scene = vehicle_sim::StaticScene::FromMap(ParkingSchool());
  LocaliserParams params;
  params.mapping_scans = 3;
  Localiser localiser(grid, params);
  const RigidTransform2 first = RigidTransform2::FromXyYaw(0.6, 2.0, 0.0);
  const RigidTransform2 rolled = first * RigidTransform2::FromXyYaw(0.1, 0.0, 0.0);
  std::mt19937_64 rng(9);
  const auto at = [](int ms) { return Time{} + std::chrono::milliseconds(ms); };
  localiser.Start(first);
  localiser.Odometry(at(0), 0.0, 0.0, 0.0);
  localiser.Scan(at(0), 0.0, Scan(scene, first, rng));
  localiser.Scan(at(150), 0.0, Scan(scene, first, rng));
  EXPECT_FALSE(localiser.ready());
  const double turns = 0.1 / params.wheel_radius_m;  // 10 cm on both wheels
  localiser.Odometry(at(400), turns, turns, 0.0);
  for (int k = 0; k < 3; ++k) localiser.Scan(at(450 + 150 * k), 0.0, Scan(scene, rolled, rng));
  ASSERT_TRUE(localiser.ready());
  EXPECT_EQ(localiser.mapping_restarts(), 1);
  for (int k = 0; k < 10; ++k) localiser.Scan(at(1000 + 150 * k), 0.0, Scan(scene, rolled, rng));
  const double err = (localiser.Estimate().translation() - rolled.translation()).norm();
  std::printf("moved 10 cm while mapping: begun again, then %.1f mm from the car\n", err * 1000);
  EXPECT_LT(err, 0.01);  // 15 mm off when its map is smeared over the 10 cm
}

// The agent's localiser on what the car's topics give: wheel angles (the true car-frame motion's
// arc, 3% off in distance) and the IMU's heading, and the scans. From a first fix 2 cm and 2
// degrees off, the particle filter keeps the pose along the path to the bay; SLAM builds its map
// beside it, written in map_server's format.
TEST(Localiser, TracksThePathFromEncodersImuAndScansAndWritesSlamsMap) {
  const test::TempDir dir("localiser");
  const std::vector<PathPose> path = BayPath();
  const vehicle_sim::StaticScene scene = vehicle_sim::StaticScene::FromMap(ParkingSchool());
  const maps::OccupancyGrid grid = maps::MakeOccupancyGrid(ParkingSchool(), 0.025, false);
  LocaliserParams params;
  Localiser localiser(grid, params);
  const RigidTransform2 start = path.front().X_MV;
  localiser.Start(start * RigidTransform2::FromXyYaw(0.02, 0.0, 0.035));
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n(0.0, 1.0);
  double left = 0, right = 0, sum2 = 0, worst = 0;
  const auto at = [](std::size_t k) {  // a pose every 100 ms
    return Time{} + std::chrono::milliseconds(100) * static_cast<int>(k);
  };
  localiser.Odometry(at(0), left, right, start.yaw());
  for (std::size_t k = 0; k < path.size(); ++k) {
    const RigidTransform2& X = path[k].X_MV;
    if (k > 0) {
      const RigidTransform2 d = path[k - 1].X_MV.inverse() * X;
      const double distance =
          (d.translation().x() >= 0 ? 1 : -1) * d.translation().norm() * (1 + 0.03 * n(rng));
      left += distance / params.wheel_radius_m;
      right += distance / params.wheel_radius_m;
      localiser.Odometry(at(k), left, right, X.yaw() + 0.002 * n(rng));
    }
    localiser.Scan(at(k), 0.0, Scan(scene, X, rng));
    if (k < 10) continue;
    const double err = (localiser.Estimate().translation() - X.translation()).norm();
    sum2 += err * err;
    worst = std::max(worst, err);
  }
  const double rms = std::sqrt(sum2 / static_cast<double>(path.size() - 10));
  std::printf("localiser over %zu poses: RMS %.1f mm, worst %.1f mm\n", path.size() - 10,
              rms * 1000, worst * 1000);
  EXPECT_LT(rms, 0.02);
  EXPECT_LT(worst, 0.05);
  EXPECT_GT(CompareMaps(localiser.slam(), grid).share(), 0.9);

  const std::string prefix = (dir.path() / "slam").string();
  WriteMapServerMap(localiser.slam(), prefix);
  std::ifstream pgm(prefix + ".pgm", std::ios::binary);
  std::string magic;
  int width = 0, height = 0, max = 0;
  pgm >> magic >> width >> height >> max;
  pgm.get();
  EXPECT_EQ(magic, "P5");
  EXPECT_EQ(width, grid.width);
  EXPECT_EQ(height, grid.height);
  EXPECT_EQ(max, 255);
  std::vector<char> pixels(static_cast<std::size_t>(width * height));
  pgm.read(pixels.data(), static_cast<std::streamsize>(pixels.size()));
  ASSERT_TRUE(pgm.good());
  std::size_t occupied = 0, free = 0, unseen = 0;
  for (const char c : pixels) {
    const auto v = static_cast<unsigned char>(c);
    occupied += v == 0;
    free += v == 254;
    unseen += v == 205;
  }
  EXPECT_EQ(occupied + free + unseen, pixels.size());
  EXPECT_GT(occupied, 100u);
  EXPECT_GT(free, 5000u);
  // The north row first: the map's north wall (row height - 1) is the image's first row.
  std::size_t top_occupied = 0;
  for (std::size_t c = 0; c < static_cast<std::size_t>(width); ++c) {
    top_occupied += static_cast<unsigned char>(pixels[c]) == 0;
  }
  EXPECT_GT(top_occupied, 0u);
  const YAML::Node meta = YAML::LoadFile(prefix + ".yaml");
  EXPECT_EQ(meta["image"].as<std::string>(), "slam.pgm");
  EXPECT_EQ(meta["resolution"].as<double>(), 0.025);
}

}  // namespace
}  // namespace autodrive::examples
