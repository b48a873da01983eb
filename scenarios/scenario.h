#pragma once
/// @file
/// A scenario file (docs/scenarios.md): a city, the cars and the programs that drive them,
/// their spawns, routes and goals, SUMO's demand, the simulator's noise and seed, timed events,
/// the end and the pass thresholds. Strict like every config: a refusal names the file, line
/// and key.
///
/// ```yaml
/// name: crossing_red_light
/// description: a car drives through the Driving School's crossing ignoring its light
/// city: ../cities/driving_school.yaml
/// seed: 1
/// time_limit_s: 40
/// vehicles:
///   - name: nigel_1
///     spawn: {lane: "r1c0:W>E:0", along_m: 0.3}
///     route: ["r1c0:W>E:0", "r1c2:W>E:0"]
///     agent: {driver: [--ignore-lights]}
/// expect: {red_light_violations: "== 0"}
/// ```

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/config.h"
#include "common/time.h"
#include "vehicle_sim/sim_config.h"

namespace autodrive::scenarios {

/// The program that drives one car: the example lane driver with extra arguments, or a
/// program of the user's. Words may hold `{city}` (the composed city file), `{vehicle}` (the
/// car's name), `{route}` (its route's lanes, comma-separated), `{lockstep}` (the controller
/// name it must answer the simulator's steps with), `{run}` (the run folder) and `{scenario}`
/// (the scenario file).
struct AgentSpec {
  /// The example driver (`autodrive-example-driver`) for this car alone, on its route, in
  /// lockstep, with these arguments added (e.g. `[--ignore-lights]`).
  std::optional<std::vector<std::string>> driver;
  /// Or a program and its arguments (a name in the build's bin folder, on PATH, or a path);
  /// it must answer the lockstep as `{lockstep}` (docs/vehicle_sim.md, "Lockstep").
  std::vector<std::string> command;
  std::vector<std::string> env;  ///< NAME=value entries added to its environment

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("driver", driver);
    a.Optional("command", command);
    a.Optional("env", env);
  }
  /// Exactly one of `driver` and `command`.
  void Validate() const;
  bool operator==(const AgentSpec&) const = default;
};

/// A pose to reach instead of a route's end (a parking bay): the rear axle's, map frame. It is
/// reached when the car stands there within both tolerances.
struct GoalPoseSpec {
  double x_m = 0.0;
  double y_m = 0.0;
  double yaw_rad = 0.0;
  double tolerance_m = 0.05;
  double tolerance_rad = 0.0873;  ///< 5°

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("x_m", x_m, config::Range{-1e4, 1e4});
    a.Required("y_m", y_m, config::Range{-1e4, 1e4});
    a.Required("yaw_rad", yaw_rad, config::Range{-7.0, 7.0});
    a.Optional("tolerance_m", tolerance_m, config::Range{0.001, 10.0});
    a.Optional("tolerance_rad", tolerance_rad, config::Range{0.001, 3.2});
  }
  bool operator==(const GoalPoseSpec&) const = default;
};

struct VehicleSpec {
  std::string name;  ///< `nigel_<n>`
  vehicle_sim::SpawnConfig spawn;
  /// Lanes to drive, in order (each reachable from the one before by a movement or a
  /// successor); the goal is the end of the last. Empty: no route (route completion is not
  /// measured, the car has no goal).
  std::vector<std::string> route;
  /// The route driven this many times over (a closed loop: its first lane follows its last);
  /// the goal is the end of the last lap, and the report gives each lap's time.
  int laps = 1;
  /// The goal is reached when the car's front is within this distance of the last lane's end.
  double goal_tolerance_m = 0.15;
  /// Or a goal pose (no route then): route completion is 1 once it is reached, else 0.
  std::optional<GoalPoseSpec> goal;
  /// Without an agent the car stands where it spawned (no commands: held still).
  std::optional<AgentSpec> agent;
  /// The car's sensors (the simulator's `sensors` of a car, every key optional over the
  /// defaults), replacing the base city's for this car: a front camera turned on, say.
  std::optional<vehicle_sim::SensorConfig> sensors;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Required("spawn", spawn);
    a.Optional("route", route);
    a.Optional("laps", laps, config::Range{1, 1000});
    a.Optional("goal_tolerance_m", goal_tolerance_m, config::Range{0.01, 10.0});
    a.Optional("goal", goal);
    a.Optional("agent", agent);
    a.Optional("sensors", sensors);
  }
  void Validate() const;
  /// The lanes driven: the route, `laps` times over.
  [[nodiscard]] std::vector<std::string> DrivenRoute() const;
  bool operator==(const VehicleSpec&) const = default;
};

