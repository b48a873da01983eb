#pragma once
/// @file
/// The `launch` section of a city file: which processes `autodrive-city up` starts, each on,
/// off or (for the lights) simulated or real, how each is restarted, where the run's files go
/// (docs/launcher.md). The SCM carries the section and does not read it.
///
/// ```yaml
/// launch:
///   run_dir: /var/lib/autodrive/small_town  # logs, database, state (relative: to the file)
///   lights: {mode: on, config: ../infra/small_town.yaml}
///   scm: {mode: on}
///   sim: {mode: auto}                  # auto: on when the city has a sim section
///   driver: {mode: auto}               # the example driver: on when the simulator is
///   eye: {mode: auto}                  # on when the city has an eye section
///   traffic: {mode: auto}              # on when the city has a traffic section
///   dashboard: {mode: on, args: [--address, 127.0.0.1:8080]}
///   agents:
///     - {name: planner, command: [python3, planner.py, --city, "{city}"]}
///   hosts:                             # optional: which lab host runs which process
///     server: [scm, sim, driver, traffic, dashboard, planner]
///     track: [lights]                  # `autodrive-city up CITY --host track` on that host
/// ```
///
/// A city of districts (docs/districts.md) runs an SCM (`scm_<district>`) and a light host
/// (`lights_<district>`) per district, each on the district's domain; the rest on the
/// launcher's own domain, which must be no district's.

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/config.h"

namespace autodrive::launcher {

using std::chrono::nanoseconds;

/// One of the city's own programs.
struct ProcessConfig {
  /// on, off, or auto (on when the city file has the program's section).
  std::string mode = "auto";
  /// always: started again whenever it exits; on-failure: unless it exited with 0; never.
  /// Empty: the program's default (the SCM and the lights: always; the others: on-failure).
  std::string restart;
  std::vector<std::string> args;  ///< further arguments, appended
  /// How long it may take to be ready (its first heartbeat or topic sample).
  nanoseconds ready_timeout_s = std::chrono::seconds(120);

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("mode", mode, config::OneOf{{"on", "off", "auto"}});
    a.Optional("restart", restart, config::OneOf{{"", "always", "on-failure", "never"}});
    a.Optional("args", args);
    a.Optional("ready_timeout_s", ready_timeout_s,
               config::Range<nanoseconds>{std::chrono::seconds(1), std::chrono::hours(1)});
  }
  bool operator==(const ProcessConfig&) const = default;
};

/// The traffic lights' host (`autodrive-infra`): its own file says which heads are simulated
/// and which are real (serial); off when the lights run on another host. A city of districts
/// has a light host per district (`lights_<district>`), on the district's domain.
struct LightsProcessConfig {
  ProcessConfig process;
  /// The light host's file, relative to the city file. Empty: ../infra/<city name>.yaml.
  std::string config;
  /// With districts: each district's light host file by district name, relative to the city
  /// file. A district not named: ../infra/<city name>_<district>.yaml.
  std::map<std::string, std::string> districts;

  template <typename Archive>
  void Serialize(Archive& a) {
    process.Serialize(a);
    a.Optional("config", config);
    a.Optional("districts", districts);
  }
  bool operator==(const LightsProcessConfig&) const = default;
};

/// The dashboard (`autodrive-dashboard`): where it listens and its operators' tokens.
struct DashboardProcessConfig {
  ProcessConfig process;
  std::string listen = "127.0.0.1:8080";  ///< HOST:PORT
  /// Operators' tokens (lines `NAME TOKEN`, mode 600), relative to the city file. Empty:
  /// <run_dir>/dashboard.tokens, which `up` creates with one new token for the city's first
  /// allowed operator when it is not there.
  std::string tokens;

  template <typename Archive>
  void Serialize(Archive& a) {
    process.Serialize(a);
    a.Optional("listen", listen);
    a.Optional("tokens", tokens);
  }
  bool operator==(const DashboardProcessConfig&) const = default;
};

