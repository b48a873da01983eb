#pragma once
/// @file
/// The simulated world's variability (`sim.variability`, see `VariabilityConfig`): wall modules
/// moved and turned a little, unmapped obstacles, noise on the cars' commands and LIDAR ranges.
/// Every draw comes from the simulation's seed, so a run is reproduced by its city file.

#include <cstdint>
#include <random>
#include <span>
#include <vector>

#include "maps/map.h"
#include "vehicle_sim/sim_config.h"
#include "vehicle_sim/vehicle.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim {

/// A copy of `map` whose wall modules (obstacles of kind "wall") are each moved by N(0,
/// `position_sigma_m`) in x and y and turned by N(0, `heading_sigma_rad`) about their centroid.
/// Draws in the map's order from `seed`; nothing changes when both sigmas are 0.
[[nodiscard]] maps::Map PerturbWalls(const maps::Map& map, double position_sigma_m,
                                     double heading_sigma_rad, std::uint64_t seed);

/// The map as the simulator's world has it: `PerturbWalls` with the configured figures.
[[nodiscard]] maps::Map SimulatedMap(const SimConfig& sim, const maps::Map& map);

/// The unmapped obstacles of `sim`: those listed, then the random ones (drawn from the seed;
/// see `VariabilityConfig::random_obstacles`), placed on `map` away from `spawns` (every car's
/// starting pose). @throws InputError when no place is found for a random one.
[[nodiscard]] std::vector<UnmappedObstacle> UnmappedObstacles(
    const SimConfig& sim, const maps::Map& map, std::span<const RigidTransform2> spawns);

/// Adds `obstacles` to `world`: static boxes, or timed boxes for those placed after the start
/// or removed (`UnmappedObstacle::timed`).
void AddObstacles(std::span<const UnmappedObstacle> obstacles, World& world);

/// `film` in the lab's light of this run: the variability's light intensity and direction
/// (`light_intensity_spread`, `light_direction_spread_rad`), drawn once from the seed, so every
/// camera of a run sees the same light. `film` itself when both spreads are 0.
[[nodiscard]] FilmOptions LitFilm(const FilmOptions& film, const SimConfig& sim);

/// Car `vehicle`'s sensors with the variability's LIDAR range noise where the car sets none.
[[nodiscard]] SensorConfig EffectiveSensors(const SimConfig& sim, std::size_t vehicle);

/// Noise on one car's commands: each `Apply` adds a Gaussian draw to the throttle (σ: drive
/// noise / top speed) and to the steering (σ: steering noise / steering limit), in the
/// normalised units of the devkit topics, clamped to [-1, 1]. A zero throttle stays zero (the
/// firmware holds the car); so does a command with both sigmas 0, which draws nothing.
class CommandNoise {
 public:
  CommandNoise(const VariabilityConfig& variability, const VehicleParams& params,
               std::uint64_t seed, int vehicle);
  [[nodiscard]] VehicleCommand Apply(const VehicleCommand& command);

 private:
  double throttle_sigma_;
  double steering_sigma_;
  std::mt19937_64 rng_;
};

}  // namespace autodrive::vehicle_sim
