#include "city/launcher/launch_config.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdlib>
#include <map>
#include <optional>
#include <set>

#include "traffic/traffic_config.h"

#include "common/error.h"
#include "eye/eye_config.h"
#include "infrastructure/config.h"
#include "scm/core/city.h"
#include "vehicle_sim/sim_config.h"

namespace autodrive::launcher {
namespace {

Restart RestartOf(const std::string& text, Restart fallback) {
  if (text == "always") return Restart::kAlways;
  if (text == "on-failure") return Restart::kOnFailure;
  if (text == "never") return Restart::kNever;
  return fallback;
}

// Whether a program runs: `on`, `off`, or (auto) when the city has its section.
bool IsOn(const ProcessConfig& p, bool has_section, const std::string& name,
          const std::filesystem::path& city_file) {
  if (p.mode == "off") return false;
  if (p.mode == "on" && !has_section) {
    throw ConfigError(fmt::format(
        "{}: launch.{}: mode on, but the city has no {} section for it (add one, or use auto)",
        city_file.string(), name, name));
  }
  return p.mode == "on" || has_section;
}

std::string Substitute(std::string text, const LaunchPlan& plan) {
  const auto replace = [&](const std::string& from, const std::string& to) {
    for (std::size_t at = text.find(from); at != std::string::npos;
         at = text.find(from, at + to.size())) {
      text.replace(at, from.size(), to);
    }
  };
  replace("{city}", plan.city_file.string());
  replace("{run}", plan.run_dir.string());
  return text;
}

// A city whose simulator runs in lockstep (`sim.service.mode: lockstep`): each of the city's
// programs that the simulator waits for (by its name in `sim.service.stages` or `controllers`)
// gets `--lockstep NAME`; an agent it waits for passes its own. Nothing is waited for (no
// controller is heard before the simulator's first step, which waits for them all), and
// nothing is restarted: the run ends when a controller leaves. Throws `ConfigError` when the
// simulator would wait for a process the launcher does not start, or for one that cannot be a
// controller.
void PlanLockstep(LaunchPlan& plan, const vehicle_sim::ServiceOptions& service,
                  const std::vector<std::string>& external, const std::string& city_path) {
  std::set<std::string> waited(service.controllers.begin(), service.controllers.end());
  for (const auto& stage : service.stages) waited.insert(stage.begin(), stage.end());
  for (const std::string& name : external) waited.erase(name);
  const std::set<std::string> controllers{"lights", "scm", "traffic", "driver", "eye"};
  for (ProcessPlan& p : plan.processes) {
    if (p.name == "dashboard") continue;
    p.ready = {};
    p.restart = Restart::kNever;
    if (!waited.erase(p.name) || !p.city_program) continue;
    if (!controllers.contains(p.name)) {
      throw ConfigError(fmt::format(
          "{}: sim.service: the simulator would wait in lockstep for {}, which has no lockstep "
          "mode (the city's controllers: {})",
          city_path, p.name, fmt::join(controllers, ", ")));
    }
    p.argv.insert(p.argv.end(), {"--lockstep", p.name});
  }
  if (!waited.empty()) {
    throw ConfigError(
        fmt::format("{}: sim.service: the simulator would wait in lockstep for {}, which the "
                    "launcher does not start (the city's programs by name, launch.agents, or "
                    "launch.external_controllers)",
                    city_path, fmt::join(waited, ", ")));
  }
}

}  // namespace

namespace {

// `run_dir` relative to the city file; by default $XDG_STATE_HOME/autodrive/<name>
// (~/.local/state/autodrive/<name>): never beside a shipped city file in the source tree.
std::filesystem::path ResolveRunDir(const std::filesystem::path& city_file, const std::string& name,
                                    const std::string& run_dir) {
  if (!run_dir.empty()) return (city_file.parent_path() / run_dir).lexically_normal();
  std::filesystem::path state;
  if (const char* x = std::getenv("XDG_STATE_HOME"); x != nullptr && *x != '\0') {
    state = x;
  } else if (const char* home = std::getenv("HOME"); home != nullptr && *home != '\0') {
    state = std::filesystem::path(home) / ".local" / "state";
  } else {
    state = std::filesystem::temp_directory_path();
  }
  return state / "autodrive" / name;
}

// The launch section (defaults when the city has none).
LaunchConfig LoadLaunch(const std::filesystem::path& file) {
  bool has_section = true;
  try {
    const YAML::Node root = YAML::LoadFile(file.string());
    has_section = root.IsMap() && root["launch"];
  } catch (const YAML::BadFile&) {
    throw ConfigError(file.string() + ": cannot read the city file");
  } catch (const YAML::Exception&) {
    // the strict loader reports the syntax error with its position
  }
  return has_section ? config::LoadFile<LaunchConfig>(file, "launch") : LaunchConfig{};
}

}  // namespace

std::filesystem::path RunDirOf(const std::filesystem::path& city_file) {
  const std::filesystem::path file = std::filesystem::absolute(city_file).lexically_normal();
  std::string name;
  try {
    const YAML::Node root = YAML::LoadFile(file.string());
    if (root.IsMap() && root["name"] && root["name"].IsScalar()) {
      name = root["name"].as<std::string>();
    }
  } catch (const YAML::Exception& e) {
    throw ConfigError(file.string() + ": " + e.what());
  }
  if (name.empty()) throw ConfigError(file.string() + ": name: missing");
  const LaunchConfig launch = LoadLaunch(file);
  return ResolveRunDir(file, name, launch.run_dir);
}

namespace {

// A light host must drive every head of the signalised intersections it serves (the city's,
// or in a city of districts its district's), and only those, each at the same intersection and
// approach in its map as in the city's: a head that no one drives keeps its intersection in
// start-up flash for good.
void CheckHeadsHosted(const scm::City& city, const maps::District* district,
                      const infrastructure::HostPlan& host, const std::string& city_path,
                      const std::string& lights_path) {
  const maps::Map& city_map = city.map;
  const auto served = [&](const maps::SignalHead& h) {
    return district == nullptr || city.districts.Of(h.intersection) == district;
  };
  std::set<SignalHeadId> hosted;
  std::vector<std::string> problems;
  for (const infrastructure::HeadPlan& h : host.heads) {
    hosted.insert(h.id);
    const std::string there = host.map.DescribeSignalHead(h.id);
    const std::string here = city_map.DescribeSignalHead(h.id);
    if (!city_map.HasSignalHead(h.id)) {
      problems.push_back(
          fmt::format("it hosts {}, which the city's map {} has not", there, city_map.name));
    } else if (there != here) {
      problems.push_back(fmt::format("its map has {} where the city's has {}", there, here));
    } else if (!served(city_map.signal_head(h.id))) {
      const maps::District* other = city.districts.Of(city_map.signal_head(h.id).intersection);
      problems.push_back(fmt::format("it hosts {}, which is district {}'s", there,
                                     other == nullptr ? "(none)" : other->name));
    }
  }
  std::vector<std::string> missing;
  for (const maps::SignalHead& h : city_map.signal_heads) {
    if (served(h) && !hosted.contains(h.id)) missing.push_back(city_map.DescribeSignalHead(h.id));
  }
  if (!missing.empty()) {
    problems.push_back(fmt::format("it does not host {} (add {} to its heads)",
                                   fmt::join(missing, ", "), missing.size() == 1 ? "it" : "them"));
  }
  if (!problems.empty()) {
    const std::string key =
        district == nullptr ? "launch.lights" : "launch.lights (district " + district->name + ")";
    throw ConfigError(fmt::format(
        "{}: {}: the light host's file {} does not match the city{}: {}. Head ids are the map's "
        "heads= (autodrive-map info lists them); set launch.lights.mode: off when the lights run "
        "on other hosts",
        city_path, key, lights_path,
        district == nullptr ? "" : fmt::format(" (district {}'s heads)", district->name),
        fmt::join(problems, "; ")));
  }
}

// launch.hosts: every host named as a file name may be, every process of the plan on exactly
// one host, and nothing else named.
void CheckHosts(const LaunchPlan& plan, const std::string& city_path) {
  if (plan.hosts.empty()) return;
  std::map<std::string, std::string> host_of;
  std::vector<std::string> planned;
  for (const ProcessPlan& p : plan.processes) planned.push_back(p.name);
  for (const auto& [host, names] : plan.hosts) {
    if (host.empty() ||
        host.find_first_not_of("abcdefghijklmnopqrstuvwxyz"
                               "ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-") != std::string::npos) {
      throw ConfigError(
          fmt::format("{}: launch.hosts: host name \"{}\" (letters, digits, '_' and '-' only)",
                      city_path, host));
    }
    for (const std::string& name : names) {
      if (std::ranges::find(planned, name) == planned.end()) {
        throw ConfigError(fmt::format(
            "{}: launch.hosts.{}: {} is not one of the processes this city starts ({}; a "
            "process whose mode is off, or whose section the city has not, is not started)",
            city_path, host, name, fmt::join(planned, ", ")));
      }
      if (const auto [at, fresh] = host_of.emplace(name, host); !fresh) {
        throw ConfigError(fmt::format("{}: launch.hosts: {} is on two hosts, {} and {}", city_path,
                                      name, at->second, host));
      }
    }
  }
  std::vector<std::string> nowhere;
  for (const std::string& name : planned) {
    if (!host_of.contains(name)) nowhere.push_back(name);
  }
  if (!nowhere.empty()) {
    throw ConfigError(
        fmt::format("{}: launch.hosts: no host runs {} (name each process of the city once)",
                    city_path, fmt::join(nowhere, ", ")));
  }
}

}  // namespace

std::filesystem::path StatusFileOf(const std::filesystem::path& run_dir, const std::string& host) {
  return run_dir / (host.empty() ? "status.json" : fmt::format("status-{}.json", host));
}

std::filesystem::path PidFileOf(const std::filesystem::path& run_dir, const std::string& host) {
  return run_dir / (host.empty() ? "launcher.pid" : fmt::format("launcher-{}.pid", host));
}

void SelectHost(LaunchPlan& plan, const std::string& host) {
  if (host.empty()) return;
  if (plan.hosts.empty()) {
    throw ConfigError(
        fmt::format("{}: --host {}: the city file has no launch.hosts saying which host runs what",
                    plan.city_file.string(), host));
  }
  const auto share = plan.hosts.find(host);
  if (share == plan.hosts.end()) {
    std::vector<std::string> known;
    for (const auto& [name, processes] : plan.hosts) known.push_back(name);
    throw ConfigError(fmt::format("{}: --host {}: launch.hosts has no such host (it has {})",
                                  plan.city_file.string(), host, fmt::join(known, ", ")));
  }
  std::erase_if(plan.processes, [&](const ProcessPlan& p) {
    return std::ranges::find(share->second, p.name) == share->second.end();
  });
  if (plan.dashboard && std::ranges::find(share->second, "dashboard") == share->second.end()) {
    plan.dashboard.reset();
  }
  plan.host = host;
  plan.status_file = StatusFileOf(plan.run_dir, host);
  plan.pid_file = PidFileOf(plan.run_dir, host);
}

LaunchPlan PlanCity(const std::filesystem::path& city_file, const std::filesystem::path& bin_dir) {
  LaunchPlan plan;
  plan.city_file = std::filesystem::absolute(city_file).lexically_normal();
  const std::filesystem::path base = plan.city_file.parent_path();
  // The SCM's view: every intersection, plan and safety rule checked against the map.
  const scm::City city = scm::LoadCity(plan.city_file);
  plan.city_name = city.config.name;
  for (const maps::District& d : city.districts.all()) plan.districts.emplace(d.name, d.domain);
  const LaunchConfig launch = LoadLaunch(plan.city_file);

  plan.run_dir = ResolveRunDir(plan.city_file, plan.city_name, launch.run_dir);
  plan.status_file = StatusFileOf(plan.run_dir, "");
  plan.pid_file = PidFileOf(plan.run_dir, "");
  plan.crash_loop_exits = launch.crash_loop_exits;
  plan.crash_loop_window = launch.crash_loop_window_s;
  plan.stop_grace = launch.stop_grace_s;
  const std::string city_path = plan.city_file.string();
  const auto bin = [&](const char* program) { return (bin_dir / program).string(); };
  const auto add = [&](const std::string& name, const ProcessConfig& p,
                       std::vector<std::string> argv, Restart fallback, Readiness ready) {
    argv.insert(argv.end(), p.args.begin(), p.args.end());
    ProcessPlan process;
    process.name = name;
    process.program = name;
    process.argv = std::move(argv);
    process.restart = RestartOf(p.restart, fallback);
    process.ready = std::move(ready);
    process.ready_timeout = p.ready_timeout_s;
    process.log = plan.run_dir / "logs" / (name + ".log");
    process.city_program = true;
    plan.processes.push_back(std::move(process));
  };

  // 1. The lights: they flash on their own until the SCM is up, and last when it goes. A city
  // of districts has a light host per district, on its domain.
  const LightsProcessConfig& lights = launch.lights;
  const auto add_lights = [&](const std::string& name, const std::filesystem::path& file,
                              const maps::District* district) {
    if (!std::filesystem::exists(file)) {
      throw ConfigError(fmt::format(
          "{}: launch.lights: the light host's file {}{} does not exist (set "
          "launch.lights.{}, or launch.lights.mode: off when the lights run on another host)",
          city_path, file.lexically_normal().string(),
          district == nullptr ? "" : " of district " + district->name,
          district == nullptr ? "config" : "districts." + district->name));
    }
    const infrastructure::InfraConfig infra = infrastructure::LoadInfraConfig(file);
    if (infra.city != plan.city_name) {
      throw ConfigError(fmt::format("{}: launch.lights: {} serves the city \"{}\", not \"{}\"",
                                    city_path, file.lexically_normal().string(), infra.city,
                                    plan.city_name));
    }
    CheckHeadsHosted(city, district, infrastructure::PlanHost(infra, file), city_path,
                     file.lexically_normal().string());
    std::vector<std::string> argv{bin("autodrive-infra"), "--config",
                                  file.lexically_normal().string()};
    Readiness ready{Readiness::Kind::kHeartbeat, "infra/" + infra.name, {}};
    if (district != nullptr) {
      argv.insert(argv.end(), {"--domain", std::to_string(district->domain)});
      ready.domain = district->domain;
    }
    add(name, lights.process, std::move(argv), Restart::kAlways, std::move(ready));
    plan.processes.back().program = "lights";
  };
  if (city.districts.empty() && !lights.districts.empty()) {
    throw ConfigError(fmt::format(
        "{}: launch.lights.districts: the city has no districts (docs/districts.md)", city_path));
  }
  for (const auto& [name, file] : lights.districts) {
    if (city.districts.Find(name) == nullptr) {
      throw ConfigError(
          fmt::format("{}: launch.lights.districts: {} is not a district (the city "
                      "has {})",
                      city_path, name, city.districts.Names()));
    }
  }
  if (!city.districts.empty() && !lights.config.empty() && lights.process.mode != "off") {
    throw ConfigError(fmt::format(
        "{}: launch.lights.config: a city of districts has a light host per district; name their "
        "files in launch.lights.districts (NAME: FILE; by default ../infra/{}_NAME.yaml)",
        city_path, plan.city_name));
  }
  if (lights.process.mode != "off") {
    if (city.districts.empty()) {
      add_lights("lights",
                 lights.config.empty() ? base / ".." / "infra" / (plan.city_name + ".yaml")
                                       : base / lights.config,
                 nullptr);
    }
    for (const maps::District& d : city.districts.all()) {
      const auto named = lights.districts.find(d.name);
      add_lights("lights_" + d.name,
                 named != lights.districts.end()
                     ? base / named->second
                     : base / ".." / "infra" / fmt::format("{}_{}.yaml", plan.city_name, d.name),
                 &d);
    }
  }
  // 2. The SCM, restarted at once whatever ended it; in a city of districts, one per district
  // on its domain (`--district`), each with a database of its own.
  if (launch.scm.mode != "off") {
    if (city.districts.empty()) {
      add("scm", launch.scm,
          {bin("autodrive-scm"), "--config", city_path, "--db", (plan.run_dir / "scm.db").string()},
          Restart::kAlways, {Readiness::Kind::kHeartbeat, "scm", {}});
    }
    for (const maps::District& d : city.districts.all()) {
      add("scm_" + d.name, launch.scm,
          {bin("autodrive-scm"), "--config", city_path, "--district", d.name, "--db",
           (plan.run_dir / fmt::format("scm_{}.db", d.name)).string()},
          Restart::kAlways, {Readiness::Kind::kHeartbeat, "scm", {}, d.domain});
      plan.processes.back().program = "scm";
    }
  }
  // 3. The simulator and the cars' driver.
  const bool sim = IsOn(launch.sim, city.config.sim.has_value(), "sim", plan.city_file);
  std::optional<vehicle_sim::ServiceOptions> lockstep;
  if (sim) {
    const vehicle_sim::SimCity sim_city = vehicle_sim::LoadSimCity(city_path);
    if (sim_city.sim.service.mode == vehicle_sim::SimMode::kLockstep) {
      if (!city.districts.empty()) {
        // The lockstep handshake is on the simulator's domain; the districts' SCMs and lights
        // are on theirs.
        throw ConfigError(fmt::format(
            "{}: sim.service.mode: lockstep is not for a city of districts (its controllers would "
            "be on the districts' domains, the simulator's handshake on its own); use realtime",
            city_path));
      }
      lockstep = sim_city.sim.service;
    }
    add("sim", launch.sim, {bin("autodrive-sim"), "--city", city_path}, Restart::kOnFailure,
        {Readiness::Kind::kClock, {}, {}});
  }
  // 4. SUMO's background traffic.
  if (IsOn(launch.traffic, city.config.traffic.has_value(), "traffic", plan.city_file)) {
    (void)traffic::LoadTrafficConfig(plan.city_file);
    add("traffic", launch.traffic,
        {bin("autodrive-traffic"), "--city", city_path, "--work-dir",
         (plan.run_dir / "traffic").string()},
        Restart::kOnFailure, {Readiness::Kind::kTraffic, {}, {}});
  }
  // 5. The Eye.
  if (IsOn(launch.eye, city.config.eye.has_value(), "eye", plan.city_file)) {
    if (eye::LoadEyeConfig(plan.city_file).outputs.ips && !city.districts.empty()) {
      // Its cars' positions would be heard on its own domain only, by no district's SCM.
      throw ConfigError(fmt::format(
          "{}: eye.outputs.ips: the Eye publishes the cars' ips on its own domain only, which is "
          "no district's; in a city of districts the cars' positions come from the cars or the "
          "simulator (docs/districts.md)",
          city_path));
    }
    add("eye", launch.eye, {bin("autodrive-eye"), "run", "--config", city_path},
        Restart::kOnFailure, {});
  }
  // 6. The example driver drives the simulated cars.
  if (launch.driver.mode == "on" && !sim) {
    throw ConfigError(fmt::format(
        "{}: launch.driver: mode on, but the simulator is off (the example driver drives "
        "simulated cars)",
        city_path));
  }
  if (launch.driver.mode == "on" || (launch.driver.mode == "auto" && sim)) {
    add("driver", launch.driver, {bin("autodrive-example-driver"), "--city", city_path},
        Restart::kOnFailure, {});
  }
  // 7. The user's agents.
  std::set<std::string> names;
  for (const ProcessPlan& p : plan.processes) names.insert(p.name);
  names.insert("dashboard");
  for (std::size_t i = 0; i < launch.agents.size(); ++i) {
    const AgentConfig& a = launch.agents[i];
    if (a.name.empty() ||
        a.name.find_first_not_of("abcdefghijklmnopqrstuvwxyz"
                                 "ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-") != std::string::npos) {
      throw ConfigError(
          fmt::format("{}: launch.agents[{}].name: \"{}\" (letters, digits, '_' and '-' only)",
                      city_path, i, a.name));
    }
    if (!names.insert(a.name).second) {
      throw ConfigError(
          fmt::format("{}: launch.agents[{}].name: \"{}\" is taken", city_path, i, a.name));
    }
    if (a.command.empty()) {
      throw ConfigError(
          fmt::format("{}: launch.agents[{}].command: a program is needed", city_path, i));
    }
    ProcessConfig p;
    p.restart = a.restart;
    std::vector<std::string> argv;
    for (const std::string& word : a.command) argv.push_back(Substitute(word, plan));
    add(a.name, p, std::move(argv), Restart::kOnFailure, {});
    plan.processes.back().env = a.env;
    plan.processes.back().city_program = false;
  }
  // 8. The dashboard, last: it shows the others.
  const DashboardProcessConfig& dash = launch.dashboard;
  if (dash.process.mode == "on" ||
      (dash.process.mode == "auto" && std::filesystem::exists(bin_dir / "autodrive-dashboard"))) {
    const auto colon = dash.listen.rfind(':');
    if (colon == std::string::npos || colon == 0 ||
        dash.listen.find_first_not_of("0123456789", colon + 1) != std::string::npos ||
        colon + 1 == dash.listen.size()) {
      throw ConfigError(
          fmt::format("{}: launch.dashboard.listen: \"{}\" (HOST:PORT)", city_path, dash.listen));
    }
    LaunchPlan::Dashboard d;
    const std::string host = dash.listen.substr(0, colon);
    d.url = fmt::format("http://{}:{}/", host == "0.0.0.0" ? "localhost" : host,
                        dash.listen.substr(colon + 1));
    d.tokens = dash.tokens.empty() ? plan.run_dir / "dashboard.tokens"
                                   : (base / dash.tokens).lexically_normal();
    d.operator_name =
        city.config.operators.allowed.empty() ? "" : city.config.operators.allowed.front();
    add("dashboard", dash.process,
        {bin("autodrive-dashboard"), "--city", city_path, "--listen", dash.listen, "--run-dir",
         plan.run_dir.string(), "--token-file", d.tokens.string()},
        Restart::kOnFailure, {Readiness::Kind::kFile, {}, plan.run_dir / "dashboard.url"});
    d.url_file = plan.run_dir / "dashboard.url";
    plan.dashboard = std::move(d);
  }
  if (lockstep) PlanLockstep(plan, *lockstep, launch.external_controllers, city_path);
  plan.hosts = launch.hosts;
  CheckHosts(plan, city_path);
  for (const ProcessPlan& p : plan.processes) {
    if (p.argv.front().find('/') != std::string::npos && !std::filesystem::exists(p.argv.front())) {
      throw InputError(fmt::format("{}: {}: the program {} is not there (build it first)",
                                   city_path, p.name, p.argv.front()));
    }
  }
  return plan;
}

}  // namespace autodrive::launcher