/// A user's program started with the city (a planner, a V2I client, a ROS 2 bridge).
struct AgentConfig {
  std::string name;
  /// The program and its arguments; `{city}` becomes the city file's path and `{run}` the run
  /// folder.
  std::vector<std::string> command;
  std::string restart = "on-failure";
  std::vector<std::string> env;  ///< NAME=value entries added to its environment

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Required("command", command);
    a.Optional("restart", restart, config::OneOf{{"always", "on-failure", "never"}});
    a.Optional("env", env);
  }
  bool operator==(const AgentConfig&) const = default;
};

/// The `launch` section.
struct LaunchConfig {
  /// Logs, the SCM's database and the launcher's state; relative to the city file. Empty:
  /// $XDG_STATE_HOME/autodrive/<city name> (~/.local/state/autodrive/<city name>).
  std::string run_dir;
  LightsProcessConfig lights;
  ProcessConfig scm;
  ProcessConfig sim;
  ProcessConfig driver;
  ProcessConfig eye;
  ProcessConfig traffic;
  DashboardProcessConfig dashboard;
  std::vector<AgentConfig> agents;
  /// Lockstep controllers the simulator waits for that the launcher does not start (a
  /// scenario runner, `autodrive-scenario`, which starts the launcher itself).
  std::vector<std::string> external_controllers;
  /// A process that exits this many times within `crash_loop_window_s` is in a crash loop:
  /// reported (status, log), and started again only after the window, not at once.
  int crash_loop_exits = 5;
  nanoseconds crash_loop_window_s = std::chrono::seconds(60);
  /// On stopping, how long each process has after SIGTERM before SIGKILL.
  nanoseconds stop_grace_s = std::chrono::seconds(10);
  /// Which lab host runs which process: host name -> the processes' names (lights, scm, sim,
  /// driver, eye, traffic, dashboard, the agents'). Empty: all on the host that runs `up`.
  /// Given, it names every process of the city once; `up --host NAME` starts NAME's share.
  std::map<std::string, std::vector<std::string>> hosts;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("run_dir", run_dir);
    a.Optional("lights", lights);
    a.Optional("scm", scm);
    a.Optional("sim", sim);
    a.Optional("driver", driver);
    a.Optional("eye", eye);
    a.Optional("traffic", traffic);
    a.Optional("dashboard", dashboard);
    a.Optional("agents", agents);
    a.Optional("external_controllers", external_controllers);
    a.Optional("crash_loop_exits", crash_loop_exits, config::Range{1, 1000});
    a.Optional("crash_loop_window_s", crash_loop_window_s,
               config::Range<nanoseconds>{std::chrono::seconds(1), std::chrono::hours(24)});
    a.Optional("stop_grace_s", stop_grace_s,
               config::Range<nanoseconds>{std::chrono::milliseconds(100), std::chrono::minutes(5)});
    a.Optional("hosts", hosts);
  }
  bool operator==(const LaunchConfig&) const = default;
};

/// How a process is restarted.
enum class Restart { kAlways, kOnFailure, kNever };

/// What readiness means for a process: its first heartbeat or a first sample on its topic;
/// none: started is ready.
struct Readiness {
  enum class Kind { kNone, kHeartbeat, kClock, kTraffic, kFile };
  Kind kind = Kind::kNone;
  /// kHeartbeat: the heartbeat's sender, "scm" (on the SCM's heartbeat topic) or "infra/<host>"
  /// (on the device hosts' topic), of the plan's city.
  std::string sender;
  std::filesystem::path file;  ///< kFile: a file the process writes once it is ready
  /// kHeartbeat: the DDS domain it is heard on, a district's; unset: the launcher's own.
  std::optional<std::uint32_t> domain = std::nullopt;
};

