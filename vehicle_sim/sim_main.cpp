// autodrive-sim: the simulator of Nigel. With --city it runs the city's cars as a DDS service
// (the devkit topics, /clock, the cameras); `replay` runs one car headless from a command file;
// `render` writes one camera's frames and the ground truth as an offline data set; `record` a
// driving data set for behavioural cloning.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <exception>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/dds/participant.h"
#include "common/dds/program_options.h"
#include "common/error.h"
#include "common/ids.h"
#include "common/logging.h"
#include "common/shutdown.h"
#include "maps/district_domains.h"
#include "maps/map.h"
#include "maps/map_io.h"
#include "vehicle_sim/dataset.h"
#include "vehicle_sim/lane_driver.h"
#include "vehicle_sim/replay.h"
#include "vehicle_sim/service.h"
#include "vehicle_sim/sim_config.h"
#include "vehicle_sim/variability.h"
#include "vehicle_sim/world.h"

namespace {

using namespace autodrive;
using namespace autodrive::vehicle_sim;

int Replay(const std::string& city_path, const std::string& vehicle_name,
           const std::string& commands_path, const std::string& out_path, double log_rate_hz,
           bool quiet) {
  const SimCity city = LoadSimCity(city_path);
  const std::vector<TimedCommand> commands = ReadCommandCsv(commands_path);
  const maps::Map map = maps::LoadMapOrLayout(city.map_path);
  const std::vector<RigidTransform2> spawns = SpawnPoses(city.sim, map);
  int index = -1;
  std::string names;
  for (std::size_t i = 0; i < city.sim.vehicles.size(); ++i) {
    if (city.sim.vehicles[i].name == vehicle_name) index = static_cast<int>(i);
    names += (names.empty() ? "" : ", ") + city.sim.vehicles[i].name;
  }
  AUTODRIVE_THROW_UNLESS(index >= 0, city_path << ": no vehicle '" << vehicle_name
                                               << "' in the sim section (it has " << names << ")");
  // The replayed car alone in the map's world (the others would only stand in its way), with
  // the variability of the world (walls, obstacles) but no command noise: a replay is compared
  // with the car's own log.
  World world(SimulatedMap(city.sim, map), city.sim.world);
  AddObstacles(UnmappedObstacles(city.sim, map, spawns), world);
  world.AddVehicle(city.sim.vehicles[static_cast<std::size_t>(index)].params,
                   spawns[static_cast<std::size_t>(index)]);
  std::ofstream out(out_path, std::ios::binary);
  AUTODRIVE_THROW_UNLESS(out.good(), out_path << ": cannot write the log");
  ReplayOptions options;
  options.log_period = FromSeconds(1.0 / log_rate_hz);
  // On a terminal the progress line is rewritten every simulated second; in a log, a line every
  // ten.
  const bool tty = isatty(fileno(stderr)) != 0;
  const auto progress = [&](Duration done, Duration total) {
    const auto whole = static_cast<long long>(ToSeconds(done));
    if (quiet || (!tty && whole % 10 != 0)) return;
    std::fprintf(stderr, "%sreplay: %lld / %.0f s simulated%s", tty ? "\r" : "", whole,
                 ToSeconds(total), tty ? "" : "\n");
  };
  RunReplay(world, 0, commands, options, out, progress);
  out.close();
  AUTODRIVE_THROW_UNLESS(!out.fail(), out_path << ": writing the log failed");
  if (!quiet) {
    std::fprintf(stderr, "%sreplay: %zu commands over %.3f s, %lld steps of %.4g s, log %s\n",
                 tty ? "\r" : "", commands.size(), ToSeconds(commands.back().time),
                 static_cast<long long>(world.steps()), ToSeconds(world.options().step),
                 out_path.c_str());
  }
  return 0;
}

// The built-in driver's options for car `i` of the city: its own figures.
DriverOptions CarDriverOptions(const SimCity& city, std::size_t i) {
  DriverOptions o;
  const VehicleParams& p = city.sim.vehicles[i].params;
  o.seed = city.sim.seed + i;
  o.wheelbase_m = p.wheelbase_m;
  o.steering_limit_rad = p.steering_limit_rad;
  o.front_overhang_m = p.body_centre_ahead_of_rear_axle_m + p.body_length_m / 2;
  return o;
}

// The built-in driver's decision for car `car` on its ground truth, its LIDAR and the lamps.
DriverDecision DriveOnTruth(LaneDriver& driver, const World& world, std::size_t car,
                            std::span<const float> lidar, std::span<const HeadLamps> lamps,
                            Duration now) {
  const VehicleState& s = world.State(static_cast<int>(car));
  return driver.Step(
      RigidTransform2::FromXyYaw(s.X_MV.translation().x(), s.X_MV.translation().y(),
                                 YawFromQuaternion(s.X_MV.rotation())),
      [&](SignalHeadId h) -> std::optional<std::int32_t> {
        for (const HeadLamps& l : lamps) {
          if (l.head == h) return l.green ? 3 : l.yellow ? 2 : 1;
        }
        return std::nullopt;
      },
      lidar, now);
}

// A data set's progress on stderr: rewritten on a terminal, a line every 100 frames in a log.
std::function<void(int, int)> DatasetProgress(const char* what, bool quiet) {
  const bool tty = isatty(fileno(stderr)) != 0;
  return [=](int done, int total) {
    if (quiet || (!tty && done % 100 != 0)) return;
    std::fprintf(stderr, "%s%s: %d / %d frames%s", tty ? "\r" : "", what, done, total,
                 tty ? "" : "\n");
  };
}

int Render(const std::string& city_path, const DatasetOptions& options,
           const std::string& commands_path, const std::string& commanded_vehicle, bool quiet) {
  const SimCity city = LoadSimCity(city_path);
  const maps::Map map = maps::LoadMapOrLayout(city.map_path);
  // The built-in driver for every car (the example lane driver, on the car's ground truth and
  // LIDAR, with the fixed-time lamps), or the command file for one of them.
  std::vector<vehicle_sim::LaneDriver> drivers;
  for (std::size_t i = 0; i < city.sim.vehicles.size(); ++i) {
    drivers.emplace_back(map, CarDriverOptions(city, i));
  }
  std::vector<TimedCommand> commands;
  std::optional<std::size_t> commanded;
  if (!commands_path.empty()) {
    commands = ReadCommandCsv(commands_path);
    for (std::size_t i = 0; i < city.sim.vehicles.size(); ++i) {
      if (city.sim.vehicles[i].name == commanded_vehicle) commanded = i;
    }
    AUTODRIVE_THROW_UNLESS(
        commanded, city_path << ": no vehicle '" << commanded_vehicle << "' in the sim section");
  }
  std::size_t next_command = 0;
  VehicleCommand held;
  const DatasetDriver driver = [&](std::size_t car, const World& world,
                                   std::span<const float> lidar, std::span<const HeadLamps> lamps,
                                   Duration now) -> VehicleCommand {
    if (commanded && car == *commanded) {
      while (next_command < commands.size() && commands[next_command].time <= now) {
        held = commands[next_command++].command;
      }
      return held;
    }
    const DriverDecision d = DriveOnTruth(drivers[car], world, car, lidar, lamps, now);
    return {d.throttle, d.steering};
  };
  const DatasetSummary summary =
      RenderDataset(city, map, options, driver, DatasetProgress("render", quiet));
  if (!quiet) {
    std::fprintf(stderr,
                 "%srender: %d frames of %s (%.1f ms each) and %zu ground-truth rows in %s\n",
                 isatty(fileno(stderr)) != 0 ? "\r" : "", summary.frames, options.camera.c_str(),
                 summary.render_ms_mean, summary.rows, options.out_dir.string().c_str());
  }
  return 0;
}

// `record`: a driving data set for behavioural cloning (docs/vehicle_sim.md, "Driving data
// sets"): one car alone on the map, driven by the built-in lane driver round its route, its
// front camera's frames with the driver's commands as labels.
struct RecordOptions {
  std::string city;
  std::string vehicle = "nigel_1";
  std::string out;
  std::vector<std::string> route;
  int laps = 1;
  double along_m = 0.3;
  std::optional<std::uint64_t> seed;
  std::string variability = "cloning";
  int width_px = 160;
  int height_px = 90;
  double rate_hz = 15.0;
  double max_duration_s = 900.0;
  bool obey_lights = false;
  double steering_perturbation = 0.3;
  bool quiet = false;
};

int Record(const RecordOptions& o) {
  SimCity city = LoadSimCity(o.city);
  const maps::Map map = maps::LoadMapOrLayout(city.map_path);
  auto car = std::find_if(city.sim.vehicles.begin(), city.sim.vehicles.end(),
                          [&](const SimVehicleConfig& v) { return v.name == o.vehicle; });
  AUTODRIVE_THROW_UNLESS(car != city.sim.vehicles.end(),
                         o.city << ": no vehicle '" << o.vehicle << "' in the sim section");
  city.sim.vehicles = {*car};  // alone on the track, at the start of its route
  city.sim.vehicles[0].spawn = SpawnConfig{};
  city.sim.vehicles[0].spawn->lane = o.route.front();
  city.sim.vehicles[0].spawn->along_m = o.along_m;
  if (o.seed) city.sim.seed = *o.seed;
  bool known = false;
  for (const auto& [preset, name] : ConfigEnumNames(VariabilityPreset{})) {
    if (name == o.variability) {
      city.sim.variability.preset = preset;
      known = true;
    }
  }
  AUTODRIVE_THROW_UNLESS(known,
                         "--variability: " << o.variability << " is not none, paper or cloning");
  OnboardCameraConfig& camera = city.sim.vehicles[0].sensors.front_camera;
  camera.enabled = true;
  camera.rate_hz = o.rate_hz;
  camera.lens.calibration.reset();
  camera.lens.width_px = o.width_px;
  camera.lens.height_px = o.height_px;
  DriverOptions options = CarDriverOptions(city, 0);
  options.ignore_lights = !o.obey_lights;
  options.stop_at_route_end = true;
  for (int lap = 0; lap < o.laps; ++lap) {
    for (const std::string& name : o.route) {
      const maps::Lane* lane = map.FindLane(name);
      AUTODRIVE_THROW_UNLESS(lane != nullptr,
                             "--route: the map " << map.name << " has no lane '" << name << "'");
      options.route.push_back(lane->id);
    }
  }
  LaneDriver lane_driver(map, options);
  bool at_goal = false;
  const DatasetDriver driver = [&](std::size_t index, const World& world,
                                   std::span<const float> lidar, std::span<const HeadLamps> lamps,
                                   Duration now) -> VehicleCommand {
    const DriverDecision d = DriveOnTruth(lane_driver, world, index, lidar, lamps, now);
    at_goal = d.reason == DriverDecision::Reason::kGoal;
    return {d.throttle, d.steering};
  };
  DatasetOptions dataset;
  dataset.camera = o.vehicle + "/front_camera";
  dataset.duration = FromSeconds(o.max_duration_s);
  dataset.out_dir = o.out;
  dataset.done = [&](const World&) { return at_goal; };
  dataset.steering_perturbation = o.steering_perturbation;
  const DatasetSummary summary =
      RenderDataset(city, map, dataset, driver, DatasetProgress("record", o.quiet));
  if (!o.quiet) {
    std::fprintf(stderr, "%srecord: %d frames over %.1f s%s (%.1f ms each) in %s\n",
                 isatty(fileno(stderr)) != 0 ? "\r" : "", summary.frames,
                 ToSeconds(summary.duration), at_goal ? ", the route driven" : "",
                 summary.render_ms_mean, o.out.c_str());
  }
  if (!o.route.empty() && !at_goal) {
    std::fprintf(stderr, "autodrive-sim: record: the route's end was not reached in %.0f s\n",
                 o.max_duration_s);
    return 1;
  }
  return 0;
}

// What the command line gives overrides the city file's `sim.service`.
struct ServiceOverrides {
  std::optional<std::string> mode;
  std::optional<double> real_time_factor;
  std::optional<double> duration_s;
  std::optional<double> command_timeout_s;
  std::optional<double> control_period_s;
  std::vector<std::string> controllers;
  std::vector<std::string> stages;  // each NAME[,NAME...]
  std::optional<bool> traffic;
};

int Serve(const std::string& city_path, const ServiceOverrides& overrides,
          const std::string& log_path, const dds::ProgramOptions& dds_cli) {
  const SimCity city = LoadSimCity(city_path);
  ServiceOptions options = city.sim.service;
  std::string_view mode_name;
  for (const auto& [mode, name] : ConfigEnumNames(SimMode{})) {
    if (overrides.mode && name == *overrides.mode) options.mode = mode;
  }
  for (const auto& [mode, name] : ConfigEnumNames(SimMode{})) {
    if (mode == options.mode) mode_name = name;
  }
  if (overrides.real_time_factor) options.real_time_factor = *overrides.real_time_factor;
  if (overrides.duration_s) {
    options.duration = *overrides.duration_s > 0 ? std::optional(FromSeconds(*overrides.duration_s))
                                                 : std::nullopt;
  }
  if (overrides.command_timeout_s)
    options.command_timeout = FromSeconds(*overrides.command_timeout_s);
  if (overrides.control_period_s) options.control_period = FromSeconds(*overrides.control_period_s);
  if (overrides.traffic) options.traffic = *overrides.traffic;
  if (!overrides.controllers.empty() || !overrides.stages.empty()) {
    // A controller named for a mode that waits for none would be silently ignored.
    AUTODRIVE_THROW_UNLESS(options.mode == SimMode::kLockstep,
                           "--controller, --stage: only lockstep waits for controllers; this "
                           "run's mode is "
                               << mode_name << " (add --mode lockstep)");
    if (!overrides.controllers.empty()) options.controllers = overrides.controllers;
    if (!overrides.stages.empty()) options.stages.clear();
    for (const std::string& stage : overrides.stages) {
      std::vector<std::string>& names = options.stages.emplace_back();
      for (std::size_t at = 0;;) {
        const std::size_t comma = stage.find(',', at);
        names.push_back(stage.substr(at, comma - at));
        if (comma == std::string::npos) break;
        at = comma + 1;
      }
    }
  }
  options.Validate();
  const maps::Map map = maps::LoadMapOrLayout(city.map_path);
  std::atomic<bool> stop{false};
  // Before any other thread starts, so that they all inherit the blocked signals.
  ShutdownSignals signals([&] { stop.store(true); });
  dds::Participant participant(dds_cli.Participant());
  // A district's cars are heard on its domain (docs/districts.md).
  const maps::Districts districts(map, city.districts);
  const maps::DistrictDomains district_domains(participant, dds_cli.Participant(), districts);
  SimService service(participant, city, map, options, district_domains.participants());
  std::ofstream log;
  if (!log_path.empty()) {
    log.open(log_path, std::ios::binary);
    AUTODRIVE_THROW_UNLESS(log.good(), log_path << ": cannot write the log");
    service.LogTo(&log);
  }
  std::string names;
  for (const auto& v : city.sim.vehicles) names += (names.empty() ? "" : ", ") + v.name;
  spdlog::info(
      "sim: city {} on map {}: {} ({}), {} mode{}, partition '{}'", city.name, map.name, names,
      city.sim.vehicles.size() == 1 ? "1 car" : std::to_string(city.sim.vehicles.size()) + " cars",
      mode_name,
      options.mode == SimMode::kRealTime && options.real_time_factor != 1.0
          ? " x" + std::to_string(options.real_time_factor)
          : "",
      dds_cli.partition());
  service.Run(stop);
  service.LogTo(nullptr);
  if (log.is_open()) {
    log.close();
    AUTODRIVE_THROW_UNLESS(!log.fail(), log_path << ": writing the log failed");
  }
  spdlog::info("sim: stopped after {:.3f} simulated s ({} steps)", ToSeconds(service.time()),
               service.steps());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-sim: the simulator of Nigel, the 1:14 car, on ODE. With --city: runs the city's "
      "cars (its sim section) as a DDS service speaking the AutoDRIVE devkit topics, with "
      "/clock, until SIGINT or SIGTERM. See docs/vehicle_sim.md."};
  app.require_subcommand(0, 1);
  std::string service_city;
  ServiceOverrides overrides;
  std::string log_path;
  dds::ProgramOptions dds_cli("/autodrive/sim");
  std::string log_level = "info";
  app.add_option("--city", service_city, "city file (its map and sim section)")
      ->check(CLI::ExistingFile);
  app.add_option("--mode", overrides.mode,
                 "realtime: paced by the wall clock; fast: as fast as it goes; lockstep: a "
                 "control period each time every --controller answered (default: the city's "
                 "sim.service.mode, else realtime)")
      ->check(CLI::IsMember({"realtime", "fast", "lockstep"}));
  app.add_option("--controller", overrides.controllers,
                 "lockstep: a controller to wait for at every step (repeat for several; "
                 "default: sim.service.controllers)");
  app.add_option("--stage", overrides.stages,
                 "lockstep: NAME[,NAME...], controllers told each step before the others and "
                 "answering it first; repeat for stages in order (default: sim.service.stages)");
  app.add_option("--real-time-factor", overrides.real_time_factor,
                 "simulated seconds per wall second in realtime mode (default 1)")
      ->check(CLI::Range(0.01, 1000.0));
  app.add_option("--duration", overrides.duration_s,
                 "stop after this many simulated seconds (0: never, the default)")
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--control-period", overrides.control_period_s,
                 "seconds of simulated time between two readings of the commands (default 0.01)")
      ->check(CLI::Range(0.001, 1.0));
  app.add_option("--command-timeout", overrides.command_timeout_s,
                 "seconds without a throttle or steering command after which a car holds still "
                 "(default 0.5)")
      ->check(CLI::Range(0.01, 3600.0));
  app.add_option("--traffic", overrides.traffic,
                 "true: SUMO's background traffic (/autodrive/scm/traffic) is part of the world; "
                 "false: the topic is not read (default: sim.service.traffic, else true)");
  app.add_option("--log", log_path,
                 "write every car's ground truth after each control period to this CSV file");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|critical|off")
      ->capture_default_str();
  dds_cli.Add(app);

  auto* replay = app.add_subcommand(
      "replay",
      "run one car headless from a CSV of time_s,throttle,steering and write its "
      "ground-truth state as CSV (no DDS)");
  std::string city;
  std::string vehicle = "nigel_1";
  std::string commands;
  std::string out;
  double log_rate_hz = 100.0;
  bool quiet = false;
  replay->add_option("--city", city, "city file (its map and sim section)")
      ->required()
      ->check(CLI::ExistingFile);
  replay->add_option("--vehicle", vehicle, "which car of the sim section")->capture_default_str();
  replay->add_option("--commands", commands, "CSV: time_s,throttle,steering")
      ->required()
      ->check(CLI::ExistingFile);
  replay->add_option("--out", out, "CSV log to write")->required();
  replay->add_option("--log-rate-hz", log_rate_hz, "rows per simulated second")
      ->check(CLI::Range(0.1, 10000.0))
      ->capture_default_str();
  replay->add_flag("-q,--quiet", quiet, "no progress on stderr");

  auto* render = app.add_subcommand(
      "render",
      "drive the city's cars headless (the built-in lane driver, or --commands for one car) and "
      "write one camera's frames as PNG, ground_truth.csv, camera.yaml and camera_pose.yaml "
      "(docs/camera.md)");
  std::string render_city;
  DatasetOptions render_options;
  double render_duration_s = 10.0;
  std::string render_out;
  std::string render_commands;
  std::string render_vehicle = "nigel_1";
  bool render_quiet = false;
  render->add_option("--city", render_city, "city file (its map and sim section)")
      ->required()
      ->check(CLI::ExistingFile);
  render
      ->add_option("--camera", render_options.camera,
                   "an overhead camera's name (sim.cameras), or nigel_<n>/front_camera or "
                   "nigel_<n>/rear_camera")
      ->required();
  render->add_option("--duration", render_duration_s, "simulated seconds")
      ->check(CLI::Range(0.0, 86400.0))
      ->capture_default_str();
  render->add_option("--out", render_out, "directory to write (created)")->required();
  render
      ->add_option("--commands", render_commands,
                   "CSV time_s,throttle,steering driving --vehicle instead of the built-in "
                   "driver")
      ->check(CLI::ExistingFile);
  render->add_option("--vehicle", render_vehicle, "the car --commands drives")
      ->capture_default_str();
  render->add_flag("-q,--quiet", render_quiet, "no progress on stderr");

  auto* record = app.add_subcommand(
      "record",
      "record a driving data set for behavioural cloning: one car alone, driven round --route by "
      "the built-in lane driver, its front camera's frames as PNG with labels.csv (the "
      "driver's throttle and steering, the car's speed and pose) (docs/vehicle_sim.md)");
  RecordOptions record_options;
  record->add_option("--city", record_options.city, "city file (its map and sim section)")
      ->required()
      ->check(CLI::ExistingFile);
  record->add_option("--vehicle", record_options.vehicle, "the car (the others are left out)")
      ->capture_default_str();
  record->add_option("--out", record_options.out, "directory to write (created)")->required();
  record
      ->add_option("--route", record_options.route,
                   "lanes to drive, in order (a closed loop with --laps); the recording ends "
                   "at the last lane's end")
      ->delimiter(',')
      ->required();
  record
      ->add_option("--along", record_options.along_m,
                   "the car starts this far along the route's first lane, metres")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  record->add_option("--laps", record_options.laps, "the route driven this many times")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  record->add_option("--seed", record_options.seed,
                     "the simulation's seed (light, start, noise); default the city's");
  record
      ->add_option("--variability", record_options.variability,
                   "the variability preset: none, paper or cloning (light intensity and "
                   "direction, start pose, command noise)")
      ->capture_default_str();
  record->add_option("--width", record_options.width_px, "frame width, pixels")
      ->check(CLI::Range(16, 1920))
      ->capture_default_str();
  record->add_option("--height", record_options.height_px, "frame height, pixels")
      ->check(CLI::Range(16, 1080))
      ->capture_default_str();
  record->add_option("--rate", record_options.rate_hz, "frames per simulated second")
      ->check(CLI::Range(0.5, 60.0))
      ->capture_default_str();
  record
      ->add_option("--max-duration", record_options.max_duration_s,
                   "simulated seconds at most (the route not driven by then: exit 1)")
      ->check(CLI::Range(1.0, 86400.0))
      ->capture_default_str();
  record
      ->add_option("--steering-perturbation", record_options.steering_perturbation,
                   "noise injection (DART): a slowly varying perturbation of this standard "
                   "deviation (normalised units, 1 s correlation) on the steering the car "
                   "executes, not on the label: the data shows the driver recovering; 0: none")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  record->add_flag("--obey-lights", record_options.obey_lights,
                   "the driver stops for red lights (fixed-time lamps); by default it drives "
                   "through, as a camera-only model cannot wait out a red");
  record->add_flag("-q,--quiet", record_options.quiet, "no progress on stderr");

  CLI11_PARSE(app, argc, argv);
  try {
    InitLogging("autodrive-sim", ParseLogLevel(log_level));
    if (replay->parsed()) return Replay(city, vehicle, commands, out, log_rate_hz, quiet);
    if (record->parsed()) return Record(record_options);
    if (render->parsed()) {
      render_options.duration = FromSeconds(render_duration_s);
      render_options.out_dir = render_out;
      return Render(render_city, render_options, render_commands, render_vehicle, render_quiet);
    }
    if (service_city.empty()) {
      std::fprintf(stderr,
                   "autodrive-sim: give --city CONFIG to run the simulator, or a "
                   "subcommand (--help)\n");
      return 2;
    }
    return Serve(service_city, overrides, log_path, dds_cli);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-sim: %s\n", e.what());
    return 1;
  }
}
