#include "scm/core/internal/intersection_build.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <set>
#include <sstream>
#include <utility>

#include "common/error.h"
#include "maps/sumo.h"
#include "scm/core/pedestrian_timing.h"

namespace autodrive::scm::internal {

namespace {

constexpr std::string_view kSideNames[] = {"east", "north", "west", "south"};

std::string_view SideName(maps::Side side) { return kSideNames[static_cast<int>(side)]; }

std::optional<maps::Side> SideFromName(std::string_view name) {
  for (int i = 0; i < 4; ++i) {
    if (kSideNames[i] == name) return static_cast<maps::Side>(i);
  }
  return std::nullopt;
}

std::string Seconds(Duration d) { return fmt::format("{:g} s", ToSeconds(d)); }

// --- Groups ---

/// The movements group `gc` controls: those of its approaches, then those it names, sorted.
std::vector<MovementId> GroupMovements(const SignalGroupConfig& gc, const MapSite& site,
                                       const Where& gw) {
  std::vector<MovementId> movements;
  for (const auto& approach : gc.approaches) {
    const auto side = *SideFromName(approach);
    if (!site.HasApproach(side)) {
      gw.Fail(fmt::format("the intersection has no {} approach", approach));
    }
    for (MovementId m : site.x.movements) {
      if (site.SideOf(m) == side) movements.push_back(m);
    }
  }
  for (const auto& name : gc.movements) {
    const auto it = std::ranges::find_if(
        site.x.movements, [&](MovementId m) { return site.map.movement(m).name == name; });
    if (it == site.x.movements.end()) {
      gw.Fail(fmt::format("unknown movement \"{}\" (not a movement of {})", name, site.x.name));
    }
    if (std::ranges::find(movements, *it) == movements.end()) movements.push_back(*it);
  }
  if (movements.empty()) gw.Fail("the group controls no movement");
  std::ranges::sort(movements);
  return movements;
}

/// Conflicting movements inside one group would be green together.
void CheckNoConflictInside(const SignalGroup& g, const maps::Map& map, const Where& gw) {
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
}

/// The group's timing: its own where given, else the intersection's; checked against `floors`.
/// The ITE red clearance of group `g`: the longest (W + L) / V over its movements (W: the
/// movement's path through the box, stop line to exit) and the clearing vehicles, rounded up to
/// 0.1 s; `why` says which movement and vehicle set it.
Duration IteRedClearance(const SignalGroup& g, const MapSite& site,
                         const std::vector<ClearingVehicleConfig>& vehicles, std::string& why) {
  double worst = 0.0;
  for (MovementId m : g.movements) {
    const maps::Movement& mv = site.map.movement(m);
    for (const auto& v : vehicles) {
      const double t = (mv.length_m + v.length_m) / v.speed_mps;
      if (t <= worst) continue;
      worst = t;
      why = fmt::format("({:.3f} m through the box on {} + {} {:.3f} m) / {:.2f} m/s = {:.2f} s",
                        mv.length_m, mv.name, v.name, v.length_m, v.speed_mps, t);
    }
  }
  return FromSeconds(std::ceil(worst * 10.0 - 1e-9) / 10.0);
}

GroupTiming TimingOf(const SignalGroup& g, const GroupTimingConfig& own,
                     const TimingConfig& intersection, const GroupFloors& floors,
                     const MapSite& site, double time_scale, const Where& gw) {
  const auto pick = [&](const std::optional<nanoseconds>& o, nanoseconds d) {
    return Scaled(o.value_or(d), time_scale);
  };
  GroupTiming t;
  t.min_green = pick(own.min_green_s, intersection.min_green_s);
  t.max_green = pick(own.max_green_s, intersection.max_green_s);
  t.yellow = pick(own.yellow_s, intersection.yellow_s);
  std::string why;
  const Duration ite = IteRedClearance(g, site, floors.clearing_vehicles, why);
  const auto& configured = own.red_clearance_s ? own.red_clearance_s : intersection.red_clearance_s;
  t.red_clearance =
      configured ? Scaled(*configured, time_scale) : std::max(ite, floors.timing.red_clearance);
  const std::string label = "group " + GroupLabel(g);
  if (t.red_clearance < ite) {
    gw.Fail(fmt::format(
        "{}: red clearance {} is below the ITE figure {}: a car that enters on the last instant "
        "of yellow is still in the box when a conflicting green starts; give red_clearance_s "
        "at least {} lab s{} (or drop it to use the figure); rule: red clearance (W + L) / V "
        "for safety.clearing_vehicles",
        label, Seconds(t.red_clearance), why, ToSeconds(ite),
        time_scale == 1.0 ? std::string()
                          : fmt::format(", {:.2f} configured s at time_scale {}",
                                        ToSeconds(ite) / time_scale, time_scale)));
  }
  if (t.yellow < floors.timing.yellow) {
    gw.Fail(fmt::format("{}: yellow {} is below the minimum {}; rule: minimum yellow", label,
                        Seconds(t.yellow), Seconds(floors.timing.yellow)));
  }
  if (t.red_clearance < floors.timing.red_clearance) {
    gw.Fail(fmt::format("{}: red clearance {} is below the minimum {}; rule: minimum all-red",
                        label, Seconds(t.red_clearance), Seconds(floors.timing.red_clearance)));
  }
  if (t.min_green < floors.timing.min_green) {
    gw.Fail(fmt::format("{}: min green {} is below the minimum {}; rule: minimum green", label,
                        Seconds(t.min_green), Seconds(floors.timing.min_green)));
  }
  if (t.max_green < t.min_green) {
    gw.Fail(fmt::format("{}: max green {} is below its min green {}", label, Seconds(t.max_green),
                        Seconds(t.min_green)));
  }
  return t;
}

// --- Plans ---

PlanType PlanTypeOf(const std::string& type) {
  return type == "fixed"      ? PlanType::kFixed
         : type == "actuated" ? PlanType::kActuated
         : type == "flash"    ? PlanType::kFlash
                              : PlanType::kDark;
}

/// One phase of a plan of type `type`; marks the groups it serves in `served`.
Phase BuildPhase(const PhaseConfig& phc, PlanType type, const IntersectionModel& x,
                 double time_scale, std::vector<bool>& served, const Where& phw) {
  if (phc.groups.empty()) phw.Fail("a phase needs at least one group");
  Phase phase;
  for (std::uint32_t id : phc.groups) {
    const std::size_t gi = GroupById(x.groups, id, phw);
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
    phw.Fail(fmt::format("its groups' min greens ({}) exceed their max greens ({})", Seconds(lo),
                         Seconds(hi)));
  }
  if (phc.green_s) {
    phase.green = Scaled(*phc.green_s, time_scale);
    if (phase.green < lo) {
      phw.Fail(fmt::format("green {} is below its groups' min green {}; rule: minimum green",
                           Seconds(phase.green), Seconds(lo)));
    }
    if (phase.green > hi) {
      phw.Fail(fmt::format("green {} is above its groups' max green {}", Seconds(phase.green),
                           Seconds(hi)));
    }
  } else if (type == PlanType::kFixed) {
    phw.Fail("a fixed-time phase needs green_s");
  } else {
    phase.green = hi;
  }
  return phase;
}

/// The detectors `dc` places: one zone per ingress lane of its approach.
void AddDetectors(const DetectorConfig& dc, PlanType type, const IntersectionModel& x,
                  const MapSite& site, std::vector<Detector>& out, const Where& dw) {
  if (type != PlanType::kActuated) dw.Fail("only an actuated plan has detectors");
  const std::size_t gi = GroupById(x.groups, dc.group, dw);
  const auto side = *SideFromName(dc.approach);
  const maps::Approach* approach = nullptr;
  for (const auto& a : site.x.approaches) {
    if (a.side == side) approach = &a;
  }
  if (approach == nullptr) dw.Fail(fmt::format("the intersection has no {} approach", dc.approach));
  const bool controls = std::ranges::any_of(x.groups[gi].movements,
                                            [&](MovementId m) { return site.SideOf(m) == side; });
  if (!controls) {
    dw.Fail(fmt::format("group {} controls no movement from the {} approach",
                        GroupLabel(x.groups[gi]), dc.approach));
  }
  for (LaneId lane : approach->ingress) {
    out.push_back({gi, lane, dc.setback_m, dc.setback_m + dc.length_m});
  }
}

// --- Crosswalks ---

/// How movement `m` meets a crosswalk on the leg at `side`: `crosses` when it comes from the leg
/// or goes into it; `hard` when it comes from it or goes straight into it, so cannot cross the
/// crosswalk yielding to its pedestrians as a turn into the leg can.
struct LegCrossing {
  bool crosses = false;
  bool hard = false;
  std::string how;  ///< "comes from", "goes straight into", "turns into"
};

LegCrossing CrossingOf(const MapSite& site, MovementId m, maps::Side side) {
  const maps::Movement& mv = site.map.movement(m);
  if (site.SideOf(m) == side) return {true, true, "comes from"};
  const bool into = std::ranges::any_of(
      site.x.approaches, [&](const auto& a) { return a.id == mv.to_approach && a.side == side; });
  if (!into) return {};
  if (mv.turn == maps::Turn::kStraight) return {true, true, "goes straight into"};
  return {true, false, "turns into"};
}

/// The groups (by index into `x.groups`) crosswalk `c` on the leg at `side` crosses: as listed,
/// else every group with a movement from or into the leg; each listed one must cross it, and
/// every group that cannot cross it permissively must be listed.
std::vector<bool> CrossedGroups(const CrosswalkConfig& c, maps::Side side,
                                const IntersectionModel& x, const MapSite& site, const Where& cw) {
  const std::size_t n = x.groups.size();
  std::vector<bool> crossed(n, false);
  const auto group_crosses = [&](std::size_t gi) {
    return std::ranges::any_of(x.groups[gi].movements,
                               [&](MovementId m) { return CrossingOf(site, m, side).crosses; });
  };
  const bool listed = !c.groups.empty() || !c.movements.empty();
  for (std::size_t gi = 0; gi < n && !listed; ++gi) crossed[gi] = group_crosses(gi);
  for (const std::uint32_t id : c.groups) {
    const std::size_t gi = GroupById(x.groups, id, cw.Then("groups"));
    if (!group_crosses(gi)) {
      cw.Then("groups").Fail(fmt::format(
          "group {} has no movement from or into the {} leg: it does not cross this crosswalk",
          GroupLabel(x.groups[gi]), c.leg));
    }
    crossed[gi] = true;
  }
  for (const auto& name : c.movements) {
    const auto it = std::ranges::find_if(
        site.x.movements, [&](MovementId m) { return site.map.movement(m).name == name; });
    if (it == site.x.movements.end()) {
      cw.Then("movements")
          .Fail(fmt::format("unknown movement \"{}\" (not a movement of {})", name, site.x.name));
    }
    if (!CrossingOf(site, *it, side).crosses) {
      cw.Then("movements")
          .Fail(fmt::format("movement {} neither comes from nor goes into the {} leg: it does "
                            "not cross this crosswalk",
                            name, c.leg));
    }
    crossed[*x.GroupOfMovement(*it)] = true;
  }
  for (std::size_t gi = 0; gi < n; ++gi) {
    if (crossed[gi]) continue;
    for (MovementId m : x.groups[gi].movements) {
      const LegCrossing how = CrossingOf(site, m, side);
      if (!how.hard) continue;
      cw.Fail(fmt::format(
          "group {} is not among the groups it crosses, but its movement {} {} the {} leg; "
          "rule: traffic from a leg or straight into it never runs with the leg's walk (only "
          "turns into the leg may cross its crosswalk, yielding to pedestrians)",
          GroupLabel(x.groups[gi]), site.map.movement(m).name, how.how, c.leg));
    }
  }
  return crossed;
}

/// Checks crosswalk `c` on the leg `approach` of `x`: its length, the groups it crosses, its
/// MUTCD timing at the lab's scale and the buffer of the groups parallel to it.
void CheckCrosswalk(const CrosswalkConfig& c, const maps::Approach& approach, bool low_volume,
                    const IntersectionModel& x, const MapSite& site, double time_scale,
                    const Where& cw) {
  double roadway_m = 0.0;
  for (LaneId lane : approach.ingress) roadway_m += site.map.lane(lane).width_m;
  for (LaneId lane : approach.egress) roadway_m += site.map.lane(lane).width_m;
  if (c.length_m < roadway_m - 1e-6) {
    cw.Fail(fmt::format(
        "length_m {:g} is shorter than the {} leg's traveled way, {:.3f} m over {} lanes; rule: "
        "the MUTCD times the pedestrian clearance to the far side of the traveled way",
        c.length_m, c.leg, roadway_m, approach.ingress.size() + approach.egress.size()));
  }
  const std::vector<bool> crossed = CrossedGroups(c, approach.side, x, site, cw);
  constexpr double scale = maps::kSumoScale;
  const PedestrianCrossing full{
      c.length_m * scale, c.button_setback_m ? *c.button_setback_m * scale : kNoButtonSetbackM};
  const auto violations =
      CheckPedestrianTiming(full, {ToSeconds(c.walk_s), ToSeconds(c.ped_clear_s)}, low_volume);
  if (!violations.empty()) {
    std::string what = fmt::format(
        "the crossing of {:g} lab m is {:.2f} m at 1:{:g}, its {} {:.2f} m ({}); ", c.length_m,
        full.length_m, scale, c.button_setback_m ? "push button" : "start (no push button)",
        full.button_setback_m,
        c.button_setback_m ? fmt::format("{:g} lab m back", *c.button_setback_m)
                           : std::string("the MUTCD's 6 ft back from the kerb"));
    for (std::size_t k = 0; k < violations.size(); ++k) {
      what += (k == 0 ? "" : "; and ") + violations[k].message;
    }
    cw.Fail(what);
  }
  for (std::size_t gi = 0; gi < x.groups.size(); ++gi) {
    if (crossed[gi]) continue;
    const GroupTiming& t = x.groups[gi].timing;
    const double buffer_s = ToSeconds(t.yellow + t.red_clearance) / time_scale;
    if (const auto v = CheckBufferInterval(buffer_s)) {
      cw.Fail(fmt::format(
          "group {} runs parallel to it (it is not among the groups it crosses): its yellow "
          "{:g} s + red clearance {:g} s = {:g} s{}; {}",
          GroupLabel(x.groups[gi]), ToSeconds(t.yellow) / time_scale,
          ToSeconds(t.red_clearance) / time_scale, buffer_s,
          time_scale == 1.0 ? std::string()
                            : fmt::format(" (configured, time_scale {})", time_scale),
          v->message));
    }
  }
}

}  // namespace

Where::Where(std::string source) : text_(std::move(source)) {}

Where Where::Then(const std::string& part) const {
  Where w = *this;
  w.text_ += (w.first_ ? ": " : ".") + part;
  w.first_ = false;
  return w;
}

void Where::Fail(const std::string& what) const { throw ConfigError(text_ + ": " + what); }

maps::Side MapSite::SideOf(MovementId m) const {
  const auto& mv = map.movement(m);
  for (const auto& a : x.approaches) {
    if (a.id == mv.from_approach) return a.side;
  }
  AUTODRIVE_CHECK(false, "movement " << mv.name << " has an unknown approach");
  return maps::Side::kEast;
}

bool MapSite::HasApproach(maps::Side side) const {
  return std::ranges::any_of(x.approaches, [&](const auto& a) { return a.side == side; });
}

std::string GroupLabel(const SignalGroup& g) {
  return fmt::format("{} ({})", g.id.value(), g.name);
}

std::size_t GroupById(const std::vector<SignalGroup>& groups, std::uint32_t id,
                      const Where& where) {
  for (std::size_t i = 0; i < groups.size(); ++i) {
    if (groups[i].id == SignalGroupId(id)) return i;
  }
  where.Fail(fmt::format("unknown signal group {}", id));
}

Groups BuildGroups(const IntersectionConfig& cfg, const MapSite& site, const GroupFloors& floors,
                   double time_scale, const Where& where) {
  if (cfg.groups.empty()) where.Fail("no signal groups");
  Groups out;
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
    g.movements = GroupMovements(gc, site, gw);
    for (MovementId m : g.movements) {
      if (const auto it = out.group_of.find(m); it != out.group_of.end()) {
        gw.Fail(
            fmt::format("movement {} is also in group {}; rule: a movement belongs to one "
                        "signal group",
                        site.map.movement(m).name, GroupLabel(out.groups[it->second])));
      }
      out.group_of[m] = gi;
    }
    CheckNoConflictInside(g, site.map, gw);
    g.timing = TimingOf(g, gc.timing, cfg.timing, floors, site, time_scale, gw);
    g.flash_aspect = gc.flash == "yellow" ? Aspect::kFlashingYellow : Aspect::kFlashingRed;
    out.groups.push_back(std::move(g));
  }
  for (MovementId m : site.x.movements) {
    if (!out.group_of.contains(m)) {
      where.Fail(
          fmt::format("movement {} is in no signal group; rule: every movement of a "
                      "signalised intersection is controlled",
                      site.map.movement(m).name));
    }
  }
  return out;
}

