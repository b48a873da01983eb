#include "traffic/nema/collision_oracle.h"

#include <fmt/format.h>

#include <algorithm>
#include <ctime>
#include <map>
#include <memory>
#include <utility>

#include <nlohmann/json.hpp>
#include <pugixml.hpp>

#include "traffic/cosim.h"
#include "traffic/nema/internal/head_lamp.h"
#include "traffic/nema/internal/io.h"
#include "traffic/nema/nema_program.h"
#include "traffic/nema/oracle_traffic.h"

#include "common/aspect.h"
#include "common/error.h"
#include "maps/sumo.h"
#include "scm/core/runtime.h"

namespace autodrive::traffic::nema {

namespace {

namespace fs = std::filesystem;
using internal::HeadLamp;
using internal::WriteFile;
// What a head shows (common/aspect.h; traffic::Aspect is what a driver reads of it).
using HeadAspect = ::autodrive::Aspect;

constexpr Duration kDay = std::chrono::hours(24);

std::string GroupLabel(const scm::IntersectionModel& x, std::size_t g) {
  return fmt::format("group {} ({})", x.groups[g].id.value(), x.groups[g].name);
}

Duration FloorToStep(Duration d, Duration step) { return d - d % step; }

// A fixed-time plan's phase starts and cycle from its groups' clearances, as the city loader
// sets them, with its offset kept within the new cycle.
void SetCycle(const std::vector<scm::SignalGroup>& groups, scm::Plan& plan) {
  scm::SetPlanCycle(groups, plan);
  if (plan.cycle > Duration{0}) plan.offset = plan.offset % plan.cycle;
}

// Each group's greens as the controllers showed them, and the least intergreen seen between
// conflicting groups.
class GreenHistory {
 public:
  explicit GreenHistory(const scm::CityRuntime& runtime) : runtime_(&runtime) {
    for (const scm::IntersectionRuntime& x : runtime.intersections()) {
      const std::size_t n = x.model->groups.size();
      greens_.emplace_back(n);
      least_.emplace_back(n, std::vector<std::pair<Duration, int>>(n, {Duration::max(), 0}));
    }
  }

  void Sample(Duration t) {
    const auto& xs = runtime_->intersections();
    for (std::size_t i = 0; i < xs.size(); ++i) {
      const scm::IntersectionModel& m = *xs[i].model;
      for (std::size_t g = 0; g < m.groups.size(); ++g) {
        const bool green = xs[i].last_aspects[g] == HeadAspect::kGreen;
        auto& list = greens_[i][g];
        const bool open = !list.empty() && !list.back().second;
        if (green && !open) {
          list.emplace_back(t, std::nullopt);
          for (std::size_t a = 0; a < m.groups.size(); ++a) {
            if (!m.conflicts[a][g] || greens_[i][a].empty() || !greens_[i][a].back().second) {
              continue;
            }
            auto& [least, n] = least_[i][a][g];
            least = std::min(least, t - *greens_[i][a].back().second);
            ++n;
          }
        } else if (!green && open) {
          list.back().second = t;
        }
      }
    }
  }

  // What group `g` of intersection `i` showed at `t`, in words.
  [[nodiscard]] std::string Describe(std::size_t i, std::size_t g, Duration t) const {
    const scm::IntersectionModel& m = *runtime_->intersections()[i].model;
    const auto& list = greens_[i][g];
    auto it = std::ranges::upper_bound(list, t, {}, [](const auto& p) { return p.first; });
    if (it == list.begin()) return GroupLabel(m, g) + " not green yet";
    --it;
    if (!it->second || *it->second > t) {
      return fmt::format("{} green since {:.1f} s ({:.1f} s before)", GroupLabel(m, g),
                         ToSeconds(it->first), ToSeconds(t - it->first));
    }
    return fmt::format("{} green ended at {:.1f} s ({:.1f} s before)", GroupLabel(m, g),
                       ToSeconds(*it->second), ToSeconds(t - *it->second));
  }

  [[nodiscard]] std::vector<ObservedIntergreen> Observed() const {
    std::vector<ObservedIntergreen> out;
    const auto& xs = runtime_->intersections();
    for (std::size_t i = 0; i < xs.size(); ++i) {
      const scm::IntersectionModel& m = *xs[i].model;
      for (std::size_t a = 0; a < m.groups.size(); ++a) {
        for (std::size_t b = 0; b < m.groups.size(); ++b) {
          const auto& [least, n] = least_[i][a][b];
          if (n == 0) continue;
          out.push_back({m.name, GroupLabel(m, a), GroupLabel(m, b), ToSeconds(m.intergreens[a][b]),
                         ToSeconds(least), n});
        }
      }
    }
    return out;
  }

