#include "scm/core/city.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <utility>

#include "common/error.h"
#include "maps/map_io.h"

namespace autodrive::scm {

void TimingConfig::Validate() const {
  if (min_green_s > max_green_s) {
    throw InputError(fmt::format("min_green_s {} is above max_green_s {}", ToSeconds(min_green_s),
                                 ToSeconds(max_green_s)));
  }
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

Duration Scaled(nanoseconds configured, double time_scale) {
  return FromSeconds(ToSeconds(configured) * time_scale);
}

namespace {

constexpr std::string_view kSideNames[] = {"east", "north", "west", "south"};

std::string_view SideName(maps::Side side) { return kSideNames[static_cast<int>(side)]; }

std::optional<maps::Side> SideFromName(std::string_view name) {
  for (int i = 0; i < 4; ++i) {
    if (kSideNames[i] == name) return static_cast<maps::Side>(i);
  }
  return std::nullopt;
}

/// Collects the context of an error message: "SOURCE: intersections[1] (centre): ...".
class Where {
 public:
  explicit Where(std::string source) : text_(std::move(source)) {}
  Where Then(const std::string& part) const {
    Where w = *this;
    w.text_ += (w.first_ ? ": " : ".") + part;
    w.first_ = false;
    return w;
  }
  [[noreturn]] void Fail(const std::string& what) const { throw ConfigError(text_ + ": " + what); }

 private:
  std::string text_;
  bool first_ = true;
};

std::string GroupLabel(const SignalGroup& g) {
  return fmt::format("{} ({})", g.id.value(), g.name);
}

std::string Seconds(Duration d) { return fmt::format("{:g} s", ToSeconds(d)); }

int ParseMinuteOfDay(const std::string& text, const Where& where) {
  int h = -1;
  int m = -1;
  char colon = 0;
  std::istringstream in(text);
  in >> h >> colon >> m;
  if (!in || colon != ':' || !in.eof() || h < 0 || h > 23 || m < 0 || m > 59 || text.size() != 5) {
    where.Fail(fmt::format("bad time of day \"{}\" (expected HH:MM, 00:00 to 23:59)", text));
  }
  return h * 60 + m;
}

/// Builds one intersection; `map_x` is the map's intersection of that name.
IntersectionModel BuildIntersection(const CityConfig& city, const IntersectionConfig& cfg,
                                    const maps::Map& map, const maps::Intersection& map_x,
                                    const GroupTiming& floors, const Where& where) {
  IntersectionModel x;
  x.id = map_x.id;
  x.name = map_x.name;
  const double scale = city.time_scale;
  x.startup_flash = Scaled(city.start_up.flash_s, scale);
  x.startup_all_red = Scaled(city.start_up.all_red_s, scale);
  x.priority = {cfg.priority.enabled, Scaled(cfg.priority.max_extension_s, scale),
                Scaled(cfg.priority.max_preemption_s, scale)};

  auto approach_side = [&](MovementId m) {
    const auto& mv = map.movement(m);
    for (const auto& a : map_x.approaches) {
      if (a.id == mv.from_approach) return a.side;
    }
    AUTODRIVE_CHECK(false, "movement " << mv.name << " has an unknown approach");
    return maps::Side::kEast;
  };
  auto has_approach = [&](maps::Side side) {
    return std::ranges::any_of(map_x.approaches, [&](const auto& a) { return a.side == side; });
  };

  // --- Groups ---
  if (cfg.groups.empty()) where.Fail("no signal groups");
  std::map<MovementId, std::size_t> group_of;
  for (std::size_t gi = 0; gi < cfg.groups.size(); ++gi) {
    const auto& gc = cfg.groups[gi];
    const Where gw = where.Then(fmt::format("groups[{}] ({})", gi, gc.name));
    SignalGroup g;
    g.id = SignalGroupId(gc.id);
    g.name = gc.name;
    for (std::size_t k = 0; k < gi; ++k) {
      if (cfg.groups[k].id == gc.id) gw.Fail(fmt::format("group id {} is used twice", gc.id));
      if (cfg.groups[k].name == gc.name)
        gw.Fail(fmt::format("group name {} is used twice", gc.name));
    }
    for (const auto& approach : gc.approaches) {
      const auto side = *SideFromName(approach);
      if (!has_approach(side)) {
        gw.Fail(fmt::format("the intersection has no {} approach", approach));
      }
      for (MovementId m : map_x.movements) {
        if (approach_side(m) == side) g.movements.push_back(m);
      }
    }
    for (const auto& name : gc.movements) {
      const auto it = std::ranges::find_if(
          map_x.movements, [&](MovementId m) { return map.movement(m).name == name; });
      if (it == map_x.movements.end()) {
        gw.Fail(fmt::format("unknown movement \"{}\" (not a movement of {})", name, x.name));
      }
      if (std::ranges::find(g.movements, *it) == g.movements.end()) g.movements.push_back(*it);
    }
    if (g.movements.empty()) gw.Fail("the group controls no movement");
    std::ranges::sort(g.movements);
    for (MovementId m : g.movements) {
      if (const auto it = group_of.find(m); it != group_of.end()) {
        gw.Fail(
            fmt::format("movement {} is also in group {}; rule: a movement belongs to one "
                        "signal group",
                        map.movement(m).name, GroupLabel(x.groups[it->second])));
      }
      group_of[m] = gi;
    }
    // Conflicting movements inside one group would be green together.
    for (std::size_t i = 0; i < g.movements.size(); ++i) {
      for (std::size_t j = i + 1; j < g.movements.size(); ++j) {
        if (map.Conflict(g.movements[i], g.movements[j])) {
          gw.Fail(
              fmt::format("movements {} and {} conflict but are in one group; rule: "
                          "conflicting movements are never green together",
                          map.movement(g.movements[i]).name, map.movement(g.movements[j]).name));
        }
      }
    }
    // Timing.
    const auto pick = [&](const std::optional<nanoseconds>& o, nanoseconds d) {
      return Scaled(o.value_or(d), scale);
    };
    g.timing.min_green = pick(gc.timing.min_green_s, cfg.timing.min_green_s);
    g.timing.max_green = pick(gc.timing.max_green_s, cfg.timing.max_green_s);
    g.timing.yellow = pick(gc.timing.yellow_s, cfg.timing.yellow_s);
    g.timing.red_clearance = pick(gc.timing.red_clearance_s, cfg.timing.red_clearance_s);
    const std::string label = "group " + GroupLabel(g);
    if (g.timing.yellow < floors.yellow) {
      gw.Fail(fmt::format("{}: yellow {} is below the minimum {}; rule: minimum yellow", label,
                          Seconds(g.timing.yellow), Seconds(floors.yellow)));
    }
    if (g.timing.red_clearance < floors.red_clearance) {
      gw.Fail(fmt::format("{}: red clearance {} is below the minimum {}; rule: minimum all-red",
                          label, Seconds(g.timing.red_clearance), Seconds(floors.red_clearance)));
    }
    if (g.timing.min_green < floors.min_green) {
      gw.Fail(fmt::format("{}: min green {} is below the minimum {}; rule: minimum green", label,
                          Seconds(g.timing.min_green), Seconds(floors.min_green)));
    }
    if (g.timing.max_green < g.timing.min_green) {
      gw.Fail(fmt::format("{}: max green {} is below its min green {}", label,
                          Seconds(g.timing.max_green), Seconds(g.timing.min_green)));
    }
    g.flash_aspect = gc.flash == "yellow" ? Aspect::kFlashingYellow : Aspect::kFlashingRed;
    x.groups.push_back(std::move(g));
  }
  for (MovementId m : map_x.movements) {
    if (!group_of.contains(m)) {
      where.Fail(
          fmt::format("movement {} is in no signal group; rule: every movement of a "
                      "signalised intersection is controlled",
                      map.movement(m).name));
    }
  }
  const std::size_t n = x.groups.size();
  auto group_by_id = [&](std::uint32_t id, const Where& w) {
    const auto gi = x.GroupIndex(SignalGroupId(id));
    if (!gi) w.Fail(fmt::format("unknown signal group {}", id));
    return *gi;
  };

  // --- Conflicts: derived from the geometry, extended by hand, never reduced ---
  x.conflicts.assign(n, std::vector<bool>(n, false));
  // One pair of conflicting movements per conflicting pair of groups (a < b), for messages.
  std::map<std::pair<std::size_t, std::size_t>, std::pair<MovementId, MovementId>> why;
  for (const auto& [a, b] : map_x.conflicts) {
    const std::size_t ga = group_of.at(a);
    const std::size_t gb = group_of.at(b);
    if (ga == gb) continue;  // refused above
    x.conflicts[ga][gb] = x.conflicts[gb][ga] = true;
    why.try_emplace({std::min(ga, gb), std::max(ga, gb)}, a, b);
  }
  auto read_pairs = [&](const std::vector<std::vector<std::uint32_t>>& pairs, const Where& w) {
    std::vector<std::vector<bool>> out(n, std::vector<bool>(n, false));
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      const Where pw = w.Then(fmt::format("[{}]", k));
      if (pairs[k].size() != 2 || pairs[k][0] == pairs[k][1]) {
        pw.Fail("a conflict is a pair of two different group ids, e.g. [1, 2]");
      }
      const std::size_t a = group_by_id(pairs[k][0], pw);
      const std::size_t b = group_by_id(pairs[k][1], pw);
      out[a][b] = out[b][a] = true;
    }
    return out;
  };
  if (cfg.conflicts) {
    const Where cw = where.Then("conflicts");
    const auto given = read_pairs(*cfg.conflicts, cw);
    for (std::size_t a = 0; a < n; ++a) {
      for (std::size_t b = a + 1; b < n; ++b) {
        if (x.conflicts[a][b] && !given[a][b]) {
          const auto& [ma, mb] = why.at({a, b});
          cw.Fail(
              fmt::format("groups {} and {} conflict by geometry (movements {} and {} cross "
                          "or merge) but are missing; rule: the conflict matrix may be "
                          "extended, never reduced below the geometry",
                          GroupLabel(x.groups[a]), GroupLabel(x.groups[b]), map.movement(ma).name,
                          map.movement(mb).name));
        }
      }
    }
    x.conflicts = given;
  }
  {
    const auto extra = read_pairs(cfg.extra_conflicts, where.Then("extra_conflicts"));
    for (std::size_t a = 0; a < n; ++a) {
      for (std::size_t b = 0; b < n; ++b) {
        if (extra[a][b]) x.conflicts[a][b] = true;
      }
    }
  }

  // --- Heads ---
  std::map<SignalHeadId, std::size_t> head_group;
  for (std::size_t k = 0; k < cfg.heads.size(); ++k) {
    const Where hw = where.Then(fmt::format("heads[{}]", k));
    const SignalHeadId head(cfg.heads[k].head);
    if (std::ranges::find(map_x.signal_heads, head) == map_x.signal_heads.end()) {
      hw.Fail(fmt::format("signal_{} is not a head of {}", head.value(), x.name));
    }
    if (head_group.contains(head)) hw.Fail(fmt::format("signal_{} is listed twice", head.value()));
    head_group[head] = group_by_id(cfg.heads[k].group, hw);
  }
  for (SignalHeadId head : map_x.signal_heads) {
    const auto& h = map.signal_heads.at(head.value() - 1);
    maps::Side side = maps::Side::kEast;
    for (const auto& a : map_x.approaches) {
      if (a.id == h.approach) side = a.side;
    }
    std::set<std::size_t> groups_of_approach;
    for (MovementId m : map_x.movements) {
      if (approach_side(m) == side) groups_of_approach.insert(group_of.at(m));
    }
    if (!head_group.contains(head)) {
      if (groups_of_approach.size() != 1) {
        where.Fail(
            fmt::format("signal_{} faces the {} approach, whose movements are in {} "
                        "groups; say which group it shows under heads",
                        head.value(), SideName(side), groups_of_approach.size()));
      }
      head_group[head] = *groups_of_approach.begin();
    } else if (!groups_of_approach.contains(head_group[head])) {
      where.Fail(
          fmt::format("signal_{} faces the {} approach but shows group {}, which controls "
                      "no movement from there; rule: a head shows its own approach",
                      head.value(), SideName(side), GroupLabel(x.groups[head_group[head]])));
    }
  }
  for (const auto& [head, gi] : head_group) x.groups[gi].heads.push_back(head);
  for (const auto& g : x.groups) {
    if (x.startup_all_red < g.timing.red_clearance) {
      where.Fail(
          fmt::format("start_up.all_red_s {} is shorter than group {}'s red clearance {}; "
                      "rule: minimum all-red",
                      Seconds(x.startup_all_red), GroupLabel(g), Seconds(g.timing.red_clearance)));
    }
    if (g.heads.empty()) {
      where.Fail(fmt::format("group {} is shown by no head; rule: every group is displayed",
                             GroupLabel(g)));
    }
  }

  // --- Plans ---
  if (cfg.plans.empty()) where.Fail("no plans");
  for (std::size_t pi = 0; pi < cfg.plans.size(); ++pi) {
    const auto& pc = cfg.plans[pi];
    const Where pw = where.Then(fmt::format("plans[{}] ({})", pi, pc.name));
    for (std::size_t k = 0; k < pi; ++k) {
      if (cfg.plans[k].name == pc.name) pw.Fail(fmt::format("plan name {} is used twice", pc.name));
    }
    if (pc.name.empty() || pc.name == "auto") {
      pw.Fail("a plan needs a name other than \"\" and \"auto\"");
    }
    Plan plan;
    plan.name = pc.name;
    plan.type = pc.type == "fixed"      ? PlanType::kFixed
                : pc.type == "actuated" ? PlanType::kActuated
                : pc.type == "flash"    ? PlanType::kFlash
                                        : PlanType::kDark;
    plan.offset = Scaled(pc.offset_s, scale);
    plan.extension = Scaled(pc.extension_s, scale);
    const bool phased = plan.type == PlanType::kFixed || plan.type == PlanType::kActuated;
    if (!phased) {
      if (!pc.phases.empty() || !pc.detectors.empty()) {
        pw.Fail(fmt::format("a {} plan has no phases or detectors", pc.type));
      }
      x.plans.push_back(std::move(plan));
      continue;
    }
    if (pc.phases.empty()) pw.Fail(fmt::format("a {} plan needs phases", pc.type));
    std::vector<bool> served(n, false);
    for (std::size_t k = 0; k < pc.phases.size(); ++k) {
      const Where phw = pw.Then(fmt::format("phases[{}]", k));
      const auto& phc = pc.phases[k];
      if (phc.groups.empty()) phw.Fail("a phase needs at least one group");
      Phase phase;
      for (std::uint32_t id : phc.groups) {
        const std::size_t gi = group_by_id(id, phw);
        if (std::ranges::find(phase.groups, gi) != phase.groups.end()) {
          phw.Fail(fmt::format("group {} is listed twice", id));
        }
        for (std::size_t other : phase.groups) {
          if (x.conflicts[gi][other]) {
            phw.Fail(
                fmt::format("groups {} and {} conflict; rule: conflicting groups are never "
                            "green or yellow together",
                            GroupLabel(x.groups[other]), GroupLabel(x.groups[gi])));
          }
        }
        phase.groups.push_back(gi);
        served[gi] = true;
      }
      Duration lo{0};
      Duration hi = Duration::max();
      for (std::size_t gi : phase.groups) {
        lo = std::max(lo, x.groups[gi].timing.min_green);
        hi = std::min(hi, x.groups[gi].timing.max_green);
      }
      if (lo > hi) {
        phw.Fail(fmt::format("its groups' min greens ({}) exceed their max greens ({})",
                             Seconds(lo), Seconds(hi)));
      }
      if (phc.green_s) {
        phase.green = Scaled(*phc.green_s, scale);
        if (phase.green < lo) {
          phw.Fail(fmt::format("green {} is below its groups' min green {}; rule: minimum green",
                               Seconds(phase.green), Seconds(lo)));
        }
        if (phase.green > hi) {
          phw.Fail(fmt::format("green {} is above its groups' max green {}", Seconds(phase.green),
                               Seconds(hi)));
        }
      } else if (plan.type == PlanType::kFixed) {
        phw.Fail("a fixed-time phase needs green_s");
      } else {
        phase.green = hi;
      }
      plan.phases.push_back(std::move(phase));
    }
    for (std::size_t gi = 0; gi < n; ++gi) {
      if (!served[gi]) {
        pw.Fail(fmt::format("group {} is never green in this plan; rule: every group is served",
                            GroupLabel(x.groups[gi])));
      }
    }
    // Cycle: greens plus the clearance of the groups each phase change ends.
    Duration t{0};
    for (std::size_t k = 0; k < plan.phases.size(); ++k) {
      plan.phase_starts.push_back(t);
      const auto& now_groups = plan.phases[k].groups;
      const auto& next_groups = plan.phases[(k + 1) % plan.phases.size()].groups;
      Duration yellow{0};
      Duration red{0};
      for (std::size_t gi : now_groups) {
        if (std::ranges::find(next_groups, gi) == next_groups.end()) {
          yellow = std::max(yellow, x.groups[gi].timing.yellow);
          red = std::max(red, x.groups[gi].timing.red_clearance);
        }
      }
      t += plan.phases[k].green + yellow + red;
    }
    plan.cycle = t;
    if (plan.cycle <= Duration{0}) pw.Fail("the cycle is empty");
    plan.offset = plan.offset % plan.cycle;
    // Detectors.
    for (std::size_t k = 0; k < pc.detectors.size(); ++k) {
      const Where dw = pw.Then(fmt::format("detectors[{}]", k));
      const auto& dc = pc.detectors[k];
      if (plan.type != PlanType::kActuated) dw.Fail("only an actuated plan has detectors");
      const std::size_t gi = group_by_id(dc.group, dw);
      const auto side = *SideFromName(dc.approach);
      const maps::Approach* approach = nullptr;
      for (const auto& a : map_x.approaches) {
        if (a.side == side) approach = &a;
      }
      if (approach == nullptr)
        dw.Fail(fmt::format("the intersection has no {} approach", dc.approach));
      const bool controls = std::ranges::any_of(
          x.groups[gi].movements, [&](MovementId m) { return approach_side(m) == side; });
      if (!controls) {
        dw.Fail(fmt::format("group {} controls no movement from the {} approach",
                            GroupLabel(x.groups[gi]), dc.approach));
      }
      for (LaneId lane : approach->ingress) {
        plan.detectors.push_back({gi, lane, dc.setback_m, dc.setback_m + dc.length_m});
      }
    }
    x.plans.push_back(std::move(plan));
  }

  // --- Schedule ---
  for (std::size_t k = 0; k < cfg.schedule.size(); ++k) {
    const Where sw = where.Then(fmt::format("schedule[{}]", k));
    const auto& sc = cfg.schedule[k];
    const auto plan = x.PlanIndex(sc.plan);
    if (!plan) sw.Fail(fmt::format("unknown plan \"{}\"", sc.plan));
    const int minute = ParseMinuteOfDay(sc.at, sw);
    for (const auto& e : x.schedule) {
      if (e.minute_of_day == minute) sw.Fail(fmt::format("{} is scheduled twice", sc.at));
    }
    x.schedule.push_back({minute, *plan});
  }
  if (x.schedule.empty()) x.schedule.push_back({0, 0});
  std::ranges::sort(x.schedule, {}, &ScheduleEntry::minute_of_day);
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
  }
  city.device_timeout = config.devices.timeout_s;
  city.device_mismatch = config.devices.mismatch_s;
  city.fleet_staleness = config.fleet.staleness_s;
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
    city.intersections.push_back(BuildIntersection(config, xc, map, *it, city.floors, where));
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
  city.map = std::move(map);
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