ConflictMatrix BuildConflicts(const IntersectionConfig& cfg, const MapSite& site,
                              const Groups& groups, const Where& where) {
  // Derived from the geometry, extended by hand, never reduced.
  const std::size_t n = groups.groups.size();
  ConflictMatrix conflicts(n, std::vector<bool>(n, false));
  // One pair of conflicting movements per conflicting pair of groups (a < b), for messages.
  std::map<std::pair<std::size_t, std::size_t>, std::pair<MovementId, MovementId>> why;
  for (const auto& [a, b] : site.x.conflicts) {
    const std::size_t ga = groups.group_of.at(a);
    const std::size_t gb = groups.group_of.at(b);
    if (ga == gb) continue;  // refused by BuildGroups
    conflicts[ga][gb] = conflicts[gb][ga] = true;
    why.try_emplace({std::min(ga, gb), std::max(ga, gb)}, a, b);
  }
  auto read_pairs = [&](const std::vector<std::vector<std::uint32_t>>& pairs, const Where& w) {
    ConflictMatrix out(n, std::vector<bool>(n, false));
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      const Where pw = w.Then(fmt::format("[{}]", k));
      if (pairs[k].size() != 2 || pairs[k][0] == pairs[k][1]) {
        pw.Fail("a conflict is a pair of two different group ids, e.g. [1, 2]");
      }
      const std::size_t a = GroupById(groups.groups, pairs[k][0], pw);
      const std::size_t b = GroupById(groups.groups, pairs[k][1], pw);
      out[a][b] = out[b][a] = true;
    }
    return out;
  };
  if (cfg.conflicts) {
    const Where cw = where.Then("conflicts");
    const auto given = read_pairs(*cfg.conflicts, cw);
    for (std::size_t a = 0; a < n; ++a) {
      for (std::size_t b = a + 1; b < n; ++b) {
        if (conflicts[a][b] && !given[a][b]) {
          const auto& [ma, mb] = why.at({a, b});
          cw.Fail(
              fmt::format("groups {} and {} conflict by geometry (movements {} and {} cross "
                          "or merge) but are missing; rule: the conflict matrix may be "
                          "extended, never reduced below the geometry",
                          GroupLabel(groups.groups[a]), GroupLabel(groups.groups[b]),
                          site.map.movement(ma).name, site.map.movement(mb).name));
        }
      }
    }
    conflicts = given;
  }
  const auto extra = read_pairs(cfg.extra_conflicts, where.Then("extra_conflicts"));
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t b = 0; b < n; ++b) {
      if (extra[a][b]) conflicts[a][b] = true;
    }
  }
  return conflicts;
}

