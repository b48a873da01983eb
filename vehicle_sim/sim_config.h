#pragma once
/// @file
/// The simulator's section of a city file (`sim:`), strict like every config: which cars, where
/// they start, what they are, and how the world is stepped. The SCM carries the section without
/// reading it. Every key is documented in docs/vehicle_sim.md.
///
/// ```yaml
/// sim:
///   seed: 1
///   world: {step_s: 0.002}
///   vehicles:
///     - name: nigel_1                               # devkit topics /autodrive/nigel_1/...
///       spawn: {lane: "r4c1:W>E:0", along_m: 0.3}   # on a lane, facing along it
///     - name: nigel_2
///       spawn: {x_m: 2.5, y_m: 0.35, yaw_rad: 3.1416}
///       params: {top_speed_mps: 0.2}                # VehicleParams: Nigel's figures by default
/// ```

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/config.h"
#include "common/geometry.h"
#include "vehicle_sim/sensors.h"
#include "vehicle_sim/vehicle_params.h"
#include "vehicle_sim/world.h"

namespace autodrive::maps {
struct Map;
}

namespace autodrive::vehicle_sim {

/// Where a car starts: on a lane of the map (facing along it), or at a pose.
struct SpawnConfig {
  std::optional<std::string> lane;  ///< a lane's name, as `autodrive-map info` and map.yaml list
  double along_m = 0.0;             ///< distance of the rear axle along the lane's centreline
  std::optional<double> x_m;        ///< or a pose of the rear axle's middle in the map frame
  std::optional<double> y_m;
  std::optional<double> yaw_rad;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("lane", lane);
    a.Optional("along_m", along_m, config::Range{0.0, 1e4});
    a.Optional("x_m", x_m, config::Range{-1e4, 1e4});
    a.Optional("y_m", y_m, config::Range{-1e4, 1e4});
    a.Optional("yaw_rad", yaw_rad, config::Range{-10.0, 10.0});
  }
  /// Either `lane` (with `along_m`) or all of `x_m`, `y_m`, `yaw_rad`.
  void Validate() const;
  bool operator==(const SpawnConfig&) const = default;
};

struct SimVehicleConfig {
  std::string name;                  ///< `nigel_<n>`: its devkit topics are /autodrive/<name>/...
  std::optional<SpawnConfig> spawn;  ///< default: see `SpawnPoses`
  VehicleParams params;
  SensorConfig sensors;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Optional("spawn", spawn);
    a.Optional("params", params);
    a.Optional("sensors", sensors);
  }
  /// The name must be `nigel_<n>`.
  void Validate() const;
  bool operator==(const SimVehicleConfig&) const = default;
};

struct SimConfig {
  std::uint64_t seed = 1;  ///< every random source of the simulation derives from it
  WorldOptions world;
  /// The cars; without the key, one car `nigel_1` on the map's first lane.
  std::vector<SimVehicleConfig> vehicles{SimVehicleConfig{"nigel_1", std::nullopt, {}, {}}};

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("seed", seed);
    a.Optional("world", world);
    a.Optional("vehicles", vehicles);
  }
  /// Names unique; at least one car.
  void Validate() const;
  bool operator==(const SimConfig&) const = default;
};

/// The simulator's view of a city file: its map path (as the SCM reads it, relative to the city
/// file) and its `sim:` section (defaults when absent).
struct SimCity {
  std::string name;
  std::string map_path;  ///< resolved against the city file's folder
  SimConfig sim;
};
/// Reads `name`, `map` and `sim` of the city file at `path`; other sections belong to other
/// programs and are not read. @throws ConfigError naming the file, line and key.
[[nodiscard]] SimCity LoadSimCity(const std::string& path);

/// Every car's starting pose on `map`: its spawn, or when it has none, the middle of a lane no
/// car took, facing along it: a lane that no intersection starts or ends on a tile no car took
/// if there is one, else such a lane on any tile, else any lane of at least 0.3 m (in the map's
/// order). @throws InputError naming the car for a lane the map does not have, a distance
/// beyond the lane's end, or a map with too few lanes.
[[nodiscard]] std::vector<RigidTransform2> SpawnPoses(const SimConfig& sim, const maps::Map& map);

}  // namespace autodrive::vehicle_sim
