#include "scenarios/compose.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <set>
#include <string_view>

#include "scenarios/metrics.h"

#include "common/error.h"

namespace autodrive::scenarios {

namespace {

namespace fs = std::filesystem;

std::string Absolute(const fs::path& base_dir, const std::string& path) {
  return (base_dir / path).lexically_normal().string();
}

// Replaces {city}, {vehicle}, {route}, {lockstep}, {run} and {scenario} in `word`.
std::string Substitute(std::string word,
                       const std::vector<std::pair<std::string, std::string>>& with) {
  for (const auto& [key, value] : with) {
    for (std::size_t at = word.find(key); at != std::string::npos;
         at = word.find(key, at + value.size())) {
      word.replace(at, key.size(), value);
    }
  }
  return word;
}

// The program `word` names: the build's own when bin_dir has it, else as given (PATH or a path).
std::string ResolveProgram(const std::string& word, const fs::path& bin_dir) {
  if (word.find('/') == std::string::npos && fs::exists(bin_dir / word)) {
    return (bin_dir / word).string();
  }
  return word;
}

}  // namespace

std::string AgentController(const std::string& vehicle) { return "agent_" + vehicle; }

ComposedCity ComposeCity(const Scenario& scenario, const fs::path& scenario_file,
                         const maps::Map& map, const fs::path& city_file, const fs::path& run_dir,
                         const fs::path& logs_dir, const fs::path& bin_dir) {
  const fs::path base_file = fs::absolute(scenario.city);
  const fs::path base_dir = base_file.parent_path();
  YAML::Node city;
  try {
    city = YAML::LoadFile(base_file.string());
  } catch (const YAML::Exception& e) {
    throw ConfigError(fmt::format("{}: {}", base_file.string(), e.what()));
  }
  const auto refuse = [&](const std::vector<std::string>& keypath, const std::string& message) {
    throw ConfigError(LocateInFile(scenario_file, keypath, message));
  };
  if (!city.IsMap() || !city["sim"] || !city["name"] || !city["map"]) {
    refuse({"city"}, fmt::format("{} has no sim section (the simulator's cars): a scenario "
                                 "runs in the simulator",
                                 base_file.string()));
  }
  ComposedCity out;
  out.city_name = city["name"].as<std::string>();
  out.map_path = Absolute(base_dir, city["map"].as<std::string>());
  city["map"] = out.map_path;
  if (city["operators"] && city["operators"]["allowed"] &&
      city["operators"]["allowed"].size() > 0) {
    out.operator_name = city["operators"]["allowed"][0].as<std::string>();
  }

  // Routes: every lane on the map, each reachable from the one before.
  for (std::size_t i = 0; i < scenario.vehicles.size(); ++i) {
    const VehicleSpec& v = scenario.vehicles[i];
    const std::string vi = fmt::format("[{}]", i);
    if (v.spawn.lane && map.FindLane(*v.spawn.lane) == nullptr) {
      refuse({"vehicles", vi, "spawn", "lane"},
             fmt::format("map {} has no lane \"{}\" (autodrive-map info lists them)", map.name,
                         *v.spawn.lane));
    }
    const maps::Lane* before = nullptr;
    // With laps, the first lane follows the last (checked as the route's lane after its end).
    for (std::size_t k = 0; k < v.route.size() + (v.laps > 1 ? 1 : 0); ++k) {
      const std::string ki = fmt::format("[{}]", k % v.route.size());
      const maps::Lane* lane = map.FindLane(v.route[k % v.route.size()]);
      if (lane == nullptr) {
        refuse({"vehicles", vi, "route", ki},
               fmt::format("map {} has no lane \"{}\" (autodrive-map info lists them)", map.name,
                           v.route[k % v.route.size()]));
      }
      if (before != nullptr) {
        const bool successor = std::find(before->successors.begin(), before->successors.end(),
                                         lane->id) != before->successors.end();
        const bool movement =
            std::any_of(before->movements_out.begin(), before->movements_out.end(),
                        [&](MovementId m) { return map.movement(m).to == lane->id; });
        if (!successor && !movement) {
          refuse({"vehicles", vi, "route", ki},
                 fmt::format("lane {} does not follow {} (neither a successor nor the end of a "
                             "movement from it){}",
                             lane->name, before->name,
                             k == v.route.size() ? ": laps need a closed route" : ""));
        }
      }
      before = lane;
    }
  }
  // Events: intersections of the map, plans of the city, an operator to send them.
  for (std::size_t i = 0; i < scenario.events.size(); ++i) {
    const EventSpec& e = scenario.events[i];
    const std::string ei = fmt::format("[{}]", i);
    if (!e.host.empty()) continue;      // a light host's link: checked with the launch below
    if (!e.obstacle.empty()) continue;  // one of the scenario's obstacles: checked on load
    if (!e.camera.empty()) continue;    // a simulated camera: checked with the sim section
    if (e.action == "surge") {
      for (const auto& [lane, key] : {std::pair{&e.from, "from"}, {&e.to, "to"}}) {
        if (!lane->empty() && map.FindLane(*lane) == nullptr) {
          refuse({"events", ei, key},
                 fmt::format("map {} has no lane \"{}\" (autodrive-map info lists them)", map.name,
                             *lane));
        }
      }
      const bool route_files = city["traffic"] && city["traffic"]["route_files"] &&
                               city["traffic"]["route_files"].size() > 0;
      if (!e.type.empty() && e.type != "nigel" && e.type != "bus" && e.type != "emergency" &&
          !route_files) {
        refuse({"events", ei, "type"},
               fmt::format("SUMO type \"{}\" is not one of nigel, bus, emergency (and {} "
                           "gives no route files with types of their own)",
                           e.type, base_file.string()));
      }
      continue;
    }
    if (e.head != 0) {
      if (!map.HasSignalHead(SignalHeadId(static_cast<std::uint32_t>(e.head)))) {
        refuse({"events", ei, "head"},
               fmt::format("map {} has no signal head {}", map.name, e.head));
      }
      continue;
    }
    const auto x =
        std::find_if(map.intersections.begin(), map.intersections.end(),
                     [&](const maps::Intersection& y) { return y.name == e.intersection; });
    if (x == map.intersections.end()) {
      refuse({"events", ei, "intersection"},
             fmt::format("map {} has no intersection \"{}\"", map.name, e.intersection));
    }
    if ((e.action == "mode" || e.action == "plan") && out.operator_name.empty()) {
      refuse({"events", ei, "action"},
             fmt::format("{} allows no operator (operators.allowed): nobody may change a mode "
                         "or plan",
                         base_file.string()));
    }
    if (e.action == "plan" && e.plan != "auto") {
      bool found = false;
      for (const auto& xc : city["intersections"]) {
        if (xc["name"] && xc["name"].as<std::string>() == e.intersection) {
          for (const auto& p : xc["plans"]) found = found || p["name"].as<std::string>() == e.plan;
        }
      }
      if (!found) {
        refuse({"events", ei, "plan"}, fmt::format("{} has no plan \"{}\" for {}",
                                                   base_file.string(), e.plan, e.intersection));
      }
    }
  }

  // The simulator: the scenario's cars (keeping what the base city says of a car of the same
  // name), seed, noise and obstacles; lockstep.
  YAML::Node sim = city["sim"];
  sim["seed"] = scenario.seed;
  YAML::Node vehicles(YAML::NodeType::Sequence);
  for (const VehicleSpec& v : scenario.vehicles) {
    YAML::Node car(YAML::NodeType::Map);
    if (sim["vehicles"]) {
      for (const auto& base : sim["vehicles"]) {
        if (base["name"] && base["name"].as<std::string>() == v.name) car = YAML::Clone(base);
      }
    }
    car["name"] = v.name;
    YAML::Node spawn(YAML::NodeType::Map);
    if (v.spawn.lane) {
      spawn["lane"] = *v.spawn.lane;
      spawn["along_m"] = v.spawn.along_m;
    } else {
      spawn["x_m"] = *v.spawn.x_m;
      spawn["y_m"] = *v.spawn.y_m;
      spawn["yaw_rad"] = *v.spawn.yaw_rad;
    }
    car["spawn"] = spawn;
    if (v.sensors) car["sensors"] = YAML::Load(config::SaveString(*v.sensors));
    vehicles.push_back(car);
  }
  sim["vehicles"] = vehicles;
  YAML::Node variability =
      sim["variability"] ? sim["variability"] : YAML::Node(YAML::NodeType::Map);
  for (const auto& [preset, name] : ConfigEnumNames(scenario.noise)) {
    if (preset == scenario.noise) variability["preset"] = std::string(name);
  }
  YAML::Node obstacles(YAML::NodeType::Sequence);
  if (variability["obstacles"]) obstacles = variability["obstacles"];
  for (const auto& o : scenario.TimedObstacles()) {
    YAML::Node n(YAML::NodeType::Map);
    if (!o.name.empty()) n["name"] = o.name;
    if (o.from_s > Duration{0}) n["from_s"] = ToSeconds(o.from_s);
    if (o.until_s) n["until_s"] = ToSeconds(*o.until_s);
    n["x_m"] = o.x_m;
    n["y_m"] = o.y_m;
    n["yaw_rad"] = o.yaw_rad;
    n["length_m"] = o.length_m;
    n["width_m"] = o.width_m;
    n["height_m"] = o.height_m;
    obstacles.push_back(n);
  }
  if (obstacles.size() > 0) variability["obstacles"] = obstacles;
  // The random obstacles keep clear of the cars' goal poses as of their starts.
  for (const VehicleSpec& v : scenario.vehicles) {
    if (!v.goal) continue;
    YAML::Node point(YAML::NodeType::Map);
    point["x_m"] = v.goal->x_m;
    point["y_m"] = v.goal->y_m;
    variability["keep_clear"].push_back(point);
  }
  sim["variability"] = variability;
  for (auto cam : sim["cameras"]) {
    if (cam["lens"] && cam["lens"]["calibration"]) {
      cam["lens"]["calibration"] = Absolute(base_dir, cam["lens"]["calibration"].as<std::string>());
    }
  }
  // A camera lost: the simulator sends no frame of it from..until (its own clock).
  const auto outages = scenario.CameraOutages();
  for (std::size_t i = 0; i < scenario.events.size(); ++i) {
    const EventSpec& e = scenario.events[i];
    if (e.camera.empty()) continue;
    std::vector<std::string> names;
    bool found = false;
    for (auto cam : sim["cameras"]) {
      const std::string name = cam["name"] ? cam["name"].as<std::string>() : "";
      names.push_back(name);
      if (name != e.camera) continue;
      found = true;
      const auto& [from, until] = outages.at(name);
      cam["lost_from_s"] = ToSeconds(from);
      if (until) cam["lost_until_s"] = ToSeconds(*until);
    }
    if (!found) {
      refuse({"events", fmt::format("[{}]", i), "camera"},
             fmt::format("{}'s simulator has no overhead camera \"{}\" (it has: {})",
                         base_file.string(), e.camera,
                         names.empty() ? "none" : fmt::format("{}", fmt::join(names, ", "))));
    }
  }
  if (scenario.eye && !city["eye"]) {
    refuse({"eye"},
           fmt::format("{} has no eye section: there is no Eye to run", base_file.string()));
  }
  const bool surges =
      std::ranges::any_of(scenario.events, [](const EventSpec& e) { return e.action == "surge"; });
  out.traffic = scenario.traffic.vehicles > 0 || surges;
  if (out.traffic) {
    YAML::Node traffic = city["traffic"] ? city["traffic"] : YAML::Node(YAML::NodeType::Map);
    traffic["seed"] = scenario.seed;
    traffic["vehicles"] = scenario.traffic.vehicles;
    // A surge is one more flow of SUMO's demand, from the event's time on: SUMO's own clock
    // sends them, step by step with the rest.
    YAML::Node flows = traffic["flows"] ? traffic["flows"] : YAML::Node(YAML::NodeType::Sequence);
    for (const EventSpec& e : scenario.events) {
      if (e.action != "surge") continue;
      YAML::Node f(YAML::NodeType::Map);
      f["from"] = e.from;
      if (!e.to.empty()) f["to"] = e.to;
      f["per_hour"] = e.per_hour;
      f["count"] = e.count;
      if (!e.type.empty()) f["type"] = e.type;
      f["begin_s"] = ToSeconds(e.at_s);
      flows.push_back(f);
    }
    if (flows.size() > 0) traffic["flows"] = flows;
    // SUMO's own trip statistics of its cars (waiting time, time loss), written as it closes;
    // those still driving then are written too, so that every car that departed counts.
    YAML::Node sumo = traffic["sumo"] ? traffic["sumo"] : YAML::Node(YAML::NodeType::Map);
    YAML::Node args = sumo["args"] ? sumo["args"] : YAML::Node(YAML::NodeType::Sequence);
    args.push_back("--tripinfo-output");
    args.push_back((fs::absolute(logs_dir) / kTripinfoFile).lexically_normal().string());
    args.push_back("--tripinfo-output.write-unfinished");
    args.push_back("true");
    sumo["args"] = args;
    traffic["sumo"] = sumo;
    city["traffic"] = traffic;
  } else {
    city.remove("traffic");
  }
  out.controllers.emplace_back(kRunnerController);
  if (out.traffic) out.controllers.emplace_back("traffic");
  for (const VehicleSpec& v : scenario.vehicles) {
    if (v.agent) out.controllers.push_back(AgentController(v.name));
  }
  YAML::Node service = sim["service"] ? sim["service"] : YAML::Node(YAML::NodeType::Map);
  service["mode"] = "lockstep";
  YAML::Node stages(YAML::NodeType::Sequence);
  // The lights and the Eye first (the SCM decides on what they said), then the SCM. A map
  // without signal heads (the Parking School) has no light host to run.
  const bool has_lights = !map.signal_heads.empty();
  {
    YAML::Node first(YAML::NodeType::Sequence);
    if (has_lights) first.push_back("lights");
    if (scenario.eye) first.push_back("eye");
    YAML::Node second(YAML::NodeType::Sequence);
    second.push_back("scm");
    for (YAML::Node s : {first, second}) {
      if (s.size() == 0) continue;
      s.SetStyle(YAML::EmitterStyle::Flow);
      stages.push_back(s);
    }
  }
  service["stages"] = stages;
  YAML::Node controllers(YAML::NodeType::Sequence);
  for (const std::string& c : out.controllers) controllers.push_back(c);
  service["controllers"] = controllers;
  service["duration_s"] = std::chrono::duration<double>(scenario.time_limit_s).count();
  service["control_period_s"] = std::chrono::duration<double>(scenario.step_s).count();
  service.remove("real_time_factor");
  sim["service"] = service;

  // The SCM's fleet and the Eye's cars: the scenario's.
  if (city["fleet"]) {
    YAML::Node names(YAML::NodeType::Sequence);
    for (const VehicleSpec& v : scenario.vehicles) names.push_back(v.name);
    city["fleet"]["vehicles"] = names;
  }
  if (city["eye"]) {
    for (auto cam : city["eye"]["cameras"]) {
      if (cam["calibration"]) {
        cam["calibration"] = Absolute(base_dir, cam["calibration"].as<std::string>());
      }
    }
    if (city["eye"]["vehicles"]) {
      YAML::Node kept(YAML::NodeType::Sequence);
      for (const auto& e : city["eye"]["vehicles"]) {
        const std::string name = e["name"].as<std::string>();
        if (std::any_of(scenario.vehicles.begin(), scenario.vehicles.end(),
                        [&](const VehicleSpec& v) { return v.name == name; })) {
          kept.push_back(e);
        }
      }
      city["eye"]["vehicles"] = kept;
    }
  }

  // The launch: the lights, the SCM, the simulator, SUMO, the Eye when asked for, and the
  // agents; no dashboard, no example driver for the whole city.
  std::string lights_config = Absolute(base_dir, "../infra/" + out.city_name + ".yaml");
  if (city["launch"] && city["launch"]["lights"] && city["launch"]["lights"]["config"]) {
    lights_config = Absolute(base_dir, city["launch"]["lights"]["config"].as<std::string>());
  }
  // A link event names the light host: the one the city runs (its configuration's `name`).
  for (std::size_t i = 0; i < scenario.events.size(); ++i) {
    const EventSpec& e = scenario.events[i];
    if (e.host.empty()) continue;
    std::string name;
    try {
      const YAML::Node lights = YAML::LoadFile(lights_config);
      if (lights["name"]) name = lights["name"].as<std::string>();
    } catch (const YAML::Exception& error) {
      throw ConfigError(fmt::format("{}: {}", lights_config, error.what()));
    }
    if (e.host != name) {
      refuse({"events", fmt::format("[{}]", i), "host"},
             fmt::format("the city's light host is \"{}\" ({}), not \"{}\"", name, lights_config,
                         e.host));
    }
  }
  YAML::Node launch(YAML::NodeType::Map);
  launch["run_dir"] = fs::absolute(run_dir).lexically_normal().string();
  launch["lights"]["config"] = lights_config;
  if (!has_lights) launch["lights"]["mode"] = "off";
  launch["eye"]["mode"] = scenario.eye ? "on" : "off";
  launch["driver"]["mode"] = "off";
  launch["dashboard"]["mode"] = "off";
  launch["stop_grace_s"] = 10.0;
  YAML::Node agents(YAML::NodeType::Sequence);
  for (const VehicleSpec& v : scenario.vehicles) {
    if (!v.agent) continue;
    std::vector<std::string> words = v.agent->command;
    if (v.agent->driver) {
      words = {"autodrive-example-driver",
               "--city",
               "{city}",
               "--vehicles",
               "{vehicle}",
               "--lockstep",
               "{lockstep}",
               "--seed",
               std::to_string(scenario.seed),
               "--log-level",
               "warn"};
      if (!v.route.empty()) {
        words.insert(words.end(), {"--route", "{route}", "--stop-at-route-end"});
      }
      words.insert(words.end(), v.agent->driver->begin(), v.agent->driver->end());
    }
    const std::vector<std::pair<std::string, std::string>> with{
        {"{city}", fs::absolute(city_file).lexically_normal().string()},
        {"{vehicle}", v.name},
        {"{seed}", std::to_string(scenario.seed)},
        {"{goal}", v.goal ? fmt::format("{},{},{}", v.goal->x_m, v.goal->y_m, v.goal->yaw_rad)
                          : std::string()},
        {"{route}", fmt::format("{}", fmt::join(v.DrivenRoute(), ","))},
        {"{lockstep}", AgentController(v.name)},
        {"{run}", fs::absolute(run_dir).lexically_normal().string()},
        {"{scenario}", fs::absolute(scenario_file).lexically_normal().string()}};
    YAML::Node agent(YAML::NodeType::Map);
    agent["name"] = AgentController(v.name);
    YAML::Node command(YAML::NodeType::Sequence);
    for (std::size_t k = 0; k < words.size(); ++k) {
      const std::string word = Substitute(words[k], with);
      command.push_back(k == 0 ? ResolveProgram(word, bin_dir) : word);
    }
    agent["command"] = command;
    agent["restart"] = "never";
    if (!v.agent->env.empty()) {
      YAML::Node env(YAML::NodeType::Sequence);
      for (const std::string& e : v.agent->env) env.push_back(Substitute(e, with));
      agent["env"] = env;
    }
    agents.push_back(agent);
  }
  if (agents.size() > 0) launch["agents"] = agents;
  launch["external_controllers"].push_back(std::string(kRunnerController));
  city["launch"] = launch;

  YAML::Emitter emitter;
  emitter << city;
  out.yaml = fmt::format(
      "# Composed by autodrive-scenario from {} (scenario {}) and {}: do not edit; edit the "
      "scenario.\n{}\n",
      fs::absolute(scenario_file).lexically_normal().string(), scenario.name, base_file.string(),
      emitter.c_str());
  return out;
}

}  // namespace autodrive::scenarios
