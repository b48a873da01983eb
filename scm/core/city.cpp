#include "scm/core/city.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "common/error.h"
#include "maps/map_io.h"
#include "scm/core/intergreen.h"
#include "scm/core/internal/intersection_build.h"

namespace autodrive::scm {

void TimingConfig::Validate() const {
  if (min_green_s > max_green_s) {
    throw InputError(fmt::format("min_green_s {} is above max_green_s {}", ToSeconds(min_green_s),
                                 ToSeconds(max_green_s)));
  }
}

void SetPlanCycle(const std::vector<SignalGroup>& groups, Plan& plan) {
  plan.phase_starts.clear();
  Duration t{0};
  for (std::size_t k = 0; k < plan.phases.size(); ++k) {
    plan.phase_starts.push_back(t);
    const auto& next = plan.phases[(k + 1) % plan.phases.size()].groups;
    Duration yellow{0};
    Duration red{0};
    for (std::size_t g : plan.phases[k].groups) {
      if (std::ranges::find(next, g) != next.end()) continue;
      yellow = std::max(yellow, groups[g].timing.yellow);
      red = std::max(red, groups[g].timing.red_clearance);
    }
    t += plan.phases[k].green + yellow + red;
  }
  plan.cycle = t;
}

std::string_view ToString(PlanType type) {
  switch (type) {
    case PlanType::kFixed:
      return "fixed";
    case PlanType::kActuated:
      return "actuated";
    case PlanType::kFlash:
      return "flash";
    case PlanType::kDark:
      return "dark";
  }
  return "?";
}

std::optional<std::size_t> IntersectionModel::GroupIndex(SignalGroupId group_id) const {
  for (std::size_t i = 0; i < groups.size(); ++i) {
    if (groups[i].id == group_id) return i;
  }
  return std::nullopt;
}

std::optional<std::size_t> IntersectionModel::PlanIndex(std::string_view plan_name) const {
  for (std::size_t i = 0; i < plans.size(); ++i) {
    if (plans[i].name == plan_name) return i;
  }
  return std::nullopt;
}

std::optional<std::size_t> IntersectionModel::GroupOfMovement(MovementId movement) const {
  for (std::size_t i = 0; i < groups.size(); ++i) {
    if (std::ranges::find(groups[i].movements, movement) != groups[i].movements.end()) return i;
  }
  return std::nullopt;
}

std::size_t IntersectionModel::ScheduledPlan(int minute_of_day) const {
  // The last entry at or before the minute; before the first entry of the day, the day's last.
  std::size_t plan = schedule.back().plan;
  for (const auto& entry : schedule) {
    if (entry.minute_of_day <= minute_of_day) plan = entry.plan;
  }
  return plan;
}

const IntersectionModel* City::Find(IntersectionId intersection_id) const {
  for (const auto& x : intersections) {
    if (x.id == intersection_id) return &x;
  }
  return nullptr;
}

const IntersectionModel* City::Find(std::string_view intersection_name) const {
  for (const auto& x : intersections) {
    if (x.name == intersection_name || std::to_string(x.id.value()) == intersection_name) {
      return &x;
    }
  }
  return nullptr;
}

void NarrowToDistrict(City& city, std::string_view name) {
  const maps::District* district = city.districts.Find(name);
  if (district == nullptr) {
    throw InputError(fmt::format("city {} has no district {} ({})", city.config.name, name,
                                 city.districts.empty() ? "it has no districts: section"
                                                        : "it has: " + city.districts.Names()));
  }
  std::erase_if(city.intersections, [&](const IntersectionModel& x) {
    return std::ranges::find(district->intersections, x.id) == district->intersections.end();
  });
  city.district = district->name;
}

std::uint32_t DistrictDomain(const std::filesystem::path& path, std::string_view name,
                             std::optional<std::uint32_t> requested) {
  const auto config = config::LoadString<CityConfig>(config::ReadFile(path), path.string());
  const auto it = std::ranges::find(config.districts, name, &maps::DistrictConfig::name);
  if (it == config.districts.end()) {
    std::string names;
    for (const auto& d : config.districts) names += (names.empty() ? "" : ", ") + d.name;
    throw InputError(
        fmt::format("{}: no district {} ({})", path.string(), name,
                    names.empty() ? "the city has no districts: section" : "it has: " + names));
  }
  if (requested && *requested != it->domain) {
    throw InputError(fmt::format("district {} is on DDS domain {} ({}), not on --domain {}",
                                 it->name, it->domain, path.string(), *requested));
  }
  return it->domain;
}

Duration Scaled(nanoseconds configured, double time_scale) {
  return FromSeconds(ToSeconds(configured) * time_scale);
}

namespace {

using internal::MapSite;
using internal::Where;

std::string Seconds(Duration d) { return fmt::format("{:g} s", ToSeconds(d)); }

/// Computes `x`'s intergreen matrix (its groups and conflicts built) and checks that each
/// group's clearance, its yellow and red clearance, reaches every entry of its row.
void SetIntergreens(const SafetyConfig& safety, const maps::Map& map, IntergreenCache& cache,
                    const Where& where, IntersectionModel& x) {
  const IntergreenInputs inputs{safety.clearing_vehicles, safety.entering_speed_mps,
                                safety.crossing_time_s};
  const auto entries = ComputeIntergreens(map, x, inputs, &cache);
  const std::size_t n = x.groups.size();
  x.intergreens.assign(n, std::vector<Duration>(n, Duration{0}));
  for (std::size_t a = 0; a < n; ++a) {
    const GroupTiming& t = x.groups[a].timing;
    for (std::size_t b = 0; b < n; ++b) {
      if (!entries[a][b]) continue;
      const IntergreenEntry& e = *entries[a][b];
      x.intergreens[a][b] = FromSeconds(e.intergreen_s);
      if (t.yellow + t.red_clearance >= x.intergreens[a][b]) continue;
      where.Fail(fmt::format(
          "groups {} > {}: the clearance of group {}, yellow {} + red clearance {} = {}, is "
          "below the intergreen {} the map gives ({} clearing: ({:.2f} m + {:.3f} m) / {:g} m/s "
          "= {:.2f} s, entering {:.2f} m / {:g} m/s = {:.2f} s, t_cross {:g} s; `scmctl show X "
          "--intergreen`); rule: a clearance may exceed the intergreen matrix, never undercut it",
          internal::GroupLabel(x.groups[a]), internal::GroupLabel(x.groups[b]),
          x.groups[a].id.value(), Seconds(t.yellow), Seconds(t.red_clearance),
          Seconds(t.yellow + t.red_clearance), Seconds(x.intergreens[a][b]), e.vehicle,
          e.clearing_path_m, e.vehicle_length_m, e.clearing_speed_mps, e.clearing_time_s,
          e.entering_path_m, inputs.entering_speed_mps, e.entering_time_s, e.crossing_time_s));
    }
  }
}

/// Sets `x`'s pre-emption parameters (its groups and plans built) and checks them: no green is
/// ended or timed below its min green, which the conflict monitor holds every green to, and
/// every plan with phases has a phase driving all the track groups (docs/controller.md,
/// "Pre-emption").
void SetPreempt(const PriorityConfig& cfg, double scale, const Where& where, IntersectionModel& x) {
  PriorityParams& p = x.priority;
  p.preempt_delay = Scaled(cfg.preempt_delay_s, scale);
  p.preempt_min_duration = Scaled(cfg.preempt_min_duration_s, scale);
  if (cfg.preempt_min_green_s) p.preempt_min_green = Scaled(*cfg.preempt_min_green_s, scale);
  p.preempt_track_green = Scaled(cfg.preempt_track_green_s, scale);
  p.preempt_dwell_green = Scaled(cfg.preempt_dwell_green_s, scale);
  for (const std::uint32_t id : cfg.preempt_track_groups) {
    p.preempt_track_groups.push_back(internal::GroupById(x.groups, id, where));
  }
  if ((p.preempt_track_green > Duration{0}) != !p.preempt_track_groups.empty()) {
    where.Fail(
        "preempt_track_green_s and preempt_track_groups come together (a track clearance needs "
        "its groups and its green)");
  }
  for (const SignalGroup& g : x.groups) {
    if (p.preempt_min_green && *p.preempt_min_green < g.timing.min_green) {
      where.Fail(fmt::format(
          "preempt_min_green_s {} is below group {}'s min green {}; rule: the conflict monitor "
          "holds every green to its min green, so a pre-emption may not end one sooner",
          Seconds(*p.preempt_min_green), internal::GroupLabel(g), Seconds(g.timing.min_green)));
    }
  }
  for (const std::size_t t : p.preempt_track_groups) {
    if (p.preempt_track_green < x.groups[t].timing.min_green) {
      where.Fail(fmt::format(
          "preempt_track_green_s {} is below track group {}'s min green {}; rule: the conflict "
          "monitor holds every green to its min green",
          Seconds(p.preempt_track_green), internal::GroupLabel(x.groups[t]),
          Seconds(x.groups[t].timing.min_green)));
    }
  }
  if (p.preempt_track_groups.empty()) return;
  for (const Plan& plan : x.plans) {
    if (plan.phases.empty()) continue;
    const bool driven = std::ranges::any_of(plan.phases, [&](const Phase& phase) {
      return std::ranges::all_of(p.preempt_track_groups, [&](std::size_t t) {
        return std::ranges::find(phase.groups, t) != phase.groups.end();
      });
    });
    if (!driven) {
      where.Fail(fmt::format(
          "no phase of plan {} drives every track group (preempt_track_groups); rule: the track "
          "clearance is one phase of the running plan (NTCIP preemptTrackPhase)",
          plan.name));
    }
  }
}

/// Builds one intersection; `map_x` is the map's intersection of that name.
IntersectionModel BuildIntersection(const CityConfig& city, const IntersectionConfig& cfg,
                                    const maps::Map& map, const maps::Intersection& map_x,
                                    const internal::GroupFloors& floors, IntergreenCache& cache,
                                    const Where& where) {
  IntersectionModel x;
  x.id = map_x.id;
  x.name = map_x.name;
  const double scale = city.time_scale;
  x.startup_flash = Scaled(city.start_up.flash_s, scale);
  x.priority.enabled = cfg.priority.enabled;
  x.priority.max_extension = Scaled(cfg.priority.max_extension_s, scale);
  x.priority.max_preemption = Scaled(cfg.priority.max_preemption_s, scale);
  x.next_phase_decision = cfg.next_phase_decision == "end_of_clearance"
                              ? NextPhaseDecision::kEndOfClearance
                              : NextPhaseDecision::kEndOfGreen;
  x.green_rest = cfg.green_rest == "sumo" ? GreenRest::kSumo : GreenRest::kNtcip;
  const MapSite site{map, map_x};
  internal::Groups groups = internal::BuildGroups(cfg, site, floors, scale, where);
  x.conflicts = internal::BuildConflicts(cfg, site, groups, where);
  internal::AssignHeads(cfg, site, groups, where);
  x.groups = std::move(groups.groups);
  if (city.start_up.all_red_s) {
    x.startup_all_red = Scaled(*city.start_up.all_red_s, scale);
  } else {
    for (const auto& g : x.groups)
      x.startup_all_red = std::max(x.startup_all_red, g.timing.red_clearance);
  }
  for (const auto& g : x.groups) {
    if (x.startup_all_red < g.timing.red_clearance) {
      where.Fail(fmt::format(
          "start_up.all_red_s {} is shorter than group {}'s red clearance {}; "
          "rule: minimum all-red",
          Seconds(x.startup_all_red), internal::GroupLabel(g), Seconds(g.timing.red_clearance)));
    }
    if (g.heads.empty()) {
      where.Fail(fmt::format("group {} is shown by no head; rule: every group is displayed",
                             internal::GroupLabel(g)));
    }
  }
  SetIntergreens(city.safety, map, cache, where, x);
  internal::CheckCrosswalks(cfg, x, site, scale, where);
  x.plans = internal::BuildPlans(cfg, x, site, scale, where);
  x.schedule = internal::BuildSchedule(cfg, x, where);
  SetPreempt(cfg.priority, scale, where.Then("priority"), x);
  return x;
}

}  // namespace

City BuildCity(const CityConfig& config, maps::Map map, const std::string& source) {
  City city;
  city.config = config;
  city.floors_config = config.safety;
  city.floors.min_green = Scaled(config.safety.min_green_s, config.time_scale);
  city.floors.yellow = Scaled(config.safety.min_yellow_s, config.time_scale);
  city.floors.red_clearance = Scaled(config.safety.min_red_clearance_s, config.time_scale);
  const Where root(source);
  {
    // The floors have floors of their own: a city file cannot lower them below what the lab's
    // cars, SPaT's 10 Hz and the lights' conflict monitor need (docs/scm.md, "Safety floors").
    const Where safety = root.Then("safety");
    auto check = [&](const char* key, nanoseconds configured, Duration lab, Duration hard) {
      if (lab < hard) {
        safety.Then(key).Fail(fmt::format(
            "{:.3f} s ({:.3f} lab s at time_scale {}) is below the hard minimum of {:.1f} lab s; "
            "rule: safety floors cannot go below the hard minimums",
            ToSeconds(configured), ToSeconds(lab), config.time_scale, ToSeconds(hard)));
      }
    };
    check("min_yellow_s", config.safety.min_yellow_s, city.floors.yellow, kHardMinimums.yellow);
    check("min_red_clearance_s", config.safety.min_red_clearance_s, city.floors.red_clearance,
          kHardMinimums.red_clearance);
    check("min_green_s", config.safety.min_green_s, city.floors.min_green, kHardMinimums.min_green);
    if (config.safety.clearing_vehicles.empty()) {
      safety.Then("clearing_vehicles")
          .Fail("is empty; name at least the slowest vehicle that crosses the intersections");
    }
  }
  city.device_timeout = config.devices.timeout_s;
  city.device_mismatch = config.devices.mismatch_s;
  city.fleet_staleness = config.fleet.staleness_s;
  IntergreenCache intergreens;  // the map's intersections are mostly alike
  for (std::size_t i = 0; i < config.intersections.size(); ++i) {
    const auto& xc = config.intersections[i];
    const Where where = root.Then(fmt::format("intersections[{}] ({})", i, xc.name));
    const auto it =
        std::ranges::find_if(map.intersections, [&](const auto& x) { return x.name == xc.name; });
    if (it == map.intersections.end()) {
      std::string names;
      for (const auto& x : map.intersections) names += (names.empty() ? "" : ", ") + x.name;
      where.Fail(
          fmt::format("the map {} has no intersection {} (it has: {})", map.name, xc.name, names));
    }
    if (it->control != maps::Control::kSignal) {
      where.Fail(fmt::format("{} is not signalised in the map", xc.name));
    }
    for (std::size_t k = 0; k < i; ++k) {
      if (config.intersections[k].name == xc.name) where.Fail("configured twice");
    }
    city.intersections.push_back(BuildIntersection(
        config, xc, map, *it, internal::GroupFloors{city.floors, config.safety.clearing_vehicles},
        intergreens, where));
  }
  for (const auto& x : map.intersections) {
    if (x.control == maps::Control::kSignal && city.Find(x.id) == nullptr) {
      root.Fail(
          fmt::format("intersection {} is signalised in the map but not configured; rule: "
                      "every signal is controlled",
                      x.name));
    }
  }
  std::ranges::sort(city.intersections, {}, &IntersectionModel::id);
  city.map = std::move(map);
  try {
    city.districts = maps::Districts(city.map, config.districts);
  } catch (const InputError& e) {
    root.Fail(e.what());
  }
  for (const auto& v : config.fleet.vehicles) {
    try {
      (void)ParseVehicleName(v);
    } catch (const InputError& e) {
      root.Then("fleet.vehicles").Fail(e.what());
    }
  }
  // One publisher per `ips` topic: the simulator publishes every car's, so the Eye may not too.
  if (config.sim && config.eye) {
    try {
      const YAML::Node eye = YAML::Load(config.eye->yaml);
      const YAML::Node ips = eye["outputs"] ? eye["outputs"]["ips"] : YAML::Node();
      if (ips && ips.IsScalar() && ips.as<std::string>() == "true") {
        root.Then("eye.outputs.ips")
            .Fail(
                "the simulator (the sim section) publishes every car's ips topic, so the Eye "
                "may not: set eye.outputs.ips to false, or drop the sim section; rule: one "
                "publisher per ips topic");
      }
    } catch (const YAML::Exception&) {
      // The Eye reports its own section's errors.
    }
  }
  return city;
}

City LoadCityString(const std::string& yaml, const std::string& source,
                    const std::filesystem::path& base_dir) {
  return LoadCityString(yaml, source, MapResolution{base_dir, std::nullopt});
}

City LoadCityString(const std::string& yaml, const std::string& source,
                    const MapResolution& resolution) {
  if (const auto nul = yaml.find('\0'); nul != std::string::npos) {
    throw ConfigError(
        fmt::format("{}: the text holds a NUL byte at offset {}; a city file is "
                    "text",
                    source, nul));
  }
  const auto config = config::LoadString<CityConfig>(yaml, source);
  std::filesystem::path map_path = config.map;
  if (map_path.is_relative()) map_path = resolution.base_dir / map_path;
  if (resolution.root) {
    // Nothing from the network names a file outside the SCM's configuration root.
    std::error_code ec;
    auto root = std::filesystem::weakly_canonical(*resolution.root, ec);
    if (root.filename().empty()) root = root.parent_path();
    const auto resolved = std::filesystem::weakly_canonical(map_path, ec);
    const auto [r, m] = std::mismatch(root.begin(), root.end(), resolved.begin(), resolved.end());
    if (ec || r != root.end()) {
      throw ConfigError(
          fmt::format("{}: map: {} is outside the SCM's configuration root {}; "
                      "a configuration sent to the SCM may only name maps under it",
                      source, resolved.string(), root.string()));
    }
  }
  maps::Map map;
  try {
    map = maps::LoadMapOrLayout(map_path.string());
  } catch (const ConfigError&) {
    throw;
  } catch (const InputError& e) {
    throw ConfigError(fmt::format("{}: map: {}", source, e.what()));
  }
  City city = BuildCity(config, std::move(map), source);
  city.config_text = yaml;
  return city;
}

City LoadCity(const std::filesystem::path& path) {
  const std::string text = config::ReadFile(path);
  City city = LoadCityString(text, path.string(), path.parent_path());
  city.config_path = path;
  return city;
}

}  // namespace autodrive::scm