/// What triggers an event: a car's front coming within `within_m` of a point.
struct TriggerSpec {
  std::string vehicle;  ///< one of the scenario's cars
  double x_m = 0.0;     ///< the point, map frame
  double y_m = 0.0;
  double within_m = 0.3;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("vehicle", vehicle);
    a.Required("x_m", x_m, config::Range{-1e4, 1e4});
    a.Required("y_m", y_m, config::Range{-1e4, 1e4});
    a.Optional("within_m", within_m, config::Range{0.001, 1e4});
  }
  bool operator==(const TriggerSpec&) const = default;
};

/// What happens at a time, or when a car comes somewhere.
struct EventSpec {
  /// Simulated time since the start at which it happens; with `when`, the earliest time it
  /// may (default 0: from the start).
  Duration at_s{0};
  /// A trigger: the event happens at the first step (at or after `at_s`) at which the car's
  /// front is within reach of the point (ground truth, as the runner records it). For the
  /// events the runner sends (not place, remove, camera_lost, camera_back or surge, which the
  /// simulator and SUMO apply on their own clocks from `at_s`).
  std::optional<TriggerSpec> when;
  /// `mode` (an intersection put into `flash`, `dark` or back to `auto`), `plan` (an
  /// intersection's plan chosen by name, or `auto` for its schedule), `preempt` or `priority`
  /// (a V2I request for `vehicle` at `intersection`, from the lane it is on), `cancel` (that
  /// vehicle's request cancelled); on a simulated light head (`/autodrive/sim/fault`): `lamp`
  /// (its `lamp` burns out, sticks on or is repaired: `fault`), `unplug` (the head goes
  /// offline, its cable pulled), `plug` (back online); on a light host's DDS link with the SCM:
  /// `link_cut`, `link_restore` (`host`); in the simulator's world: `place`, `remove` (the
  /// scenario's unmapped `obstacle` of that name), `camera_lost`, `camera_back` (the overhead
  /// `camera` of that name sends no frame between them); in SUMO's demand: `surge` (`count`
  /// more vehicles entering at lane `from` at `per_hour`, to lane `to` or circulating, of
  /// `type`).
  std::string action;
  std::string intersection;  ///< the map's intersection name
  std::string mode;          ///< action mode: flash | dark | auto
  std::string plan;          ///< action plan: a plan of the intersection, or auto
  std::string vehicle;       ///< actions preempt, priority, cancel
  int head = 0;              ///< actions lamp, unplug, plug: the head (`signal_<head>`)
  std::string lamp;          ///< action lamp: red | yellow | green
  std::string fault;         ///< action lamp: burnt_out | stuck_on | repaired
  std::string host;          ///< actions link_cut, link_restore: the light host's name
  std::string obstacle;      ///< actions place, remove: the name of one of `obstacles`
  std::string camera;        ///< actions camera_lost, camera_back: an overhead camera's name
  std::string from;          ///< action surge: the map lane they enter at
  std::string to;            ///< action surge: the map lane they leave at (empty: circulate)
  double per_hour = 0;       ///< action surge: the rate they enter at
  int count = 0;             ///< action surge: how many
  std::string type;          ///< action surge: SUMO type (traffic.mix's; empty: nigel)

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("at_s", at_s, config::Range<Duration>{Duration{0}, std::chrono::hours(24)});
    a.Optional("when", when);
    a.Required("action", action,
               config::OneOf{{"mode", "plan", "preempt", "priority", "cancel", "lamp", "unplug",
                              "plug", "link_cut", "link_restore", "place", "remove", "camera_lost",
                              "camera_back", "surge"}});
    a.Optional("intersection", intersection);
    a.Optional("mode", mode, config::OneOf{{"", "flash", "dark", "auto"}});
    a.Optional("plan", plan);
    a.Optional("vehicle", vehicle);
    a.Optional("head", head, config::Range{1, 1000000});
    a.Optional("lamp", lamp, config::OneOf{{"", "red", "yellow", "green"}});
    a.Optional("fault", fault, config::OneOf{{"", "burnt_out", "stuck_on", "repaired"}});
    a.Optional("host", host);
    a.Optional("obstacle", obstacle);
    a.Optional("camera", camera);
    a.Optional("from", from);
    a.Optional("to", to);
    a.Optional("per_hour", per_hour, config::Range{0.0, 1e6});
    a.Optional("count", count, config::Range{0, 100000});
    a.Optional("type", type);
  }
  /// The keys each action needs, and no other.
  void Validate() const;
  bool operator==(const EventSpec&) const = default;
};