/// One process of the plan, fully resolved.
struct ProcessPlan {
  /// lights, scm, sim, driver, eye, traffic, dashboard, or an agent's; in a city of districts,
  /// lights_<district> and scm_<district> for each district.
  std::string name;
  /// The city's program it runs, as `name` without the district: lights, scm, ... (an agent:
  /// its name).
  std::string program;
  std::vector<std::string> argv;  ///< argv[0]: a path (the city's programs) or a name on PATH
  std::vector<std::string> env;
  Restart restart = Restart::kOnFailure;
  Readiness ready;
  nanoseconds ready_timeout{std::chrono::seconds(120)};
  std::filesystem::path log;  ///< stdout and stderr, appended
  bool city_program = false;  ///< one of ours (takes --partition), not a user's agent
};

/// The whole city's processes in start order (stopped in reverse: the lights last, so that
/// they flash on their own once the SCM has gone).
struct LaunchPlan {
  std::string city_name;
  std::filesystem::path city_file;  ///< absolute
  /// The city's districts (docs/districts.md): name -> DDS domain. The launcher joins each
  /// district's domain to hear its SCM and light host get ready and to send its process table
  /// to the district's SCM.
  std::map<std::string, std::uint32_t> districts;
  std::filesystem::path run_dir;  ///< absolute
  std::vector<ProcessPlan> processes;
  int crash_loop_exits = 5;
  nanoseconds crash_loop_window{std::chrono::seconds(60)};
  nanoseconds stop_grace{std::chrono::seconds(10)};
  /// When the dashboard runs: its address, its tokens file, and the operator a new token is
  /// made for when that file does not exist yet (`up` makes it).
  struct Dashboard {
    std::string url;  ///< http://HOST:PORT/ as configured
    /// Where the dashboard writes the address it serves on once it listens (the real port
    /// when the configured one is 0); removed before it starts.
    std::filesystem::path url_file;
    std::filesystem::path tokens;
    std::string operator_name;
  };
  std::optional<Dashboard> dashboard;
  /// `launch.hosts`, checked: each of the city's processes on exactly one host.
  std::map<std::string, std::vector<std::string>> hosts;
  /// The host whose share this plan is (`up --host`); empty: the whole city.
  std::string host;
  /// The launcher's own files in the run folder: per host when the plan is a host's share, so
  /// that the shares of one city never mix (several hosts may share the folder over NFS, or
  /// run as network namespaces of one machine in the tests).
  std::filesystem::path status_file;  ///< status.json or status-<host>.json
  std::filesystem::path pid_file;     ///< launcher.pid or launcher-<host>.pid
};

/// The launcher's status and pid files in `run_dir` for the share of `host` (empty: the whole
/// city).
[[nodiscard]] std::filesystem::path StatusFileOf(const std::filesystem::path& run_dir,
                                                 const std::string& host);
[[nodiscard]] std::filesystem::path PidFileOf(const std::filesystem::path& run_dir,
                                              const std::string& host);

/// Keeps the processes of `plan` that `host` runs (launch.hosts), in their start order, and
/// points its launcher files at that host's. Empty `host`: the whole city, unchanged.
/// @throws ConfigError when the city has no launch.hosts or no host of that name.
void SelectHost(LaunchPlan& plan, const std::string& host);

/// Loads the city file at `city_file` whole (the SCM's checks, the map, each section the plan
/// starts a program for) and resolves its launch plan, with the city's programs in `bin_dir`.
/// Everything a process would refuse at start is refused here, before anything starts.
/// @throws ConfigError / InputError naming the file, line and key.
[[nodiscard]] LaunchPlan PlanCity(const std::filesystem::path& city_file,
                                  const std::filesystem::path& bin_dir);

/// The run folder of the city file at `city_file` (`launch.run_dir`, else
/// ~/.local/state/autodrive/<name>), read without loading the city: for `down`, `status`,
/// `logs`.
/// @throws ConfigError naming the file.
[[nodiscard]] std::filesystem::path RunDirOf(const std::filesystem::path& city_file);

}  // namespace autodrive::launcher