 private:
  const scm::CityRuntime* runtime_;
  // By intersection and group: (green start, green end).
  std::vector<std::vector<std::vector<std::pair<Duration, std::optional<Duration>>>>> greens_;
  // By intersection, clearing and entering group: the least intergreen seen and how often.
  std::vector<std::vector<std::vector<std::pair<Duration, int>>>> least_;
};

}  // namespace

// Every scheduled plan during the run must be fixed time (no detector calls reach the
// controllers here, and flash or dark test nothing).
std::vector<std::string> CheckCollisionOracleOptions(const scm::City& city,
                                                     const CollisionOracleOptions& o) {
  AUTODRIVE_THROW_UNLESS(o.step > Duration{0}, "the step must be > 0");
  AUTODRIVE_THROW_UNLESS(o.duration > Duration{0} && o.duration % o.step == Duration{0},
                         "--duration " << ToSeconds(o.duration)
                                       << " s is not a positive whole number of steps of "
                                       << ToSeconds(o.step) << " s");
  AUTODRIVE_THROW_UNLESS(o.time_of_day >= Duration{0} && o.time_of_day + o.duration <= kDay,
                         "the run (from " << internal::HoursMinutes(o.time_of_day) << " for "
                                          << ToSeconds(o.duration) << " s) must end by midnight");
  AUTODRIVE_THROW_UNLESS(!o.out_dir.empty(), "no output folder");
  if (o.intersection && city.Find(*o.intersection) == nullptr) {
    std::string names;
    for (const scm::IntersectionModel& x : city.intersections) {
      names += (names.empty() ? "" : ", ") + x.name;
    }
    throw InputError(fmt::format("city {} has no signalised intersection \"{}\" (it has: {})",
                                 city.config.name, *o.intersection, names));
  }
  std::vector<std::string> plans;
  for (const scm::IntersectionModel& x : city.intersections) {
    std::string names;
    for (Duration t = o.time_of_day; t <= o.time_of_day + o.duration;
         t += std::chrono::minutes(1)) {
      const int minute = scm::DayClock::At(t).minute_of_day;
      const scm::Plan& p = x.plans[x.ScheduledPlan(minute)];
      AUTODRIVE_THROW_UNLESS(p.type == scm::PlanType::kFixed,
                             "intersection " << x.name << " runs plan " << p.name << " ("
                                             << scm::ToString(p.type) << ") at minute " << minute
                                             << " of the day: the oracle runs fixed-time plans "
                                                "only (choose another --time-of-day)");
      if (names.find(p.name) == std::string::npos) names += (names.empty() ? "" : ", ") + p.name;
    }
    plans.push_back(x.name + ": " + names);
  }
  return plans;
}

namespace {

// SUMO's collision output, one record per collision (a pair's records at consecutive steps are
// one).
std::vector<OracleCollision> ReadCollisions(const fs::path& file, Duration step) {
  pugi::xml_document doc;
  const pugi::xml_parse_result r = doc.load_file(file.c_str());
  AUTODRIVE_THROW_UNLESS(r, file.string()
                                << ": cannot read SUMO's collision output: " << r.description());
  std::vector<OracleCollision> out;
  std::map<std::pair<std::string, std::string>, double> last;  // pair: its last record
  const double gap = ToSeconds(step) * 1.5;
  for (pugi::xml_node n : doc.child("collisions").children("collision")) {
    OracleCollision c;
    c.time_s = n.attribute("time").as_double();
    c.type = n.attribute("type").as_string();
    c.lane = n.attribute("lane").as_string();
    c.collider = n.attribute("collider").as_string();
    c.victim = n.attribute("victim").as_string();
    c.collider_type = n.attribute("colliderType").as_string();
    c.victim_type = n.attribute("victimType").as_string();
    c.collider_speed_mps = n.attribute("colliderSpeed").as_double();
    c.victim_speed_mps = n.attribute("victimSpeed").as_double();
    const auto pair = std::minmax(c.collider, c.victim);
    const auto [it, fresh] = last.try_emplace({pair.first, pair.second}, c.time_s);
    const bool repeat = !fresh && c.time_s - it->second <= gap;
    it->second = c.time_s;
    if (repeat) continue;
    c.in_junction = !c.lane.empty() && c.lane.front() == ':';
    if (c.in_junction) {
      // ":<junction>_<link>_<lane>"
      const std::size_t b = c.lane.rfind('_');
      const std::size_t a = b == std::string::npos ? b : c.lane.rfind('_', b - 1);
      c.junction = a == std::string::npos ? c.lane.substr(1) : c.lane.substr(1, a - 1);
    }
    out.push_back(std::move(c));
  }
  return out;
}

// SUMO's statistics output: vehicles and safety.
void ReadStatistics(const fs::path& file, CollisionOracleResult& r) {
  pugi::xml_document doc;
  const pugi::xml_parse_result result = doc.load_file(file.c_str());
  AUTODRIVE_THROW_UNLESS(
      result, file.string() << ": cannot read SUMO's statistics output: " << result.description());
  const pugi::xml_node s = doc.child("statistics");
  r.vehicles_loaded = s.child("vehicles").attribute("loaded").as_llong();
  r.vehicles_waiting = s.child("vehicles").attribute("waiting").as_llong();
  r.sumo_collisions = s.child("safety").attribute("collisions").as_llong();
  r.emergency_stops = s.child("safety").attribute("emergencyStops").as_llong();
}

// Names the movements of the two vehicles and what their groups showed.
void Explain(const OracleTraffic& traffic, const scm::CityRuntime& runtime,
             const GreenHistory& greens, OracleCollision& c) {
  const Duration t = FromSeconds(c.time_s);
  std::string signals;
  for (const auto& [vehicle, movement] :
       {std::pair{&c.collider, &c.collider_movement}, std::pair{&c.victim, &c.victim_movement}}) {
    const OracleFlow* f = traffic.FlowOfVehicle(*vehicle);
    if (f == nullptr) continue;
    *movement = f->movement_name;
    const OracleFlow* other = traffic.FlowOfVehicle(vehicle == &c.collider ? c.victim : c.collider);
    if (other != nullptr && other->intersection == f->intersection) {
      const std::optional<std::size_t> x = runtime.Find(f->intersection);
      c.conflicting_groups =
          x && runtime.intersections()[*x].model->conflicts[f->group][other->group];
    }
    const std::optional<std::size_t> i = runtime.Find(f->intersection);
    if (!i) continue;
    signals += (signals.empty() ? "" : "; ") + *vehicle + ": " + greens.Describe(*i, f->group, t);
  }
  c.signals = std::move(signals);
}

// Starts SUMO through the co-simulation with the oracle's traffic.
std::unique_ptr<CoSimulation> StartCoSimulation(const scm::City& city, const fs::path& out,
                                                const OracleTraffic& traffic,
                                                const CollisionOracleOptions& o) {
  TrafficConfig config;
  config.seed = o.seed;
  config.step_s = o.step;
  config.vehicles = 0;
  config.route_files = {(out / "oracle.rou.xml").string()};
  config.speed_mps = traffic.road_speed_mps;
  config.lab_cars.source = "none";
  config.sumo.args = {"--collision-output",
                      (out / "collisions.xml").string(),
                      "--statistic-output",
                      (out / "statistics.xml").string(),
                      "--end",
                      SumoSeconds(o.duration + o.step)};
  CoSimulation::Options options;
  options.work_dir = out;
  options.check_junction_collisions = true;
  return std::make_unique<CoSimulation>(city, config, std::move(options));
}

std::string Figure(double s) { return fmt::format("{:.1f}", s); }

std::string ReportText(const CollisionOracleResult& r, const std::vector<std::string>& inputs) {
  std::string t =
      fmt::format("verdict: {} junction collision{} ({} between conflicting groups; {} other)\n",
                  r.junction_collisions, r.junction_collisions == 1 ? "" : "s",
                  r.intergreen_collisions, r.other_collisions);
  for (const std::string& line : inputs) t += line + "\n";
  t += fmt::format(
      "vehicles: {} departed, {} arrived ({} made by the flows, {} waiting to go in at the end); "
      "SUMO's safety statistics: {} collision records, {} emergency stops; conflict monitor "
      "violations: {}\n",
      r.vehicles_departed, r.vehicles_arrived, r.vehicles_loaded, r.vehicles_waiting,
      r.sumo_collisions, r.emergency_stops, r.monitor_violations);
  t += fmt::format("CPU: {:.1f} s ({:.1f} s in SUMO's steps)\n", r.cpu_s, r.sumo_step_cpu_s);
  t += "intergreens given (least seen from a group's end of green to a conflicting green; "
       "matrix entry):\n";
  for (const ObservedIntergreen& g : r.intergreens) {
    t += fmt::format("  {} {} > {}: {} s (matrix {} s, {} times)\n", g.intersection, g.clearing,
                     g.entering, Figure(g.observed_s), Figure(g.matrix_s), g.transitions);
  }
  t += fmt::format("collisions ({}):\n", r.collisions.size());
  for (const OracleCollision& c : r.collisions) {
    t += fmt::format(
        "  {:.1f} s {} {}{} on {}: {} ({}, {}, {:.2f} m/s) and {} ({}, {}, {:.2f} m/s); {}\n",
        c.time_s, c.in_junction ? "junction" : "lane", c.type,
        c.conflicting_groups ? " (conflicting groups)" : "", c.lane, c.collider, c.collider_type,
        c.collider_movement, c.collider_speed_mps, c.victim, c.victim_type, c.victim_movement,
        c.victim_speed_mps, c.signals);
  }
  return t;
}

std::string ReportJson(const CollisionOracleResult& r, const std::vector<std::string>& inputs,
                       const OracleTraffic& traffic, const CollisionOracleOptions& o) {
  nlohmann::json j = {{"junction_collisions", r.junction_collisions},
                      {"intergreen_collisions", r.intergreen_collisions},
                      {"other_collisions", r.other_collisions},
                      {"intergreens_changed", o.intergreens.Describe()},
                      {"intergreen_factor", o.intergreens.kind == IntergreenChange::Kind::kScale
                                                ? nlohmann::json(o.intergreens.factor)
                                                : nlohmann::json(nullptr)},
                      {"duration_s", ToSeconds(o.duration)},
                      {"step_s", ToSeconds(o.step)},
                      {"seed", o.seed},
                      {"headway_s", ToSeconds(o.headway)},
                      {"inputs", inputs},
                      {"vehicles_departed", r.vehicles_departed},
                      {"vehicles_arrived", r.vehicles_arrived},
                      {"vehicles_loaded", r.vehicles_loaded},
                      {"vehicles_waiting", r.vehicles_waiting},
                      {"sumo_collisions", r.sumo_collisions},
                      {"emergency_stops", r.emergency_stops},
                      {"monitor_violations", r.monitor_violations},
                      {"cpu_s", r.cpu_s},
                      {"sumo_step_cpu_s", r.sumo_step_cpu_s},
                      {"flows", traffic.flows.size()},
                      {"vehicle_types", nlohmann::json::array()},
                      {"intergreens", nlohmann::json::array()},
                      {"collisions", nlohmann::json::array()}};
  for (const OracleVehicleType& v : traffic.types) {
    j["vehicle_types"].push_back({{"id", v.id},
                                  {"why", v.why},
                                  {"length_m", v.length_m},
                                  {"max_speed_mps", v.max_speed_mps},
                                  {"accel_mps2", v.accel_mps2},
                                  {"decel_mps2", v.decel_mps2},
                                  {"drive_after_yellow_s", ToSeconds(v.drive_after_yellow)}});
  }
  for (const ObservedIntergreen& g : r.intergreens) {
    j["intergreens"].push_back({{"intersection", g.intersection},
                                {"clearing", g.clearing},
                                {"entering", g.entering},
                                {"matrix_s", g.matrix_s},
                                {"observed_s", g.observed_s},
                                {"transitions", g.transitions}});
  }
  for (const OracleCollision& c : r.collisions) {
    j["collisions"].push_back({{"time_s", c.time_s},
                               {"type", c.type},
                               {"lane", c.lane},
                               {"junction", c.junction},
                               {"in_junction", c.in_junction},
                               {"conflicting_groups", c.conflicting_groups},
                               {"collider", c.collider},
                               {"victim", c.victim},
                               {"collider_type", c.collider_type},
                               {"victim_type", c.victim_type},
                               {"collider_speed_mps", c.collider_speed_mps},
                               {"victim_speed_mps", c.victim_speed_mps},
                               {"collider_movement", c.collider_movement},
                               {"victim_movement", c.victim_movement},
                               {"signals", c.signals}});
  }
  return j.dump(2) + "\n";
}

}  // namespace

std::string IntergreenChange::Describe() const {
  switch (kind) {
    case Kind::kNone:
      return "the city's timings";
    case Kind::kScale:
      return fmt::format("every intergreen x {:g}", factor);
    case Kind::kMatrix:
      return "every group's yellow + red clearance at its largest intergreen matrix entry";
  }
  return "?";
}

std::vector<std::string> ChangeIntergreens(scm::City& city, const IntergreenChange& change,
                                           Duration step) {
  AUTODRIVE_THROW_UNLESS(step > Duration{0}, "the step must be > 0");
  using Kind = IntergreenChange::Kind;
  if (change.kind == Kind::kNone) return {};
  AUTODRIVE_THROW_UNLESS(change.kind != Kind::kScale || (change.factor > 0 && change.factor <= 1),
                         "the intergreens' factor must be in (0, 1], got " << change.factor);
  const auto scaled = [&](Duration d) {
    return FloorToStep(FromSeconds(ToSeconds(d) * change.factor), step);
  };
  std::vector<std::string> notes;
  for (scm::IntersectionModel& x : city.intersections) {
    for (std::size_t g = 0; g < x.groups.size(); ++g) {
      scm::GroupTiming& t = x.groups[g].timing;
      const Duration total = t.yellow + t.red_clearance;
      Duration target = scaled(total);
      if (change.kind == Kind::kMatrix) {
        target = Duration{0};
        for (Duration e : x.intergreens[g]) target = std::max(target, e);
        target = FloorToStep(target + step - Duration(1), step);  // up to a step
        target = std::max(target, t.yellow);                      // the yellow kept
      }
      const Duration yellow = std::min(t.yellow, target);
      notes.push_back(fmt::format(
          "{} {}: yellow {} s + red clearance {} s = {} s -> {} s + {} s = {} s", x.name,
          GroupLabel(x, g), SumoSeconds(t.yellow), SumoSeconds(t.red_clearance), SumoSeconds(total),
          SumoSeconds(yellow), SumoSeconds(target - yellow), SumoSeconds(target)));
      t.yellow = yellow;
      t.red_clearance = target - yellow;
    }
    if (change.kind == Kind::kScale) {
      for (auto& row : x.intergreens) {
        for (Duration& e : row) e = scaled(e);
      }
    }
    for (scm::Plan& p : x.plans) {
      if (p.type != scm::PlanType::kFixed) continue;
      SetCycle(x.groups, p);
      notes.push_back(fmt::format("{} plan {}: cycle {} s", x.name, p.name, SumoSeconds(p.cycle)));
    }
  }
  return notes;
}

CollisionOracleResult RunCollisionOracle(const scm::City& loaded, const CollisionOracleOptions& o) {
  const std::clock_t cpu0 = std::clock();
  auto city = std::make_unique<scm::City>(loaded);
  std::vector<std::string> inputs;
  inputs.push_back(fmt::format("city {}: {} s from {}, step {} s, seed {}", city->config.name,
                               SumoSeconds(o.duration), internal::HoursMinutes(o.time_of_day),
                               SumoSeconds(o.step), o.seed));
  if (o.intergreens.kind != IntergreenChange::Kind::kNone) {
    inputs.push_back(
        fmt::format("intergreens altered in memory after loading (the loader refuses them): {}{}:",
                    o.intergreens.Describe(),
                    o.intergreens.kind == IntergreenChange::Kind::kScale
                        ? " (yellow + red clearance, the yellow kept, and the matrix)"
                        : ""));
    for (const std::string& n : ChangeIntergreens(*city, o.intergreens, o.step)) {
      inputs.push_back("  " + n);
    }
  }
  for (const std::string& p : CheckCollisionOracleOptions(*city, o))
    inputs.push_back("plans: " + p);
  {
    const scm::SafetyConfig& safety = city->config.safety;
    std::string clearing;
    for (const scm::ClearingVehicleConfig& v : safety.clearing_vehicles) {
      clearing += fmt::format("{}{} {} m at {} m/s", clearing.empty() ? "" : ", ", v.name,
                              v.length_m, v.speed_mps);
    }
    inputs.push_back(fmt::format(
        "intergreen matrix (scm/core/intergreen.h) for clearing vehicles {}, entering speed {} "
        "m/s, t_cross {} s",
        clearing, safety.entering_speed_mps, safety.crossing_time_s));
  }
  scm::CityRuntime runtime(std::move(city));
  const scm::City& c = runtime.city();

  fs::create_directories(o.out_dir);
  const fs::path out = fs::absolute(o.out_dir);
  OracleTrafficParams params;
  params.headway = o.headway;
  params.intersection = o.intersection;
  params.end = o.duration;
  for (const scm::IntersectionModel& x : c.intersections) {
    params.begin = std::max(params.begin, x.startup_flash + x.startup_all_red);
  }
  maps::SumoOptions net_options;
  net_options.speed_mps = OracleTypesOf(c, maps::kSumoScale).road_speed_mps;
  const OracleTraffic traffic =
      OracleTrafficOf(c, maps::ExportSumo(c.map, (out / "network").string(), net_options), params);
  WriteFile(out / "oracle.rou.xml", OracleRoutesXml(traffic));
  inputs.push_back(fmt::format(
      "traffic: {} flows (oracle.rou.xml) from {} s, a vehicle every {} s per ingress lane on "
      "average; roads {} m/s (lab)",
      traffic.flows.size(), SumoSeconds(traffic.begin), SumoSeconds(o.headway),
      traffic.road_speed_mps));
  for (const OracleVehicleType& v : traffic.types) {
    inputs.push_back(fmt::format("type {}: {:.3g} m, {:.3g} m/s, accel {:.3g} m/s^2 in SUMO; {}",
                                 v.id, v.length_m, v.max_speed_mps, v.accel_mps2, v.why));
  }

  std::unique_ptr<CoSimulation> cosim = StartCoSimulation(c, out, traffic, o);
  const MonoTime origin = MonoTime{} + std::chrono::hours(1);
  runtime.Start(origin, {});
  scm::EventRecorder events;
  GreenHistory greens(runtime);
  std::vector<HeadLamp> lamps(runtime.heads().size());
  std::vector<int> reported(runtime.heads().size(), -1);
  std::uint64_t violations = 0;
  const Duration every = std::max(o.duration / 20, o.step);
  for (Duration t{0}; t < o.duration; t += o.step) {
    const MonoTime now = origin + t;
    violations += runtime
                      .Step(ClockReading{now, Time{} + (now - MonoTime{})},
                            scm::DayClock::At(o.time_of_day + t), nullptr, events)
                      .monitor_violations;
    greens.Sample(t);
    for (std::size_t h = 0; h < lamps.size(); ++h) {
      const int lamp = lamps[h].At(runtime.AspectOfHead(h), t);
      if (lamp == reported[h]) continue;
      reported[h] = lamp;
      cosim->ReportLamp(runtime.heads()[h].id, lamp, now);
    }
    (void)cosim->Step({}, now);
    if (o.progress && (t + o.step) % every == Duration{0}) {
      o.progress(fmt::format("{} s of {} s: {} vehicles departed, {} collisions so far",
                             SumoSeconds(t + o.step), SumoSeconds(o.duration),
                             cosim->stats().departed, cosim->stats().collisions));
    }
  }
  CollisionOracleResult r;
  r.vehicles_departed = cosim->stats().departed;
  r.vehicles_arrived = cosim->stats().arrived_planned;
  r.sumo_step_cpu_s = cosim->stats().sumo_step_cpu_s;
  cosim.reset();  // closes SUMO: its outputs are written
  r.monitor_violations = violations;
  r.collisions = ReadCollisions(out / "collisions.xml", o.step);
  ReadStatistics(out / "statistics.xml", r);
  for (OracleCollision& col : r.collisions) {
    Explain(traffic, runtime, greens, col);
    ++(col.in_junction ? r.junction_collisions : r.other_collisions);
    if (col.in_junction && col.conflicting_groups) ++r.intergreen_collisions;
  }
  r.intergreens = greens.Observed();
  r.cpu_s = static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC;
  r.text = ReportText(r, inputs);
  r.text_report = out / "report.txt";
  r.json_report = out / "report.json";
  WriteFile(r.text_report, r.text);
  WriteFile(r.json_report, ReportJson(r, inputs, traffic, o));
  return r;
}

}  // namespace autodrive::traffic::nema