/// SUMO's background traffic: the base city's `traffic` section with these figures.
struct TrafficSpec {
  int vehicles = 0;  ///< 0: no background traffic (the section is dropped)

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("vehicles", vehicles, config::Range{0, 10000});
  }
  bool operator==(const TrafficSpec&) const = default;
};

/// When the run ends (besides `time_limit_s`).
struct EndSpec {
  /// End once every car with a route has reached its goal and stands still there (and at
  /// least one car has a route).
  bool goals_reached = true;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("goals_reached", goals_reached);
  }
  bool operator==(const EndSpec&) const = default;
};

struct Scenario {
  std::string name;
  std::string description;
  std::string city;  ///< the base city file, relative to the scenario file
  std::uint64_t seed = 1;
  vehicle_sim::VariabilityPreset noise = vehicle_sim::VariabilityPreset::kNone;
  Duration time_limit_s = std::chrono::seconds(60);
  /// The lockstep's step (the simulator's control period): every controller, the runner
  /// included, answers once per step; the logs have a row per car per step.
  Duration step_s = std::chrono::milliseconds(20);
  std::vector<VehicleSpec> vehicles;
  TrafficSpec traffic;
  /// The Eye in the loop: the base city's `eye` section runs, in lockstep, on the simulator's
  /// overhead cameras, and the SCM's fleet takes its poses (the cars' `ips` the fall-back).
  bool eye = false;
  /// Unmapped obstacles on the track: from the start, or from a `place` event (those a
  /// `place` event names) until a `remove` event names them. Their `from_s` and `until_s` are
  /// the events' (refused here: the events say when).
  std::vector<vehicle_sim::UnmappedObstacle> obstacles;
  std::vector<EventSpec> events;
  EndSpec end;
  /// Pass thresholds: a run-level metric (docs/scenarios.md, "Metrics") and a comparison,
  /// e.g. `collisions: "== 0"`, `route_completion: ">= 1"`.
  std::map<std::string, std::string> expect;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Optional("description", description);
    a.Required("city", city);
    a.Optional("seed", seed);
    a.Optional("noise", noise);
    a.Optional("time_limit_s", time_limit_s,
               config::Range<Duration>{std::chrono::milliseconds(100), std::chrono::hours(24)});
    a.Optional(
        "step_s", step_s,
        config::Range<Duration>{std::chrono::milliseconds(5), std::chrono::milliseconds(100)});
    a.Required("vehicles", vehicles);
    a.Optional("traffic", traffic);
    a.Optional("eye", eye);
    a.Optional("obstacles", obstacles);
    a.Optional("events", events);
    a.Optional("end", end);
    a.Optional("expect", expect);
  }
  /// A name of letters, digits, '_' and '-'; cars named once, at least one; obstacles named
  /// once where named, each placed and removed at most once, removed after it is placed;
  /// expectations name known metrics with a valid comparison.
  void Validate() const;
  bool operator==(const Scenario&) const = default;

  /// The obstacles as the simulator takes them: `from_s` and `until_s` from the events.
  [[nodiscard]] std::vector<vehicle_sim::UnmappedObstacle> TimedObstacles() const;
  /// Each camera that `camera_lost` names: lost from that time until its `camera_back` (none:
  /// to the end). @throws InputError for a camera lost or back twice, back before it is lost.
  [[nodiscard]] std::map<std::string, std::pair<Duration, std::optional<Duration>>> CameraOutages()
      const;
};

/// A pass threshold: `<op> <number>` with op one of `<`, `<=`, `==`, `>=`, `>`, `!=`.
struct Expectation {
  std::string op;
  double value = 0.0;
  [[nodiscard]] bool Holds(double x) const;
};
/// @throws InputError for text that is not `<op> <number>`.
[[nodiscard]] Expectation ParseExpectation(std::string_view text);

/// The run-level metrics an `expect` may name, in the order reports list them.
[[nodiscard]] const std::vector<std::string_view>& RunMetricNames();

/// Loads and checks a scenario file; its `city` is resolved against the file's folder.
/// @throws ConfigError naming the file, line and key.
[[nodiscard]] Scenario LoadScenario(const std::filesystem::path& path);

/// "FILE:LINE:COLUMN: KEYPATH: message" for the node at `keypath` of the YAML file (path
/// elements: map keys, or list indices as "[i]"); the file's name alone when it is absent.
[[nodiscard]] std::string LocateInFile(const std::filesystem::path& file,
                                       const std::vector<std::string>& keypath,
                                       const std::string& message);

}  // namespace autodrive::scenarios
