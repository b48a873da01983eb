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

#include <array>
#include <cstdint>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "common/config.h"
#include "common/geometry.h"
#include "common/time.h"
#include "maps/districts.h"
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
  VehicleLookConfig look;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Optional("spawn", spawn);
    a.Optional("params", params);
    a.Optional("sensors", sensors);
    a.Optional("look", look);
  }
  /// The name must be `nigel_<n>`.
  void Validate() const;
  bool operator==(const SimVehicleConfig&) const = default;
};

/// How `autodrive-sim --city` advances time (see service.h and docs/vehicle_sim.md).
enum class SimMode {
  kRealTime,  ///< paced by the wall clock (times real_time_factor)
  kFast,      ///< as fast as the machine goes
  kLockstep,  ///< one control period each time every named controller has answered the last
};
constexpr auto ConfigEnumNames(SimMode) {
  return std::array{std::pair{SimMode::kRealTime, std::string_view{"realtime"}},
                    std::pair{SimMode::kFast, std::string_view{"fast"}},
                    std::pair{SimMode::kLockstep, std::string_view{"lockstep"}}};
}

/// The DDS service's settings (`sim.service` in a city file; `autodrive-sim` options override
/// them).
struct ServiceOptions {
  SimMode mode = SimMode::kRealTime;
  double real_time_factor = 1.0;  ///< simulated seconds per wall second in real-time mode
  Duration control_period = std::chrono::milliseconds(10);
  Duration command_timeout = std::chrono::milliseconds(500);
  std::optional<Duration> duration;  ///< stop after this much simulated time
  /// Lockstep: the controllers that must answer every step (their `step_done` frame ids).
  std::vector<std::string> controllers;
  /// Lockstep: controllers that answer each step before `controllers`, stage by stage, each
  /// stage told the step once the one before answered (common/dds/lockstep.h, "Stages"): e.g.
  /// `[[eye], [lights], [scm]]` so that the SCM decides on the lamps and fleet of the step.
  std::vector<std::vector<std::string>> stages;
  /// SUMO's background traffic (`/autodrive/scm/traffic`) in the world: seen, drawn and
  /// collided with (traffic.h). Off: the topic is not read.
  bool traffic = true;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("mode", mode);
    a.Optional("real_time_factor", real_time_factor, config::Range{0.01, 1000.0});
    a.Optional("control_period_s", control_period,
               config::Range<Duration>{std::chrono::milliseconds(1), std::chrono::seconds(1)});
    a.Optional("command_timeout_s", command_timeout,
               config::Range<Duration>{std::chrono::milliseconds(10), std::chrono::hours(1)});
    a.Optional("duration_s", duration,
               config::Range<Duration>{Duration{0}, std::chrono::hours(24 * 365)});
    a.Optional("controllers", controllers);
    a.Optional("stages", stages);
    a.Optional("traffic", traffic);
  }
  /// Lockstep needs at least one controller (plain or staged); names are unique and not
  /// empty; no stage is empty.
  void Validate() const;
  bool operator==(const ServiceOptions&) const = default;
};

/// An obstacle that is not on the map (the paper's "unmapped obstacles"): a box standing on
/// the ground, from the start or for a while (placed at `from_s`, removed at `until_s`).
struct UnmappedObstacle {
  std::string name;  ///< for the logs and the scenarios' events; may be empty
  double x_m = 0.0;  ///< centre of its footprint, map frame
  double y_m = 0.0;
  double yaw_rad = 0.0;
  double length_m = 0.1;
  double width_m = 0.1;
  double height_m = 0.1;
  Duration from_s{0};               ///< simulated time it is placed at (0: from the start)
  std::optional<Duration> until_s;  ///< simulated time it is removed at (none: it stays)

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("name", name);
    a.Required("x_m", x_m, config::Range{-1e4, 1e4});
    a.Required("y_m", y_m, config::Range{-1e4, 1e4});
    a.Optional("yaw_rad", yaw_rad, config::Range{-10.0, 10.0});
    a.Optional("length_m", length_m, config::Range{0.001, 100.0});
    a.Optional("width_m", width_m, config::Range{0.001, 100.0});
    a.Optional("height_m", height_m, config::Range{0.001, 100.0});
    a.Optional("from_s", from_s,
               config::Range<Duration>{Duration{0}, std::chrono::hours(24 * 365)});
    a.Optional("until_s", until_s,
               config::Range<Duration>{Duration{0}, std::chrono::hours(24 * 365)});
  }
  /// `until_s` after `from_s`.
  void Validate() const;
  /// Whether it stands for a while only (placed after the start or removed).
  [[nodiscard]] bool timed() const { return from_s > Duration{0} || until_s.has_value(); }
  bool operator==(const UnmappedObstacle&) const = default;
};

