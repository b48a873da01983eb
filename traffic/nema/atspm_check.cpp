#include "traffic/nema/atspm_check.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>
#include <pugixml.hpp>

#include "traffic/cosim.h"
#include "traffic/nema/collision_oracle.h"
#include "traffic/nema/internal/head_lamp.h"
#include "traffic/nema/internal/io.h"
#include "traffic/nema/nema_program.h"
#include "traffic/nema/oracle_traffic.h"

#include "common/error.h"
#include "maps/sumo.h"
#include "scm/atspm/arrivals.h"
#include "scm/atspm/event_log.h"
#include "scm/atspm/splits.h"
#include "scm/core/fleet.h"
#include "scm/core/ring_plan.h"
#include "scm/core/runtime.h"

namespace autodrive::traffic::nema {

namespace {

namespace fs = std::filesystem;
using internal::HeadLamp;
using internal::WriteFile;
using Window = std::pair<double, double>;

constexpr double kEps = 1e-6;

pugi::xml_document Load(const fs::path& file, const char* what) {
  pugi::xml_document doc;
  const pugi::xml_parse_result r = doc.load_file(file.c_str());
  AUTODRIVE_THROW_UNLESS(r, file.string()
                                << ": cannot read SUMO's " << what << ": " << r.description());
  return doc;
}

bool Inside(const std::vector<Window>& windows, double t) {
  return std::ranges::any_of(windows,
                             [&](const Window& w) { return w.first <= t && t < w.second; });
}

// The windows during which `state` (a tlsState string) shows one of `chars` at any of `links`.
std::vector<Window> StateWindows(const std::vector<std::pair<double, std::string>>& states,
                                 const std::vector<int>& links, std::string_view chars) {
  std::vector<Window> out;
  double open = std::numeric_limits<double>::quiet_NaN();  // NaN: none open
  for (const auto& [t, state] : states) {
    const bool on = std::ranges::any_of(links, [&](int l) {
      return static_cast<std::size_t>(l) < state.size() &&
             chars.find(state[static_cast<std::size_t>(l)]) != std::string_view::npos;
    });
    if (on && std::isnan(open)) open = t;
    if (!on && !std::isnan(open)) {
      out.emplace_back(open, t);
      open = std::numeric_limits<double>::quiet_NaN();
    }
  }
  return out;
}

// The union of windows (sorted, overlapping and touching ones merged).
std::vector<Window> Union(std::vector<Window> w) {
  std::ranges::sort(w);
  std::vector<Window> out;
  for (const Window& x : w) {
    if (!out.empty() && x.first <= out.back().second + kEps) {
      out.back().second = std::max(out.back().second, x.second);
    } else {
      out.push_back(x);
    }
  }
  return out;
}

// The loops of the additional file by phase: "aog_p<phase>_<lane>".
std::map<std::uint16_t, SumoPhaseRecords> ReadLoops(
    const SumoFiles& f, std::map<std::string, std::uint16_t>& phase_of) {
  std::map<std::uint16_t, SumoPhaseRecords> phases;
  const pugi::xml_document add = Load(f.additional, "additional file");
  for (pugi::xml_node n : add.child("additional").children("instantInductionLoop")) {
    const std::string id = n.attribute("id").as_string();
    unsigned phase = 0;
    if (std::sscanf(id.c_str(), "aog_p%u_", &phase) != 1 || phase == 0 || phase > 65535) continue;
    const auto p = static_cast<std::uint16_t>(phase);
    phases[p].phase = p;
    phases[p].lanes.emplace_back(n.attribute("lane").as_string());
    phase_of[id] = p;
  }
  const pugi::xml_document loops = Load(f.loops, "instantInductionLoop output");
  for (pugi::xml_node n : loops.first_child().children("instantOut")) {
    if (std::string_view(n.attribute("state").as_string()) != "enter") continue;
    const auto it = phase_of.find(n.attribute("id").as_string());
    if (it != phase_of.end()) phases[it->second].entries.push_back(n.attribute("time").as_double());
  }
  for (auto& [p, r] : phases) std::ranges::sort(r.entries);
  return phases;
}

}  // namespace

SumoRecords ReadSumoRecords(const SumoFiles& f) {
  std::map<std::string, std::uint16_t> phase_of_loop;
  std::map<std::uint16_t, SumoPhaseRecords> phases = ReadLoops(f, phase_of_loop);
  std::map<std::string, std::uint16_t> phase_of_lane;
  for (const auto& [p, r] : phases) {
    for (const std::string& lane : r.lanes) phase_of_lane[lane] = p;
  }
  SumoRecords out;
  // Green windows: each link's from the switch times, by phase of its from-lane.
  std::map<std::uint16_t, std::map<std::string, std::vector<Window>>> by_link;
  const pugi::xml_document sw = Load(f.switches, "SaveTLSSwitchTimes output");
  for (pugi::xml_node n : sw.child("tlsSwitches").children("tlsSwitch")) {
    if (f.tls != n.attribute("id").as_string()) continue;
    const auto it = phase_of_lane.find(n.attribute("fromLane").as_string());
    if (it == phase_of_lane.end()) continue;
    const std::string link =
        std::string(n.attribute("fromLane").as_string()) + ">" + n.attribute("toLane").as_string();
    by_link[it->second][link].emplace_back(n.attribute("begin").as_double(),
                                           n.attribute("end").as_double());
  }
  // Yellows: the states at the link indices of the phase's lanes (the network's connections).
  std::map<std::uint16_t, std::vector<int>> links_of;
  const pugi::xml_document net = Load(f.net, "network");
  for (pugi::xml_node c : net.child("net").children("connection")) {
    if (f.tls != c.attribute("tl").as_string()) continue;
    const std::string lane =
        std::string(c.attribute("from").as_string()) + "_" + c.attribute("fromLane").as_string();
    const auto it = phase_of_lane.find(lane);
    if (it != phase_of_lane.end())
      links_of[it->second].push_back(c.attribute("linkIndex").as_int());
  }
  std::vector<std::pair<double, std::string>> states;
  const pugi::xml_document st = Load(f.states, "SaveTLSStates output");
  for (pugi::xml_node n : st.child("tlsStates").children("tlsState")) {
    if (f.tls != n.attribute("id").as_string()) continue;
    states.emplace_back(n.attribute("time").as_double(), n.attribute("state").as_string());
  }
  for (auto& [p, r] : phases) {
    std::vector<Window> all;
    const std::vector<Window>* first = nullptr;
    for (const auto& [link, windows] : by_link[p]) {
      if (first != nullptr && windows != *first) ++out.links_disagreeing;
      if (first == nullptr) first = &windows;
      all.insert(all.end(), windows.begin(), windows.end());
    }
    r.greens = Union(std::move(all));
    r.yellows = StateWindows(states, links_of[p], "yY");
    out.phases.push_back(std::move(r));
  }
  return out;
}

namespace {

// ---------------------------------------------------------------------------------------------
// The run.

struct Loop {
  std::string id;
  std::string lane;  // SUMO lane
  double pos = 0.0;  // SUMO m from the lane's start
};

// Where the check's SUMO run is and what it was given.
struct Setup {
  std::string tls;
  std::size_t x = 0;  // the intersection's index in the city
  scm::RingPlan ring;
  std::vector<Loop> loops;
  std::vector<std::string> inputs;  // lines of the report
};

std::map<std::string, double> LaneLengths(const fs::path& net_file) {
  std::map<std::string, double> out;
  const pugi::xml_document net = Load(net_file, "network");
  for (pugi::xml_node e : net.child("net").children("edge")) {
    for (pugi::xml_node l : e.children("lane")) {
      out[l.attribute("id").as_string()] = l.attribute("length").as_double();
    }
  }
  return out;
}

// Gives every fixed-time plan of `x` a zone per ingress lane and group at the detection point
// and lists SUMO's loops at the same place. Throws InputError for a lane of two groups or a
// point SUMO cannot hold.
std::vector<Loop> PlaceDetectors(const scm::City& city, scm::IntersectionModel& x,
                                 const scm::RingPlan& ring, const maps::SumoExport& net,
                                 double longest_vehicle_m, const AtspmCheckOptions& o) {
  std::map<LaneId, std::size_t> group_of;
  std::map<LaneId, std::string> sumo_lane;
  for (std::size_t g = 0; g < x.groups.size(); ++g) {
    for (MovementId m : x.groups[g].movements) {
      const LaneId lane = city.map.movement(m).from;
      const auto [it, fresh] = group_of.try_emplace(lane, g);
      AUTODRIVE_THROW_UNLESS(fresh || it->second == g,
                             "lane " << city.map.lane(lane).name << " of " << x.name
                                     << " carries two groups' movements: the check wants one "
                                        "group per ingress lane");
      sumo_lane[lane] = net.movement(m).from.id();
    }
  }
  const std::map<std::string, double> lengths = LaneLengths(net.net_file);
  std::vector<Loop> loops;
  std::vector<scm::Detector> zones;
  for (const auto& [lane, g] : group_of) {
    std::vector<std::uint32_t> phases;
    for (const scm::RingPhase& p : ring.phases) {
      if (std::ranges::find(p.groups, g) != p.groups.end()) phases.push_back(p.number);
    }
    AUTODRIVE_THROW_UNLESS(phases.size() == 1, "group " << x.groups[g].name << " of " << x.name
                                                        << " is in " << phases.size()
                                                        << " phases: the check wants one");
    const std::string& sl = sumo_lane.at(lane);
    const double pos = lengths.at(sl) - o.setback_m * net.scale;
    AUTODRIVE_THROW_UNLESS(pos > longest_vehicle_m && o.zone_m > 0 && o.zone_m <= o.setback_m,
                           "the detection point " << o.setback_m << " m before the stop line is "
                                                  << pos << " m into SUMO lane " << sl
                                                  << ": it must lie past the inserted vehicles' "
                                                     "fronts ("
                                                  << longest_vehicle_m << " m)");
    loops.push_back({fmt::format("aog_p{}_{}", phases[0], sl), sl, pos});
    zones.push_back({g, lane, o.setback_m - o.zone_m, o.setback_m});
  }
  for (scm::Plan& p : x.plans) {
    if (p.type == scm::PlanType::kFixed) p.detectors = zones;
  }
  return loops;
}

std::string AdditionalXml(const Setup& s, const fs::path& out) {
  pugi::xml_document doc;
  doc.append_child(pugi::node_comment)
      .set_value(
          " autodrive-scm-nema atspm-check: a loop per ingress lane at the SCM's arrival "
          "detection point (id aog_p<phase>_<lane>), the light's switch times and states. ");
  auto root = doc.append_child("additional");
  for (const Loop& l : s.loops) {
    auto n = root.append_child("instantInductionLoop");
    n.append_attribute("id") = l.id.c_str();
    n.append_attribute("lane") = l.lane.c_str();
    n.append_attribute("pos") = fmt::format("{:.4f}", l.pos).c_str();
    n.append_attribute("file") = (out / "loops.xml").c_str();
  }
  for (const auto& [type, file] : {std::pair{"SaveTLSSwitchTimes", "switches.xml"},
                                   std::pair{"SaveTLSStates", "states.xml"}}) {
    auto e = root.append_child("timedEvent");
    e.append_attribute("type") = type;
    e.append_attribute("source") = s.tls.c_str();
    e.append_attribute("dest") = (out / file).c_str();
  }
  std::ostringstream text;
  doc.save(text, "    ");
  return text.str();
}

// The plan the intersection runs throughout (fixed time, checked), its city with the zones, and
// the SUMO files' inputs.
Setup Prepare(scm::City& city, const AtspmCheckOptions& o, const fs::path& out,
              maps::SumoExport& net, OracleTraffic& traffic) {
  CollisionOracleOptions check;
  check.duration = o.duration;
  check.time_of_day = o.time_of_day;
  check.step = o.step;
  check.out_dir = out;
  check.intersection = o.intersection;
  Setup s;
  for (const std::string& p : CheckCollisionOracleOptions(city, check)) {
    s.inputs.push_back("plans: " + p);
  }
  const scm::IntersectionModel* found = city.Find(o.intersection);
  s.x = static_cast<std::size_t>(found - city.intersections.data());
  scm::IntersectionModel& x = city.intersections[s.x];
  const std::size_t plan = x.ScheduledPlan(scm::DayClock::At(o.time_of_day).minute_of_day);
  for (Duration t = o.time_of_day; t <= o.time_of_day + o.duration; t += std::chrono::minutes(1)) {
    AUTODRIVE_THROW_UNLESS(x.ScheduledPlan(scm::DayClock::At(t).minute_of_day) == plan,
                           x.name << " changes plan during the run: the check wants one plan");
  }
  s.ring = scm::RingPlanOf(x, x.plans[plan]);
  maps::SumoOptions net_options;
  net_options.speed_mps = OracleTypesOf(city, maps::kSumoScale).road_speed_mps;
  net = maps::ExportSumo(city.map, (out / "network").string(), net_options);
  s.tls = net.junctions.at(x.id);
  OracleTrafficParams params;
  params.headway = o.headway;
  params.intersection = x.name;
  params.end = o.duration;
  for (const scm::IntersectionModel& m : city.intersections) {
    params.begin = std::max(params.begin, m.startup_flash + m.startup_all_red);
  }
  traffic = OracleTrafficOf(city, net, params);
  double longest = 0.0;
  for (const OracleVehicleType& t : traffic.types) longest = std::max(longest, t.length_m);
  s.loops = PlaceDetectors(city, x, s.ring, net, longest, o);
  s.inputs.push_back(fmt::format(
      "arrival detection point: {} lab m before the stop line on each ingress lane (SUMO: "
      "instantInductionLoop at {} m before the lane's end; SCM: zone {}..{} m, its channel = "
      "the group's)",
      o.setback_m, o.setback_m * net.scale, o.setback_m - o.zone_m, o.setback_m));
  s.inputs.push_back(fmt::format(
      "traffic: the oracle's vehicles through {} ({} flows), a vehicle every {} s per ingress "
      "lane on average from {} s",
      x.name, traffic.flows.size(), SumoSeconds(o.headway), SumoSeconds(params.begin)));
  return s;
}

std::unique_ptr<CoSimulation> StartSumo(const scm::City& city, const fs::path& out,
                                        const maps::SumoExport& net, const OracleTraffic& traffic,
                                        const AtspmCheckOptions& o) {
  TrafficConfig config;
  config.seed = o.seed;
  config.step_s = o.step;
  config.vehicles = 0;
  config.route_files = {(out / "oracle.rou.xml").string()};
  config.speed_mps = traffic.road_speed_mps;
  config.lab_cars.source = "none";
  config.sumo.args = {"--additional-files",
                      net.vtype_file.string() + "," + (out / "atspm.add.xml").string(),
                      "--precision",
                      "4",  // loop stamps to 0.1 ms (SUMO writes 2 digits)
                      "--end",
                      SumoSeconds(o.duration + o.step)};
  CoSimulation::Options options;
  options.work_dir = out;
  options.check_junction_collisions = true;
  return std::make_unique<CoSimulation>(city, config, std::move(options));
}

struct RunOutput {
  std::vector<scm::atspm::Event> events;  // the intersection's hires log, t = 0 at the start
  std::int64_t departed = 0;
  std::uint64_t violations = 0;
  std::uint64_t dropped = 0;
};

// The co-simulation: the SCM's runtime, SUMO, and SUMO's vehicles into the SCM's fleet.
RunOutput Run(scm::CityRuntime& runtime, CoSimulation& cosim, std::size_t xi,
              const AtspmCheckOptions& o) {
  RunOutput r;
  const MonoTime origin = MonoTime{} + std::chrono::hours(1);
  const auto wire = [](MonoTime m) { return Time{} + (m - MonoTime{}); };
  scm::FleetRegistry fleet(runtime.city().map);
  runtime.Start(origin, {});
  scm::EventRecorder events;
  std::vector<HeadLamp> lamps(runtime.heads().size());
  std::vector<int> reported(runtime.heads().size(), -1);
  std::vector<scm::TrafficObservation> batch;
  const Duration every = std::max(o.duration / 10, o.step);
  for (Duration t{0}; t < o.duration; t += o.step) {
    const MonoTime now = origin + t;
    r.violations += runtime
                        .Step(ClockReading{now, wire(now)}, scm::DayClock::At(o.time_of_day + t),
                              &fleet, events)
                        .monitor_violations;
    for (std::size_t i = 0; i < runtime.intersections().size(); ++i) {
      scm::IntersectionController& c = *runtime.intersections()[i].controller;
      if (i != xi) {
        c.ClearHiresEvents();
        continue;
      }
      for (const scm::HiresEvent& e : c.TakeHiresEvents()) {
        r.events.push_back({Time{} + (e.at - origin), e.code, e.param});
      }
    }
    for (std::size_t h = 0; h < lamps.size(); ++h) {
      const int lamp = lamps[h].At(runtime.AspectOfHead(h), t);
      if (lamp == reported[h]) continue;
      reported[h] = lamp;
      cosim.ReportLamp(runtime.heads()[h].id, lamp, now);
    }
    batch.clear();
    for (const TrafficVehicle& v : cosim.Step({}, now)) {
      batch.push_back({v.id, v.map_lane, v.centre, v.length_m});
    }
    (void)fleet.ObserveTraffic(wire(now + o.step), batch);
    if (o.progress && (t + o.step) % every == Duration{0}) {
      o.progress(fmt::format("{} s of {} s: {} vehicles departed, {} hires records",
                             SumoSeconds(t + o.step), SumoSeconds(o.duration),
                             cosim.stats().departed, r.events.size()));
    }
  }
  r.departed = cosim.stats().departed;
  r.dropped = runtime.intersections()[xi].controller->hires_dropped();
  // Records of one instant keep their order; the min-green record (3) is logged at the min
  // green's end, which a detector's step may pass: the log by time, as the store keeps it.
  std::ranges::stable_sort(r.events, {}, &scm::atspm::Event::at);
  return r;
}

// ---------------------------------------------------------------------------------------------
// The comparison.

namespace atspm = scm::atspm;

double Sec(Time t) { return ToSeconds(t - Time{}); }

// The SCM's greens of `phase`: begin green (1) to begin yellow (8).
std::vector<Window> ScmGreens(const std::vector<atspm::Event>& events, std::uint16_t phase) {
  std::vector<Window> out;
  double open = std::numeric_limits<double>::quiet_NaN();  // NaN: none open
  for (const atspm::Event& e : events) {
    if (e.param != phase) continue;
    if (e.code == atspm::code::kPhaseBeginGreen) open = Sec(e.at);
    if (e.code == atspm::code::kPhaseBeginYellow && !std::isnan(open)) {
      out.emplace_back(open, Sec(e.at));
      open = std::numeric_limits<double>::quiet_NaN();
    }
  }
  return out;
}

const SumoPhaseRecords* FindPhase(const SumoRecords& sumo, std::uint16_t phase) {
  const auto it = std::ranges::find(sumo.phases, phase, &SumoPhaseRecords::phase);
  return it == sumo.phases.end() ? nullptr : &*it;
}

// The time the SCM's detector reads a loop entry stamped `t`: SUMO stamps an entry inside the
// move of the step labelled ceil(t / step) (its interval (label - step, label]); the SCM sees
// that step's positions at its next control step.
double ReadTime(double t, double step) { return (std::ceil(t / step - 1e-6) + 1.0) * step; }

// Per phase and bin: loop entries and those inside the greens, between the phase's first and
// last end of yellow (the PCD's red-to-red cycles), each at `when(entry)`.
template <typename When>
std::vector<std::pair<int, int>> SumoBins(const SumoPhaseRecords* rec, std::size_t bins,
                                          double bin_s, When when) {
  std::vector<std::pair<int, int>> out(bins);  // volume, on green
  if (rec == nullptr || rec->yellows.empty()) return out;
  const double from = rec->yellows.front().second;
  const double to = rec->yellows.back().second;
  for (const double entry : rec->entries) {
    const double e = when(entry);
    if (e < from || e >= to) continue;
    const auto k = static_cast<std::size_t>(std::floor(e / bin_s));
    if (k >= out.size()) continue;
    ++out[k].first;
    out[k].second += Inside(rec->greens, e) ? 1 : 0;
  }
  return out;
}

bool Agree(int scm_volume, int sumo_volume, double difference_pp, double tolerance_pp) {
  return (scm_volume == 0 && sumo_volume == 0) ||
         (scm_volume > 0 && sumo_volume > 0 && std::abs(difference_pp) <= tolerance_pp + kEps);
}

// Per phase and bin: the SCM's PCD bins against SUMO's loop entries inside its greens, at the
// entries' times (literal) and at the times the SCM reads them.
void CompareAog(const atspm::PcdResult& pcd, const SumoRecords& sumo,
                const std::vector<atspm::Window>& bins, const AtspmCheckOptions& o,
                AtspmCheckResult& r) {
  std::set<std::uint16_t> phases;
  for (const atspm::PcdPhase& p : pcd.phases) phases.insert(p.phase);
  for (const SumoPhaseRecords& p : sumo.phases) phases.insert(p.phase);
  const double bin_s = ToSeconds(o.bin);
  const double step = ToSeconds(o.step);
  for (const std::uint16_t phase : phases) {
    const auto scm = std::ranges::find(pcd.phases, phase, &atspm::PcdPhase::phase);
    const SumoPhaseRecords* rec = FindPhase(sumo, phase);
    const auto literal = SumoBins(rec, bins.size(), bin_s, [](double t) { return t; });
    const auto read =
        SumoBins(rec, bins.size(), bin_s, [step](double t) { return ReadTime(t, step); });
    for (std::size_t k = 0; k < bins.size(); ++k) {
      AogRow row;
      row.phase = phase;
      row.bin_start_s = Sec(bins[k].since);
      if (scm != pcd.phases.end() && k < scm->bins.size()) {
        row.scm_volume = scm->bins[k].second.volume;
        row.scm_on_green = scm->bins[k].second.on_green;
        row.scm_percent = scm->bins[k].second.percent_on_green();
      }
      std::tie(row.sumo_volume, row.sumo_on_green) = literal[k];
      row.sumo_percent = atspm::Percent(row.sumo_on_green, row.sumo_volume);
      row.difference_pp = row.scm_percent - row.sumo_percent;
      row.ok = Agree(row.scm_volume, row.sumo_volume, row.difference_pp, o.aog_tolerance_pp);
      std::tie(row.read_volume, row.read_on_green) = read[k];
      row.read_percent = atspm::Percent(row.read_on_green, row.read_volume);
      row.read_difference_pp = row.scm_percent - row.read_percent;
      row.read_ok =
          Agree(row.scm_volume, row.read_volume, row.read_difference_pp, o.aog_tolerance_pp);
      r.max_aog_difference_pp = std::max(r.max_aog_difference_pp, std::abs(row.difference_pp));
      r.max_read_difference_pp =
          std::max(r.max_read_difference_pp, std::abs(row.read_difference_pp));
      r.aog.push_back(row);
    }
  }
}

// SUMO's green + yellow + red of the green `w` of `rec`: to the next green of another phase.
std::optional<SplitRow> SumoSplit(const SumoRecords& sumo, const SumoPhaseRecords& rec,
                                  const Window& w) {
  double next = std::numeric_limits<double>::infinity();
  for (const SumoPhaseRecords& other : sumo.phases) {
    if (other.phase == rec.phase) continue;
    for (const Window& g : other.greens) {
      if (g.first >= w.second - kEps) next = std::min(next, g.first);
    }
  }
  if (!std::isfinite(next)) return std::nullopt;  // the run ended first
  SplitRow s;
  s.sumo_green_s = w.second - w.first;
  double yellow_end = w.second;
  for (const Window& y : rec.yellows) {
    if (y.first >= w.second - 0.05 && y.first <= w.second + 1.0) {
      s.sumo_yellow_s = y.second - y.first;
      yellow_end = y.second;
      break;
    }
  }
  s.sumo_red_s = next - yellow_end;
  s.sumo_split_s = next - w.first;
  return s;
}

void CompareSplits(const atspm::SplitMonitorResult& sm, const SumoRecords& sumo,
                   const AtspmCheckOptions& o, AtspmCheckResult& r) {
  for (const atspm::SplitMonitorPhase& p : sm.phases) {
    const SumoPhaseRecords* rec = FindPhase(sumo, p.phase);
    for (const atspm::PhaseCycle& c : p.cycles) {
      const double green = Sec(c.green);
      const Window* w = nullptr;
      if (rec != nullptr) {
        for (const Window& g : rec->greens) {
          if (std::abs(g.first - green) <= 1.0) w = &g;
        }
      }
      std::optional<SplitRow> row = w != nullptr ? SumoSplit(sumo, *rec, *w) : std::nullopt;
      if (!row) {
        if (w == nullptr) ++r.splits_unmatched;
        continue;
      }
      row->phase = p.phase;
      row->green_start_s = green;
      row->scm_green_s = ToSeconds(c.green_time());
      row->scm_yellow_s = ToSeconds(c.yellow_time());
      row->scm_red_s = ToSeconds(c.red_clearance_time());
      row->scm_split_s = ToSeconds(c.split());
      row->difference_s = row->scm_split_s - row->sumo_split_s;
      row->ok = std::abs(row->difference_s) <= ToSeconds(o.split_tolerance) + kEps;
      r.max_split_difference_s = std::max(r.max_split_difference_s, std::abs(row->difference_s));
      r.splits.push_back(*row);
    }
  }
}

// Where a time lies against windows, for people: "0.05 s after the begin green at 82.0 s".
std::string Near(const std::vector<Window>& windows, double t, const char* who) {
  double best = std::numeric_limits<double>::infinity();
  std::string out;
  for (const Window& w : windows) {
    for (const auto& [edge, name] :
         {std::pair{w.first, "green begins"}, {w.second, "green ends"}}) {
      if (std::abs(t - edge) < std::abs(best)) {
        best = t - edge;
        out = fmt::format("{} {} at {:.2f} s", who, name, edge);
      }
    }
  }
  return out;
}

// Each loop entry paired with the first 82 of its phase at or after it (within 1 s): the lag,
// and the pairs the two sides place differently.
void PairArrivals(const std::vector<atspm::Event>& events, const atspm::ChannelMap& map,
                  const SumoRecords& sumo, double step, AtspmCheckResult& r) {
  double lag_sum = 0.0;
  r.lag_min_s = std::numeric_limits<double>::infinity();
  r.lag_max_s = -r.lag_min_s;
  for (const SumoPhaseRecords& rec : sumo.phases) {
    std::vector<double> ons;
    for (const Time t : atspm::DetectorOns(events, map, rec.phase)) ons.push_back(Sec(t));
    r.loop_entries += static_cast<int>(rec.entries.size());
    r.detector_ons += static_cast<int>(ons.size());
    const std::vector<Window> scm_greens = ScmGreens(events, rec.phase);
    std::size_t k = 0;
    for (const double e : rec.entries) {
      while (k < ons.size() && ons[k] < e - 0.05) ++k;
      if (k == ons.size() || ons[k] - e > 1.0) continue;
      const double s = ons[k++];
      ++r.paired;
      r.read_time_matches += std::abs(s - ReadTime(e, step)) < 1e-6 ? 1 : 0;
      lag_sum += s - e;
      r.lag_min_s = std::min(r.lag_min_s, s - e);
      r.lag_max_s = std::max(r.lag_max_s, s - e);
      const bool sumo_green = Inside(rec.greens, e);
      const bool scm_green = Inside(scm_greens, s);
      if (sumo_green == scm_green) continue;
      r.differences.push_back(
          {rec.phase, e, s, sumo_green, scm_green,
           Near(rec.greens, e, "SUMO's") + "; " + Near(scm_greens, s, "the SCM's")});
    }
  }
  if (r.paired == 0) r.lag_min_s = r.lag_max_s = 0.0;
  r.lag_mean_s = r.paired > 0 ? lag_sum / r.paired : 0.0;
}

std::string ReportText(const AtspmCheckResult& r, const std::vector<std::string>& inputs,
                       const AtspmCheckOptions& o) {
  std::string t = fmt::format(
      "verdict: {} ({}); arrivals on green, largest difference: {:.2f} pp at SUMO's loop stamps "
      "({}), {:.2f} pp at the SCM's read times ({}), tolerance {} pp; splits: largest difference "
      "{:.3f} s, tolerance {} s, {} SCM services without a SUMO green\n",
      r.passed ? "PASS" : "FAIL",
      o.literal_verdict ? "on the loop stamps" : "on the entries at the SCM's read times",
      r.max_aog_difference_pp, r.passed_literal ? "pass" : "fail", r.max_read_difference_pp,
      r.passed_read ? "pass" : "fail", o.aog_tolerance_pp, r.max_split_difference_s,
      ToSeconds(o.split_tolerance), r.splits_unmatched);
  for (const std::string& line : inputs) t += line + "\n";
  t += fmt::format(
      "vehicles departed {}; loop entries {}, SCM detector-ons {}, paired {} (SCM 82 - loop "
      "entry: min {:.3f} s, mean {:.3f} s, max {:.3f} s; {} of them exactly at the read time: "
      "the step after the SUMO step that moved the vehicle past the loop); links of a phase with "
      "differing greens {}; conflict monitor violations {}; hires records dropped {}; CPU {:.1f} "
      "s\n",
      r.vehicles_departed, r.loop_entries, r.detector_ons, r.paired, r.lag_min_s, r.lag_mean_s,
      r.lag_max_s, r.read_time_matches, r.links_disagreeing, r.monitor_violations, r.hires_dropped,
      r.cpu_s);
  t += "arrivals on green per phase and bin (SCM: scm/atspm Pcd on the controller's log; SUMO: "
       "loop entries inside SaveTLSSwitchTimes greens, at their stamps and at the SCM's read "
       "times):\n";
  t += "  phase  bin_s   scm_n scm_g  scm_%   sumo_n sumo_g sumo_%  diff_pp   read_n read_g "
       "read_%  diff_pp\n";
  for (const AogRow& a : r.aog) {
    t += fmt::format(
        "  {:5}  {:6.0f}  {:5} {:5}  {:6.2f}  {:6} {:6}  {:6.2f}  {:+7.2f}{}  {:6} {:6}  {:6.2f}  "
        "{:+7.2f}{}\n",
        a.phase, a.bin_start_s, a.scm_volume, a.scm_on_green, a.scm_percent, a.sumo_volume,
        a.sumo_on_green, a.sumo_percent, a.difference_pp, a.ok ? "  " : " !", a.read_volume,
        a.read_on_green, a.read_percent, a.read_difference_pp, a.read_ok ? "" : " !");
  }
  std::map<std::uint16_t, std::vector<const SplitRow*>> by_phase;
  for (const SplitRow& s : r.splits) by_phase[s.phase].push_back(&s);
  t += "split monitor per phase (SCM 1->11 against SUMO green + yellow + red to the next "
       "green):\n";
  for (const auto& [phase, rows] : by_phase) {
    double worst = 0.0;
    for (const SplitRow* s : rows) worst = std::max(worst, std::abs(s->difference_s));
    const SplitRow& f = *rows.front();
    t += fmt::format(
        "  phase {}: {} services, largest difference {:.3f} s; first: SCM {:.1f} + {:.1f} + "
        "{:.1f} = {:.1f} s, SUMO {:.1f} + {:.1f} + {:.1f} = {:.1f} s\n",
        phase, rows.size(), worst, f.scm_green_s, f.scm_yellow_s, f.scm_red_s, f.scm_split_s,
        f.sumo_green_s, f.sumo_yellow_s, f.sumo_red_s, f.sumo_split_s);
    for (const SplitRow* s : rows) {
      if (s->ok) continue;
      t += fmt::format("    FAIL green at {:.1f} s: SCM {:.2f} s, SUMO {:.2f} s\n",
                       s->green_start_s, s->scm_split_s, s->sumo_split_s);
    }
  }
  t += fmt::format("arrivals the two sides place differently ({}):\n", r.differences.size());
  for (const ArrivalDifference& d : r.differences) {
    t += fmt::format("  phase {}: loop entry {:.3f} s ({}), SCM 82 {:.3f} s ({}): {}\n", d.phase,
                     d.sumo_s, d.sumo_green ? "green" : "not green", d.scm_s,
                     d.scm_green ? "green" : "not green", d.why);
  }
  return t;
}

std::string ReportJson(const AtspmCheckResult& r, const std::vector<std::string>& inputs,
                       const AtspmCheckOptions& o) {
  nlohmann::json j = {
      {"passed", r.passed},
      {"intersection", o.intersection},
      {"duration_s", ToSeconds(o.duration)},
      {"seed", o.seed},
      {"headway_s", ToSeconds(o.headway)},
      {"setback_m", o.setback_m},
      {"aog_tolerance_pp", o.aog_tolerance_pp},
      {"split_tolerance_s", ToSeconds(o.split_tolerance)},
      {"test_shift_sumo_windows_s", ToSeconds(o.test_shift_sumo_windows)},
      {"passed_literal", r.passed_literal},
      {"passed_read", r.passed_read},
      {"literal_verdict", o.literal_verdict},
      {"max_aog_difference_pp", r.max_aog_difference_pp},
      {"max_read_difference_pp", r.max_read_difference_pp},
      {"read_time_matches", r.read_time_matches},
      {"max_split_difference_s", r.max_split_difference_s},
      {"splits_unmatched", r.splits_unmatched},
      {"loop_entries", r.loop_entries},
      {"detector_ons", r.detector_ons},
      {"paired", r.paired},
      {"lag_s", {{"min", r.lag_min_s}, {"mean", r.lag_mean_s}, {"max", r.lag_max_s}}},
      {"links_disagreeing", r.links_disagreeing},
      {"vehicles_departed", r.vehicles_departed},
      {"monitor_violations", r.monitor_violations},
      {"hires_dropped", r.hires_dropped},
      {"cpu_s", r.cpu_s},
      {"inputs", inputs},
      {"aog", nlohmann::json::array()},
      {"splits", nlohmann::json::array()},
      {"differences", nlohmann::json::array()}};
  for (const AogRow& a : r.aog) {
    j["aog"].push_back({{"phase", a.phase},
                        {"bin_start_s", a.bin_start_s},
                        {"scm_volume", a.scm_volume},
                        {"scm_on_green", a.scm_on_green},
                        {"scm_percent", a.scm_percent},
                        {"sumo_volume", a.sumo_volume},
                        {"sumo_on_green", a.sumo_on_green},
                        {"sumo_percent", a.sumo_percent},
                        {"difference_pp", a.difference_pp},
                        {"ok", a.ok},
                        {"read_volume", a.read_volume},
                        {"read_on_green", a.read_on_green},
                        {"read_percent", a.read_percent},
                        {"read_difference_pp", a.read_difference_pp},
                        {"read_ok", a.read_ok}});
  }
  for (const SplitRow& s : r.splits) {
    j["splits"].push_back(
        {{"phase", s.phase},
         {"green_start_s", s.green_start_s},
         {"scm", {s.scm_green_s, s.scm_yellow_s, s.scm_red_s, s.scm_split_s}},
         {"sumo", {s.sumo_green_s, s.sumo_yellow_s, s.sumo_red_s, s.sumo_split_s}},
         {"difference_s", s.difference_s},
         {"ok", s.ok}});
  }
  for (const ArrivalDifference& d : r.differences) {
    j["differences"].push_back({{"phase", d.phase},
                                {"sumo_s", d.sumo_s},
                                {"scm_s", d.scm_s},
                                {"sumo_green", d.sumo_green},
                                {"scm_green", d.scm_green},
                                {"why", d.why}});
  }
  return j.dump(2) + "\n";
}

}  // namespace

AtspmCheckResult RunAtspmCheck(const scm::City& loaded, const AtspmCheckOptions& o) {
  const std::clock_t cpu0 = std::clock();
  AUTODRIVE_THROW_UNLESS(!o.intersection.empty(), "no intersection");
  AUTODRIVE_THROW_UNLESS(o.bin > Duration{0}, "the bin must be > 0");
  AUTODRIVE_THROW_UNLESS(!o.out_dir.empty(), "no output folder");
  fs::create_directories(o.out_dir);
  const fs::path out = fs::absolute(o.out_dir);
  auto city = std::make_unique<scm::City>(loaded);
  maps::SumoExport net;
  OracleTraffic traffic;
  Setup s = Prepare(*city, o, out, net, traffic);
  s.inputs.insert(s.inputs.begin(),
                  fmt::format("city {}, intersection {}: {} s from {}, step {} s, seed {}",
                              city->config.name, o.intersection, SumoSeconds(o.duration),
                              internal::HoursMinutes(o.time_of_day), SumoSeconds(o.step), o.seed));
  WriteFile(out / "oracle.rou.xml", OracleRoutesXml(traffic));
  WriteFile(out / "atspm.add.xml", AdditionalXml(s, out));
  scm::CityRuntime runtime(std::move(city));
  std::unique_ptr<CoSimulation> cosim = StartSumo(runtime.city(), out, net, traffic, o);
  const RunOutput run = Run(runtime, *cosim, s.x, o);
  cosim.reset();  // closes SUMO: its outputs are written

  SumoRecords sumo = ReadSumoRecords({net.net_file, out / "atspm.add.xml", out / "loops.xml",
                                      out / "switches.xml", out / "states.xml", s.tls});
  if (o.test_shift_sumo_windows != Duration{0} && !sumo.phases.empty()) {
    const double d = ToSeconds(o.test_shift_sumo_windows);
    for (Window& w : sumo.phases.front().greens) w = {w.first + d, w.second + d};
    s.inputs.push_back(fmt::format("TEST: SUMO's greens of phase {} moved by {} s",
                                   sumo.phases.front().phase,
                                   SumoSeconds(o.test_shift_sumo_windows)));
  }
  atspm::ChannelMap map;
  for (const scm::RingPhase& p : s.ring.phases) {
    for (const std::size_t g : p.groups) {
      map.Add(static_cast<std::uint16_t>(g + 1), static_cast<std::uint16_t>(p.number));
    }
  }
  const atspm::Window window{Time{}, Time{} + o.duration};
  atspm::CheckInput(run.events, window);
  AtspmCheckResult r;
  CompareAog(atspm::Pcd(run.events, window, map, o.bin), sumo, atspm::Bins(window, o.bin), o, r);
  CompareSplits(atspm::SplitMonitor(run.events, window), sumo, o, r);
  PairArrivals(run.events, map, sumo, ToSeconds(o.step), r);
  r.links_disagreeing = sumo.links_disagreeing;
  r.vehicles_departed = run.departed;
  r.monitor_violations = run.violations;
  r.hires_dropped = run.dropped;
  const bool splits_ok =
      !r.splits.empty() && r.splits_unmatched == 0 && std::ranges::all_of(r.splits, &SplitRow::ok);
  r.passed_literal = !r.aog.empty() && splits_ok && std::ranges::all_of(r.aog, &AogRow::ok);
  r.passed_read = !r.aog.empty() && splits_ok && std::ranges::all_of(r.aog, &AogRow::read_ok);
  r.passed = o.literal_verdict ? r.passed_literal : r.passed_read;
  r.cpu_s = static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC;
  r.text = ReportText(r, s.inputs, o);
  r.text_report = out / "report.txt";
  r.json_report = out / "report.json";
  WriteFile(r.text_report, r.text);
  WriteFile(r.json_report, ReportJson(r, s.inputs, o));
  return r;
}

}  // namespace autodrive::traffic::nema
