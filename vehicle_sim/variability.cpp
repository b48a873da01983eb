#include "vehicle_sim/variability.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/error.h"
#include "common/geometry.h"
#include "maps/polyline.h"
#include "vehicle_sim/raycast.h"

namespace autodrive::vehicle_sim {

FilmOptions LitFilm(const FilmOptions& film, const SimConfig& sim) {
  const double intensity = sim.variability.LightIntensitySpread();
  const double direction = sim.variability.LightDirectionSpreadRad();
  if (intensity == 0.0 && direction == 0.0) return film;
  std::mt19937_64 rng(StreamSeed(sim.seed, -1, kLightStream));
  const auto uniform = [&](double half) {
    return std::uniform_real_distribution<double>(-half, half)(rng);
  };
  const double scale = 1.0 + uniform(intensity);
  const double azimuth = uniform(direction);
  const double elevation = uniform(direction / 4);
  FilmOptions out = film;
  // The renderer shows the ground in its own colours in any light (the shade is relative to the
  // ground's), so the light's intensity is what the film gets of it: the exposure.
  out.exposure = std::clamp(out.exposure * scale, 0.001, 20.0);
  out.light_azimuth_rad += azimuth;
  out.light_elevation_rad = std::clamp(out.light_elevation_rad + elevation, 0.2, 1.5);
  return out;
}

maps::Map PerturbWalls(const maps::Map& map, double position_sigma_m, double heading_sigma_rad,
                       std::uint64_t seed) {
  maps::Map out = map;
  if (position_sigma_m == 0.0 && heading_sigma_rad == 0.0) return out;
  std::mt19937_64 rng(StreamSeed(seed, -1, kWallStream));
  for (maps::Obstacle& o : out.obstacles) {
    if (o.kind != "wall" || o.footprint.empty()) continue;
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (const Eigen::Vector2d& p : o.footprint) centre += p;
    centre /= static_cast<double>(o.footprint.size());
    const double dx = Gaussian(rng, position_sigma_m);
    const double dy = Gaussian(rng, position_sigma_m);
    const double dyaw = Gaussian(rng, heading_sigma_rad);
    const Eigen::Rotation2Dd turn(dyaw);
    for (Eigen::Vector2d& p : o.footprint)
      p = centre + turn * (p - centre) + Eigen::Vector2d(dx, dy);
  }
  return out;
}

maps::Map SimulatedMap(const SimConfig& sim, const maps::Map& map) {
  return PerturbWalls(map, sim.variability.WallPositionNoiseM(),
                      sim.variability.WallHeadingNoiseRad(), sim.seed);
}

namespace {
bool Inside(const maps::Polyline& polygon, const Eigen::Vector2d& p) {
  return !polygon.empty() &&
         InsidePolygon(polygon.data(), static_cast<std::uint32_t>(polygon.size()), p.x(), p.y());
}
}  // namespace

std::vector<UnmappedObstacle> UnmappedObstacles(const SimConfig& sim, const maps::Map& map,
                                                std::span<const RigidTransform2> spawns) {
  std::vector<UnmappedObstacle> out = sim.variability.obstacles;
  const int n = sim.variability.RandomObstacles();
  if (n == 0) return out;
  // 0.1 m square, 0.3 m tall: above the LIDAR's plane (0.176 m up), so a car's LIDAR sees it.
  constexpr double kSize = 0.1, kHeight = 0.3, kClearOfCars = 0.5;
  // Clear of every lane and path through an intersection by this much (its half diagonal and
  // 2 cm): beside the road, or on open and parking floor.
  const double clear_of_road = kSize * std::numbers::sqrt2 / 2 + 0.02;
  std::mt19937_64 rng(StreamSeed(sim.seed, -1, kObstacleStream));
  std::uniform_real_distribution<double> x(0.0, map.cols * map.tile_size_m);
  std::uniform_real_distribution<double> y(0.0, map.rows * map.tile_size_m);
  std::uniform_real_distribution<double> yaw(-std::numbers::pi, std::numbers::pi);
  for (int k = 0; k < n; ++k) {
    bool placed = false;
    for (int attempt = 0; attempt < 10'000 && !placed; ++attempt) {
      const Eigen::Vector2d p(x(rng), y(rng));
      const double heading = yaw(rng);
      bool clear = true;
      for (const RigidTransform2& s : spawns)
        clear = clear && (s.translation() - p).norm() >= kClearOfCars;
      for (const ClearPoint& c : sim.variability.keep_clear)
        clear = clear && (Eigen::Vector2d(c.x_m, c.y_m) - p).norm() >= kClearOfCars;
      // The cube's corners and centre outside every mapped obstacle.
      const Eigen::Rotation2Dd R(heading);
      for (const maps::Obstacle& o : map.obstacles) {
        if (!clear) break;
        clear = !Inside(o.footprint, p);
        for (int c = 0; c < 4 && clear; ++c) {
          const Eigen::Vector2d corner(c % 2 == 0 ? kSize / 2 : -kSize / 2,
                                       c < 2 ? kSize / 2 : -kSize / 2);
          clear = !Inside(o.footprint, p + R * corner);
        }
      }
      for (const maps::Lane& lane : map.lanes) {
        if (!clear) break;
        clear = maps::NearestOnPolyline(lane.centreline, p).distance_m >=
                lane.width_m / 2 + clear_of_road;
      }
      for (const maps::Movement& m : map.movements) {
        if (!clear) break;
        clear = maps::NearestOnPolyline(m.path, p).distance_m >=
                map.lane(m.from).width_m / 2 + clear_of_road;
      }
      if (!clear) continue;
      UnmappedObstacle cube;
      cube.x_m = p.x();
      cube.y_m = p.y();
      cube.yaw_rad = heading;
      cube.length_m = cube.width_m = kSize;
      cube.height_m = kHeight;
      out.push_back(cube);
      placed = true;
    }
    AUTODRIVE_THROW_UNLESS(placed, "variability: found no place for random obstacle "
                                       << k + 1 << " of " << n << " on map " << map.name);
  }
  return out;
}

void AddObstacles(std::span<const UnmappedObstacle> obstacles, World& world) {
  for (const UnmappedObstacle& o : obstacles) {
    const StaticBox box{RigidTransform2::FromXyYaw(o.x_m, o.y_m, o.yaw_rad),
                        Eigen::Vector3d(o.length_m, o.width_m, o.height_m)};
    if (o.timed()) {
      world.AddTimedBox(TimedBox{box, o.from_s, o.until_s});
    } else {
      world.AddStaticBox(box);
    }
  }
}

SensorConfig EffectiveSensors(const SimConfig& sim, std::size_t vehicle) {
  SensorConfig s = sim.vehicles.at(vehicle).sensors;
  if (s.lidar.range_noise_m == 0.0) s.lidar.range_noise_m = sim.variability.LidarRangeNoiseM();
  return s;
}

CommandNoise::CommandNoise(const VariabilityConfig& variability, const VehicleParams& params,
                           std::uint64_t seed, int vehicle)
    : throttle_sigma_(variability.DriveNoiseMps() / params.top_speed_mps),
      steering_sigma_(variability.SteeringNoiseRad() / params.steering_limit_rad),
      rng_(StreamSeed(seed, vehicle, kCommandStream)) {}

VehicleCommand CommandNoise::Apply(const VehicleCommand& command) {
  VehicleCommand out = command;
  if (out.throttle != 0.0) {
    out.throttle = std::clamp(out.throttle + Gaussian(rng_, throttle_sigma_), -1.0, 1.0);
  }
  out.steering = std::clamp(out.steering + Gaussian(rng_, steering_sigma_), -1.0, 1.0);
  return out;
}

}  // namespace autodrive::vehicle_sim