enum class VariabilityPreset {
  kNone,   ///< every figure 0 unless given
  kPaper,  ///< the paper's parking study (NIGEL.md): the figures below
  /// the paper's behavioural-cloning study (NIGEL.md): the light's intensity and direction and
  /// the car's start varied, with the parking study's command noise
  kCloning,
};
constexpr auto ConfigEnumNames(VariabilityPreset) {
  return std::array{std::pair{VariabilityPreset::kNone, std::string_view{"none"}},
                    std::pair{VariabilityPreset::kPaper, std::string_view{"paper"}},
                    std::pair{VariabilityPreset::kCloning, std::string_view{"cloning"}}};
}

/// A point the random obstacles keep clear of (`sim.variability.keep_clear`).
struct ClearPoint {
  double x_m = 0.0;
  double y_m = 0.0;
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("x_m", x_m, config::Range{-1e4, 1e4});
    a.Required("y_m", y_m, config::Range{-1e4, 1e4});
  }
  bool operator==(const ClearPoint&) const = default;
};

/// Variability of the simulated world (`sim.variability`), drawn from the simulation's seed.
/// A preset gives every figure a value; a figure given here overrides the preset's.
struct VariabilityConfig {
  VariabilityPreset preset = VariabilityPreset::kNone;
  /// Gaussian noise on each drive command, as a speed: σ / top speed in throttle units.
  /// Paper: 0.013 m/s.
  std::optional<double> drive_noise_mps;
  /// Gaussian noise on each steering command's wheel angle. Paper: 0.018 (NIGEL.md writes
  /// rad/s; the actuator here takes an angle, so it is applied as rad to the angle commanded).
  std::optional<double> steering_noise_rad;
  /// Each wall module (map obstacle of kind "wall") moved by N(0, σ) in x and y and turned by
  /// N(0, σ) about its centre. Paper: 0.01 m and 0.087 rad.
  std::optional<double> wall_position_noise_m;
  std::optional<double> wall_heading_noise_rad;
  /// LIDAR range noise for every car whose own `sensors.lidar.range_noise_m` is 0.
  /// Paper: 0.025 m.
  std::optional<double> lidar_range_noise_m;
  /// Unmapped obstacles added to the world where given.
  std::vector<UnmappedObstacle> obstacles;
  /// And this many more at random (0.1 m square, 0.3 m tall: above the LIDAR's plane; at a
  /// seeded random place and heading on the map, outside every mapped obstacle, off every lane
  /// and path through an intersection, and at least 0.5 m from every car's start). Paper: 3.
  std::optional<int> random_obstacles;
  /// Points the random obstacles keep 0.5 m from, as from the cars' starts: the scenario runner
  /// gives its cars' goal poses (a bay an obstacle filled could not be parked in).
  std::vector<ClearPoint> keep_clear;
  /// The lab's light, drawn once per run for every camera's film: its intensity scaled by a
  /// factor uniform in [1 - s, 1 + s] (the film's `exposure`: the renderer keeps the ground's
  /// colours in any light, so the brightness a camera records is its exposure). Cloning: 0.4.
  std::optional<double> light_intensity_spread;
  /// The directional light's azimuth turned by an angle uniform in [-s, s] and its elevation
  /// moved by one uniform in [-s/4, s/4] (kept in [0.2, 1.5] rad). Cloning: pi (any azimuth).
  std::optional<double> light_direction_spread_rad;
  /// Each car's start (its `spawn`, or the default one) moved by N(0, σ) in x and y and turned
  /// by N(0, σ). Cloning: 0.03 m and 0.087 rad.
  std::optional<double> start_position_noise_m;
  std::optional<double> start_heading_noise_rad;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("preset", preset);
    a.Optional("drive_noise_mps", drive_noise_mps, config::Range{0.0, 10.0});
    a.Optional("steering_noise_rad", steering_noise_rad, config::Range{0.0, 1.0});
    a.Optional("wall_position_noise_m", wall_position_noise_m, config::Range{0.0, 1.0});
    a.Optional("wall_heading_noise_rad", wall_heading_noise_rad, config::Range{0.0, 3.2});
    a.Optional("lidar_range_noise_m", lidar_range_noise_m, config::Range{0.0, 10.0});
    a.Optional("obstacles", obstacles);
    a.Optional("random_obstacles", random_obstacles, config::Range{0, 1000});
    a.Optional("keep_clear", keep_clear);
    a.Optional("light_intensity_spread", light_intensity_spread, config::Range{0.0, 0.95});
    a.Optional("light_direction_spread_rad", light_direction_spread_rad,
               config::Range{0.0, 3.1416});
    a.Optional("start_position_noise_m", start_position_noise_m, config::Range{0.0, 1.0});
    a.Optional("start_heading_noise_rad", start_heading_noise_rad, config::Range{0.0, 3.2});
  }
  bool operator==(const VariabilityConfig&) const = default;

  /// The figures in effect: given, else the preset's.
  [[nodiscard]] double DriveNoiseMps() const;
  [[nodiscard]] double SteeringNoiseRad() const;
  [[nodiscard]] double WallPositionNoiseM() const;
  [[nodiscard]] double WallHeadingNoiseRad() const;
  [[nodiscard]] double LidarRangeNoiseM() const;
  [[nodiscard]] int RandomObstacles() const;
  [[nodiscard]] double LightIntensitySpread() const;
  [[nodiscard]] double LightDirectionSpreadRad() const;
  [[nodiscard]] double StartPositionNoiseM() const;
  [[nodiscard]] double StartHeadingNoiseRad() const;
};