void AssignHeads(const IntersectionConfig& cfg, const MapSite& site, Groups& groups,
                 const Where& where) {
  std::map<SignalHeadId, std::size_t> head_group;
  for (std::size_t k = 0; k < cfg.heads.size(); ++k) {
    const Where hw = where.Then(fmt::format("heads[{}]", k));
    const SignalHeadId head(cfg.heads[k].head);
    if (std::ranges::find(site.x.signal_heads, head) == site.x.signal_heads.end()) {
      hw.Fail(fmt::format("signal_{} is not a head of {}", head.value(), site.x.name));
    }
    if (head_group.contains(head)) hw.Fail(fmt::format("signal_{} is listed twice", head.value()));
    head_group[head] = GroupById(groups.groups, cfg.heads[k].group, hw);
  }
  for (SignalHeadId head : site.x.signal_heads) {
    const auto& h = site.map.signal_head(head);
    maps::Side side = maps::Side::kEast;
    for (const auto& a : site.x.approaches) {
      if (a.id == h.approach) side = a.side;
    }
    std::set<std::size_t> groups_of_approach;
    for (MovementId m : site.x.movements) {
      if (site.SideOf(m) == side) groups_of_approach.insert(groups.group_of.at(m));
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
                      head.value(), SideName(side), GroupLabel(groups.groups[head_group[head]])));
    }
  }
  for (const auto& [head, gi] : head_group) groups.groups[gi].heads.push_back(head);
}

