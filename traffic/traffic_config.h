#pragma once
/// @file
/// The co-simulation's configuration: the `traffic` section of a city file (docs/traffic.md,
/// "The traffic section"). Sizes and speeds are the lab's (metres, m/s); times are lab seconds.

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "common/config.h"

namespace autodrive::traffic {

using std::chrono::nanoseconds;

/// A share of the background vehicles of one SUMO vehicle type.
struct TypeShare {
  std::string type = "nigel";  ///< nigel, bus, emergency, or a type of a route file
  double weight = 1.0;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("type", type);
    a.Required("weight", weight, config::Range{0.0, 1e6});
  }
  bool operator==(const TypeShare&) const = default;
};

/// Vehicles entering at one lane at a steady rate.
struct FlowConfig {
  std::string from;  ///< the map lane they enter on ("r0c2:W>E:0")
  /// Where they leave (a map lane); empty: they keep circulating, like every random vehicle.
  std::string to;
  double per_hour = 60.0;
  std::string type = "nigel";
  int count = 0;           ///< vehicles in all (0: no limit)
  nanoseconds begin_s{0};  ///< first departure after the start

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("from", from);
    a.Optional("to", to);
    a.Required("per_hour", per_hour, config::Range{0.001, 1e6});
    a.Optional("type", type);
    a.Optional("count", count, config::Range{0, 1000000});
    a.Optional("begin_s", begin_s,
               config::Range<nanoseconds>{nanoseconds(0), std::chrono::hours(24 * 365)});
  }
  bool operator==(const FlowConfig&) const = default;
};

/// Where the lab's own cars come from, to be placed in SUMO every step.
struct LabCarsConfig {
  /// auto: the simulator's ground truth when the city has a `sim` section, else the SCM's fleet
  /// state; ground_truth (`/autodrive/<car>/ground_truth`), eye (`/autodrive/eye/fleet`), fleet
  /// (`/autodrive/scm/fleet`: the SCM's view, from the Eye or the cars' ips) or none.
  std::string source = "auto";
  /// Ground truth: the cars (default: the `sim` section's).
  std::vector<std::string> vehicles;
  /// A car not heard from for this long leaves SUMO (it comes back when heard again).
  nanoseconds staleness_s = std::chrono::seconds(1);
  /// The middle of the car's body ahead of its origin (the middle of its rear axle): Nigel's.
  double body_centre_ahead_m = 0.07077;
  /// A car farther than this from every lane is not on the road network: it leaves SUMO.
  double max_lane_distance_m = 0.25;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("source", source, config::OneOf{{"auto", "ground_truth", "eye", "fleet", "none"}});
    a.Optional("vehicles", vehicles);
    a.Optional("staleness_s", staleness_s,
               config::Range<nanoseconds>{std::chrono::milliseconds(10), std::chrono::minutes(1)});
    a.Optional("body_centre_ahead_m", body_centre_ahead_m, config::Range{-1.0, 1.0});
    a.Optional("max_lane_distance_m", max_lane_distance_m, config::Range{0.01, 10.0});
  }
  bool operator==(const LabCarsConfig&) const = default;
};

/// How SUMO runs.
struct SumoRunConfig {
  /// 0: SUMO inside this process (libsumo). Else SUMO runs as a TraCI server on this port, so
  /// that sumo-gui can show it and further TraCI clients can attach.
  int traci_port = 0;
  int clients = 1;                ///< TraCI clients in all, this one included
  std::string binary = "sumo";    ///< TraCI: sumo or sumo-gui (a name on PATH or a path)
  std::vector<std::string> args;  ///< further SUMO options, appended

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("traci_port", traci_port, config::Range{0, 65535});
    a.Optional("clients", clients, config::Range{1, 64});
    a.Optional("binary", binary);
    a.Optional("args", args);
  }
  bool operator==(const SumoRunConfig&) const = default;
};

/// How the lamps the lights report become SUMO's link states.
struct LightsConfig {
  /// A head that went dark less than this ago and shows red (yellow) again is flashing: its
  /// movements are all-way stops (yield). The lights flash at 1 Hz: half a period is 0.5 s.
  nanoseconds flash_window_s = std::chrono::milliseconds(750);

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("flash_window_s", flash_window_s,
               config::Range<nanoseconds>{std::chrono::milliseconds(50), std::chrono::seconds(10)});
  }
  bool operator==(const LightsConfig&) const = default;
};

/// The `traffic` section.
struct TrafficConfig {
  std::uint64_t seed = 1;                              ///< SUMO's seed and the demand's
  nanoseconds step_s = std::chrono::milliseconds(50);  ///< SUMO's step (20 Hz)
  /// Background vehicles placed at random on the network at the start; they keep circulating
  /// (a random walk over the lane graph, extended as they go) and never leave.
  int vehicles = 0;
  std::vector<TypeShare> mix{TypeShare{}};  ///< their types
  std::vector<FlowConfig> flows;
  /// SUMO route files, used as they are (their vehicles arrive where their routes end).
  std::vector<std::string> route_files;
  double speed_mps = 0.25;  ///< every road's speed limit
  LabCarsConfig lab_cars;
  SumoRunConfig sumo;
  LightsConfig lights;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("seed", seed);
    a.Optional("step_s", step_s,
               config::Range<nanoseconds>{std::chrono::milliseconds(1), std::chrono::seconds(1)});
    a.Optional("vehicles", vehicles, config::Range{0, 1000000});
    a.Optional("mix", mix);
    a.Optional("flows", flows);
    a.Optional("route_files", route_files);
    a.Optional("speed_mps", speed_mps, config::Range{0.01, 10.0});
    a.Optional("lab_cars", lab_cars);
    a.Optional("sumo", sumo);
    a.Optional("lights", lights);
  }
  bool operator==(const TrafficConfig&) const = default;
};

/// The traffic section of the city file at `path` (defaults when it has none), with route
/// files resolved against the file's folder. @throws ConfigError naming the file, line and key.
[[nodiscard]] TrafficConfig LoadTrafficConfig(const std::filesystem::path& path);

}  // namespace autodrive::traffic
