#include "scenarios/scenario.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <map>
#include <set>

#include "common/error.h"

namespace autodrive::scenarios {

namespace {

bool IsPlainName(const std::string& s) {
  return !s.empty() && s.find_first_not_of(
                           "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                           "0123456789_-") == std::string::npos;
}

}  // namespace

void AgentSpec::Validate() const {
  if (driver.has_value() == !command.empty()) {
    throw InputError(
        "give exactly one of driver (the example lane driver's extra arguments, [] for none) "
        "and command (a program of your own)");
  }
}

void VehicleSpec::Validate() const {
  if (name.rfind("nigel_", 0) != 0 || name.size() == 6 ||
      name.find_first_not_of("0123456789", 6) != std::string::npos) {
    throw InputError(fmt::format("name: \"{}\" is not nigel_<n>", name));
  }
  spawn.Validate();
  if (goal && !route.empty()) {
    throw InputError("goal: a car has a route (its goal the route's end) or a goal pose, not both");
  }
  if (laps > 1 && route.empty()) throw InputError("laps: laps of a route; this car has none");
}

std::vector<std::string> VehicleSpec::DrivenRoute() const {
  std::vector<std::string> out;
  for (int lap = 0; lap < laps; ++lap) out.insert(out.end(), route.begin(), route.end());
  return out;
}

void EventSpec::Validate() const {
  // Each action's keys; every other key is refused.
  static const std::map<std::string, std::vector<std::string>> kKeys{
      {"mode", {"intersection", "mode"}},
      {"plan", {"intersection", "plan"}},
      {"preempt", {"intersection", "vehicle"}},
      {"priority", {"intersection", "vehicle"}},
      {"cancel", {"intersection", "vehicle"}},
      {"lamp", {"head", "lamp", "fault"}},
      {"unplug", {"head"}},
      {"plug", {"head"}},
      {"link_cut", {"host"}},
      {"link_restore", {"host"}},
      {"place", {"obstacle"}},
      {"remove", {"obstacle"}},
      {"camera_lost", {"camera"}},
      {"camera_back", {"camera"}},
      {"surge", {"from", "per_hour", "count"}},
  };
  static const std::set<std::string> kOptional{"to", "type"};  // surge's
  const std::map<std::string, bool> given{
      {"intersection", !intersection.empty()},
      {"mode", !mode.empty()},
      {"plan", !plan.empty()},
      {"vehicle", !vehicle.empty()},
      {"head", head != 0},
      {"lamp", !lamp.empty()},
      {"fault", !fault.empty()},
      {"host", !host.empty()},
      {"obstacle", !obstacle.empty()},
      {"camera", !camera.empty()},
      {"from", !from.empty()},
      {"to", !to.empty()},
      {"per_hour", per_hour != 0},
      {"count", count != 0},
      {"type", !type.empty()},
  };
  if (when && (action == "place" || action == "remove" || action == "camera_lost" ||
               action == "camera_back" || action == "surge")) {
    throw InputError(
        fmt::format("action {} takes no when: the simulator and SUMO apply it on "
                    "their own clocks, from at_s",
                    action));
  }
  const std::vector<std::string>& needed = kKeys.at(action);
  for (const std::string& key : needed) {
    if (!given.at(key)) throw InputError(fmt::format("action {} needs {}", action, key));
  }
  for (const auto& [key, present] : given) {
    const bool takes = std::ranges::find(needed, key) != needed.end() ||
                       (action == "surge" && kOptional.contains(key));
    if (present && !takes) throw InputError(fmt::format("action {} takes no {}", action, key));
  }
}

void Scenario::Validate() const {
  if (!IsPlainName(name)) {
    throw InputError(fmt::format("name: \"{}\" (letters, digits, '_' and '-' only)", name));
  }
  if (vehicles.empty()) throw InputError("vehicles: at least one car");
  std::set<std::string> names;
  for (const VehicleSpec& v : vehicles) {
    if (!names.insert(v.name).second) {
      throw InputError(fmt::format("vehicles: {} is listed twice", v.name));
    }
  }
  for (const EventSpec& e : events) {
    for (const std::string* v : {&e.vehicle, e.when ? &e.when->vehicle : nullptr}) {
      if (v != nullptr && !v->empty() && !names.contains(*v)) {
        throw InputError(fmt::format("events: vehicle {} is not one of the scenario's cars ({})",
                                     *v, fmt::join(names, ", ")));
      }
    }
  }
  std::set<std::string> obstacle_names;
  for (std::size_t i = 0; i < obstacles.size(); ++i) {
    const vehicle_sim::UnmappedObstacle& o = obstacles[i];
    if (o.timed()) {
      throw InputError(
          fmt::format("obstacles[{}]: from_s and until_s are set by place and remove events", i));
    }
    if (!o.name.empty() && !obstacle_names.insert(o.name).second) {
      throw InputError(fmt::format("obstacles: {} is listed twice", o.name));
    }
  }
  (void)TimedObstacles();
  (void)CameraOutages();
  const auto& known = RunMetricNames();
  for (const auto& [metric, text] : expect) {
    if (std::find(known.begin(), known.end(), metric) == known.end()) {
      throw InputError(fmt::format("expect: {} is not a run metric (known: {})", metric,
                                   fmt::join(known, ", ")));
    }
    try {
      (void)ParseExpectation(text);
    } catch (const InputError& e) {
      throw InputError(fmt::format("expect.{}: {}", metric, e.what()));
    }
  }
}

std::vector<vehicle_sim::UnmappedObstacle> Scenario::TimedObstacles() const {
  std::vector<vehicle_sim::UnmappedObstacle> out = obstacles;
  std::vector<bool> placed(out.size()), removed(out.size());
  for (const EventSpec& e : events) {
    if (e.action != "place" && e.action != "remove") continue;
    const auto it =
        std::find_if(out.begin(), out.end(), [&](const auto& o) { return o.name == e.obstacle; });
    if (it == out.end()) {
      std::vector<std::string> known;
      for (const auto& o : obstacles) {
        if (!o.name.empty()) known.push_back(o.name);
      }
      throw InputError(fmt::format(
          "events: obstacle {} is not one of the scenario's named "
          "obstacles ({})",
          e.obstacle, known.empty() ? "none" : fmt::format("{}", fmt::join(known, ", "))));
    }
    const auto k = static_cast<std::size_t>(it - out.begin());
    if (e.action == "place") {
      if (placed[k])
        throw InputError(fmt::format("events: obstacle {} is placed twice", e.obstacle));
      placed[k] = true;
      it->from_s = e.at_s;
    } else {
      if (removed[k]) {
        throw InputError(fmt::format("events: obstacle {} is removed twice", e.obstacle));
      }
      removed[k] = true;
      it->until_s = e.at_s;
    }
  }
  for (const auto& o : out) {
    if (o.until_s && *o.until_s <= o.from_s) {
      throw InputError(
          fmt::format("events: obstacle {} is removed at {} s, not after it is "
                      "placed at {} s",
                      o.name, ToSeconds(*o.until_s), ToSeconds(o.from_s)));
    }
  }
  return out;
}

std::map<std::string, std::pair<Duration, std::optional<Duration>>> Scenario::CameraOutages()
    const {
  std::map<std::string, std::pair<Duration, std::optional<Duration>>> out;
  std::vector<const EventSpec*> backs;
  for (const EventSpec& e : events) {
    if (e.action == "camera_back") backs.push_back(&e);
    if (e.action != "camera_lost") continue;
    if (!out.emplace(e.camera, std::pair{e.at_s, std::optional<Duration>{}}).second) {
      throw InputError(fmt::format("events: camera {} is lost twice", e.camera));
    }
  }
  std::set<std::string> back;
  for (const EventSpec* e : backs) {
    const auto it = out.find(e->camera);
    if (it == out.end()) {
      throw InputError(fmt::format("events: camera {} comes back but is never lost", e->camera));
    }
    if (!back.insert(e->camera).second) {
      throw InputError(fmt::format("events: camera {} comes back twice", e->camera));
    }
    if (e->at_s <= it->second.first) {
      throw InputError(
          fmt::format("events: camera {} comes back at {} s, not after it is lost "
                      "at {} s",
                      e->camera, ToSeconds(e->at_s), ToSeconds(it->second.first)));
    }
    it->second.second = e->at_s;
  }
  return out;
}

bool Expectation::Holds(double x) const {
  if (std::isnan(x)) return false;
  if (op == "<") return x < value;
  if (op == "<=") return x <= value;
  if (op == "==") return x == value;
  if (op == "!=") return x != value;
  if (op == ">=") return x >= value;
  return x > value;
}

Expectation ParseExpectation(std::string_view text) {
  std::size_t i = text.find_first_not_of(' ');
  Expectation e;
  for (std::string_view op : {"<=", ">=", "==", "!=", "<", ">"}) {
    if (i != std::string_view::npos && text.substr(i, op.size()) == op) {
      e.op = op;
      i += op.size();
      break;
    }
  }
  if (e.op.empty()) {
    throw InputError(fmt::format(
        "\"{}\" is not a comparison (expected <op> <number>, op one of < <= == != >= >)", text));
  }
  i = text.find_first_not_of(' ', i);
  std::size_t end = text.find_last_not_of(' ');
  if (i == std::string_view::npos || end < i) {
    throw InputError(fmt::format("\"{}\": a number must follow {}", text, e.op));
  }
  const char* first = text.data() + i;
  const char* last = text.data() + end + 1;
  const auto [ptr, ec] = std::from_chars(first, last, e.value);
  if (ec != std::errc{} || ptr != last || !std::isfinite(e.value)) {
    throw InputError(fmt::format("\"{}\": a number must follow {}", text, e.op));
  }
  return e;
}

const std::vector<std::string_view>& RunMetricNames() {
  static const std::vector<std::string_view> names{
      "collisions",
      "red_light_violations",
      "stop_sign_violations",
      "lane_departures",
      "infractions",
      "route_completion",
      "goals_reached",
      "time_to_goal_s",
      "distance_m",
      "infractions_per_km",
      "score",
      "stops",
      "stopped_time_s",
      "time_loss_s",
      "max_accel_mps2",
      "max_jerk_mps3",
      "energy_j_per_kg",
      "spat_messages",
      "spat_windows_below_10hz",
      "spat_min_end_error_p95_s",
      "map_messages",
      "requests",
      "requests_granted",
      "request_to_green_max_s",
      "background_trips",
      "background_waiting_time_mean_s",
      "background_time_loss_mean_s",
  };
  return names;
}

std::string LocateInFile(const std::filesystem::path& file, const std::vector<std::string>& keypath,
                         const std::string& message) {
  std::string where;
  for (const std::string& k : keypath) where += (k.front() == '[' || where.empty() ? "" : ".") + k;
  try {
    YAML::Node node = YAML::LoadFile(file.string());
    YAML::Mark mark = node.Mark();
    for (const std::string& k : keypath) {
      YAML::Node next;
      if (k.front() == '[') {
        next = node[std::stoul(k.substr(1, k.size() - 2))];
      } else {
        next = node[k];
      }
      if (!next) break;
      node = next;
      mark = node.Mark();
    }
    return fmt::format("{}:{}:{}: {}: {}", file.string(), mark.line + 1, mark.column + 1, where,
                       message);
  } catch (const YAML::Exception&) {
    return fmt::format("{}: {}: {}", file.string(), where, message);
  }
}

Scenario LoadScenario(const std::filesystem::path& path) {
  Scenario s = config::LoadFile<Scenario>(path);
  s.city = (std::filesystem::absolute(path).parent_path() / s.city).lexically_normal().string();
  if (!std::filesystem::exists(s.city)) {
    throw ConfigError(LocateInFile(path, {"city"}, s.city + " does not exist"));
  }
  return s;
}

}  // namespace autodrive::scenarios