Plan BuildPlan(const PlanConfig& pc, const IntersectionModel& x, const MapSite& site,
               double time_scale, const Where& pw) {
  Plan plan;
  plan.name = pc.name;
  plan.type = PlanTypeOf(pc.type);
  plan.offset = Scaled(pc.offset_s, time_scale);
  plan.extension = Scaled(pc.extension_s, time_scale);
  const bool phased = plan.type == PlanType::kFixed || plan.type == PlanType::kActuated;
  if (!phased) {
    if (!pc.phases.empty() || !pc.detectors.empty()) {
      pw.Fail(fmt::format("a {} plan has no phases or detectors", pc.type));
    }
    return plan;
  }
  if (pc.phases.empty()) pw.Fail(fmt::format("a {} plan needs phases", pc.type));
  const std::size_t n = x.groups.size();
  std::vector<bool> served(n, false);
  for (std::size_t k = 0; k < pc.phases.size(); ++k) {
    plan.phases.push_back(BuildPhase(pc.phases[k], plan.type, x, time_scale, served,
                                     pw.Then(fmt::format("phases[{}]", k))));
  }
  for (std::size_t gi = 0; gi < n; ++gi) {
    if (!served[gi]) {
      pw.Fail(fmt::format("group {} is never green in this plan; rule: every group is served",
                          GroupLabel(x.groups[gi])));
    }
  }
  SetPlanCycle(x.groups, plan);
  if (plan.cycle <= Duration{0}) pw.Fail("the cycle is empty");
  plan.offset = plan.offset % plan.cycle;
  for (std::size_t k = 0; k < pc.detectors.size(); ++k) {
    AddDetectors(pc.detectors[k], plan.type, x, site, plan.detectors,
                 pw.Then(fmt::format("detectors[{}]", k)));
  }
  return plan;
}