struct SimConfig {
  std::uint64_t seed = 1;  ///< every random source of the simulation derives from it
  WorldOptions world;
  /// The cars; without the key, one car `nigel_1` on the map's first lane.
  std::vector<SimVehicleConfig> vehicles{SimVehicleConfig{"nigel_1", std::nullopt, {}, {}, {}}};

  VariabilityConfig variability;
  ServiceOptions service;
  /// Overhead cameras (`/autodrive/cameras/<name>/image`).
  std::vector<OverheadCameraConfig> cameras;
  /// Reference tags fixed on the ground (what the Eye registers its cameras with).
  std::vector<GroundTag> ground_tags;
  RenderConfig render;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("seed", seed);
    a.Optional("world", world);
    a.Optional("vehicles", vehicles);
    a.Optional("variability", variability);
    a.Optional("service", service);
    a.Optional("cameras", cameras);
    a.Optional("ground_tags", ground_tags);
    a.Optional("render", render);
  }
  /// Names unique (cars, cameras, named obstacles); at least one car; tag ids unique within a
  /// family (roof and ground tags).
  void Validate() const;
  bool operator==(const SimConfig&) const = default;
};

/// The simulator's view of a city file: its map path (as the SCM reads it, relative to the city
/// file) and its `sim:` section (defaults when absent).
struct SimCity {
  std::string name;
  std::string map_path;  ///< resolved against the city file's folder
  SimConfig sim;
  /// The city's `districts:` section (docs/districts.md): empty when it has none.
  std::vector<maps::DistrictConfig> districts;
};
/// Reads `name`, `map`, `sim` and `districts` of the city file at `path`, and of its `eye` section
/// the cars' roof tag mountings (`camera::LoadCityRoofTagMounts`): a car the Eye lists gets the
/// Eye's mounting in its `look` (its own `look` may not give one: one declaration for both); other
/// sections belong to other programs and are not read. Relative paths (the map, lens
/// calibration files) are resolved against the city file's folder.
/// @throws ConfigError naming the file, line and key.
[[nodiscard]] SimCity LoadSimCity(const std::string& path);

/// Every car's starting pose on `map`: its spawn, or when it has none, the middle of a lane no
/// car took, facing along it: a lane that no intersection starts or ends on a tile no car took
/// if there is one, else such a lane on any tile, else any lane of at least 0.3 m (in the map's
/// order). @throws InputError naming the car for a lane the map does not have, a distance
/// beyond the lane's end, or a map with too few lanes.
[[nodiscard]] std::vector<RigidTransform2> SpawnPoses(const SimConfig& sim, const maps::Map& map);

/// A seed for stream `stream` of car `vehicle` (or of the world, vehicle -1) from the
/// simulation's seed: streams do not overlap, and one's draws never shift another's.
[[nodiscard]] std::uint64_t StreamSeed(std::uint64_t seed, int vehicle, int stream);
/// A draw from N(0, sigma); draws nothing when sigma is 0, so that noise turned off leaves no
/// trace in the stream.
[[nodiscard]] double Gaussian(std::mt19937_64& rng, double sigma);
/// The streams of the variability's draws: the world's (vehicle -1) and each car's (a car's
/// streams 1-3 are its sensors', sensors.cpp).
inline constexpr int kWallStream = 1;
inline constexpr int kObstacleStream = 2;
inline constexpr int kLightStream = 3;
inline constexpr int kCommandStream = 4;
inline constexpr int kStartStream = 5;
inline constexpr int kPerturbationStream = 6;

/// The look of car `i` of `sim` with its defaults filled in: colour from the palette, tag
/// tag36h11 id n for `nigel_<n>` (none with `roof_tag: false`), tag height the body's height.
[[nodiscard]] VehicleLook EffectiveLook(const SimConfig& sim, std::size_t i);

}  // namespace autodrive::vehicle_sim
