#include "scenarios/scenario.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
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
}

void EventSpec::Validate() const {
  const auto need = [&](const std::string& value, const char* key) {
    if (value.empty()) throw InputError(fmt::format("action {} needs {}", action, key));
  };
  const auto refuse = [&](const std::string& value, const char* key) {
    if (!value.empty()) throw InputError(fmt::format("action {} takes no {}", action, key));
  };
  if (action == "link_cut" || action == "link_restore") {
    need(host, "host");
    if (head != 0) throw InputError(fmt::format("action {} takes no head", action));
    for (const auto& [value, key] : {std::pair{&intersection, "intersection"},
                                     {&mode, "mode"},
                                     {&plan, "plan"},
                                     {&vehicle, "vehicle"},
                                     {&lamp, "lamp"},
                                     {&fault, "fault"}}) {
      refuse(*value, key);
    }
    return;
  }
  refuse(host, "host");
  if (action == "lamp" || action == "unplug" || action == "plug") {
    if (head == 0) throw InputError(fmt::format("action {} needs head", action));
    refuse(intersection, "intersection");
    refuse(mode, "mode");
    refuse(plan, "plan");
    refuse(vehicle, "vehicle");
    if (action == "lamp") {
      need(lamp, "lamp");
      need(fault, "fault");
    } else {
      refuse(lamp, "lamp");
      refuse(fault, "fault");
    }
    return;
  }
  if (head != 0) throw InputError(fmt::format("action {} takes no head", action));
  refuse(lamp, "lamp");
  refuse(fault, "fault");
  need(intersection, "intersection");
  if (action == "mode") {
    need(mode, "mode");
    refuse(plan, "plan");
    refuse(vehicle, "vehicle");
  } else if (action == "plan") {
    need(plan, "plan");
    refuse(mode, "mode");
    refuse(vehicle, "vehicle");
  } else {
    need(vehicle, "vehicle");
    refuse(mode, "mode");
    refuse(plan, "plan");
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
    if (!e.vehicle.empty() && !names.contains(e.vehicle)) {
      throw InputError(fmt::format("events: vehicle {} is not one of the scenario's cars ({})",
                                   e.vehicle, fmt::join(names, ", ")));
    }
  }
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