std::vector<Plan> BuildPlans(const IntersectionConfig& cfg, const IntersectionModel& x,
                             const MapSite& site, double time_scale, const Where& where) {
  if (cfg.plans.empty()) where.Fail("no plans");
  std::vector<Plan> plans;
  for (std::size_t pi = 0; pi < cfg.plans.size(); ++pi) {
    const auto& pc = cfg.plans[pi];
    const Where pw = where.Then(fmt::format("plans[{}] ({})", pi, pc.name));
    for (std::size_t k = 0; k < pi; ++k) {
      if (cfg.plans[k].name == pc.name) pw.Fail(fmt::format("plan name {} is used twice", pc.name));
    }
    if (pc.name.empty() || pc.name == "auto") {
      pw.Fail("a plan needs a name other than \"\" and \"auto\"");
    }
    plans.push_back(BuildPlan(pc, x, site, time_scale, pw));
  }
  return plans;
}

void CheckCrosswalks(const IntersectionConfig& cfg, const IntersectionModel& x, const MapSite& site,
                     double time_scale, const Where& where) {
  for (std::size_t k = 0; k < cfg.crosswalks.size(); ++k) {
    const CrosswalkConfig& c = cfg.crosswalks[k];
    const Where cw = where.Then(fmt::format("crosswalks[{}] ({} leg)", k, c.leg));
    for (std::size_t j = 0; j < k; ++j) {
      if (cfg.crosswalks[j].leg == c.leg) {
        cw.Fail(fmt::format("crosswalks[{}] is on the {} leg too; rule: one crosswalk per leg", j,
                            c.leg));
      }
    }
    const auto side = *SideFromName(c.leg);
    const auto approach = std::ranges::find(site.x.approaches, side, &maps::Approach::side);
    if (approach == site.x.approaches.end()) {
      cw.Fail(fmt::format("the intersection has no {} leg", c.leg));
    }
    CheckCrosswalk(c, *approach, cfg.low_pedestrian_volume, x, site, time_scale, cw);
  }
}

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

std::vector<ScheduleEntry> BuildSchedule(const IntersectionConfig& cfg, const IntersectionModel& x,
                                         const Where& where) {
  std::vector<ScheduleEntry> schedule;
  for (std::size_t k = 0; k < cfg.schedule.size(); ++k) {
    const Where sw = where.Then(fmt::format("schedule[{}]", k));
    const auto& sc = cfg.schedule[k];
    const auto plan = x.PlanIndex(sc.plan);
    if (!plan) sw.Fail(fmt::format("unknown plan \"{}\"", sc.plan));
    const int minute = ParseMinuteOfDay(sc.at, sw);
    for (const auto& e : schedule) {
      if (e.minute_of_day == minute) sw.Fail(fmt::format("{} is scheduled twice", sc.at));
    }
    schedule.push_back({minute, *plan});
  }
  if (schedule.empty()) schedule.push_back({0, 0});
  std::ranges::sort(schedule, {}, &ScheduleEntry::minute_of_day);
  return schedule;
}

}  // namespace autodrive::scm::internal
