#include "traffic/nema/crosscheck.h"

#include <fmt/format.h>
#include <libsumo/libsumo.h>

#include <algorithm>
#include <fstream>
#include <optional>
#include <tuple>
#include <utility>
#include <vector>

#include <pugixml.hpp>

#include "traffic/nema/diagnosis.h"
#include "traffic/nema/internal/io.h"
#include "traffic/nema/intervals.h"
#include "traffic/nema/nema_program.h"
#include "traffic/sumo_api.h"

#include "common/aspect.h"
#include "common/error.h"
#include "common/process.h"
#include "maps/sumo.h"
#include "scm/core/controller.h"

namespace autodrive::traffic::nema {

namespace {

namespace fs = std::filesystem;
using internal::WriteFile;

constexpr Duration kDay = std::chrono::hours(24);

// Runs `f`, turning SUMO's exceptions into SumoError with `what` in front.
template <typename F>
auto Sumo(const char* what, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const libsumo::TraCIException& e) {
    throw SumoError(std::string("SUMO: ") + what + ": " + e.what());
  } catch (const libsumo::FatalTraCIError& e) {
    throw SumoError(std::string("SUMO: ") + what + ": " + e.what());
  }
}

// SUMO in this process, closed when it goes out of scope.
class Simulation {
 public:
  explicit Simulation(const std::vector<std::string>& args) {
    Sumo("starting", [&] { libsumo::Simulation::start(args); });
    running_ = true;
  }
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;
  ~Simulation() {
    try {
      Close();
    } catch (const std::exception&) {  // NOLINT(bugprone-empty-catch): closing on an error path
    }
  }
  void Close() {
    if (!running_) return;
    running_ = false;
    Sumo("closing", [] { libsumo::Simulation::close(); });
  }

 private:
  bool running_ = false;
};

// A time in SUMO's output ("12.30"), to the millisecond.
Duration SumoTime(const pugi::xml_attribute& a, const fs::path& file) {
  const std::string text = a.as_string();
  AUTODRIVE_THROW_UNLESS(!text.empty(), file.string() << ": a record without " << a.name());
  return std::chrono::round<std::chrono::milliseconds>(FromSeconds(a.as_double()));
}

PhaseSignal OfLinks(const std::string& state, const std::vector<std::size_t>& links) {
  bool green = !links.empty();
  bool yellow = false;
  for (std::size_t i : links) {
    const char c = i < state.size() ? state[i] : 'r';
    if (c != 'G' && c != 'g') green = false;
    if (c == 'y' || c == 'Y') yellow = true;
  }
  return green ? PhaseSignal::kGreen : yellow ? PhaseSignal::kYellow : PhaseSignal::kRed;
}

PhaseSignal OfGroups(const std::vector<Aspect>& aspects, const std::vector<std::size_t>& groups) {
  bool green = !groups.empty();
  bool yellow = false;
  for (std::size_t g : groups) {
    if (aspects[g] != Aspect::kGreen) green = false;
    if (aspects[g] == Aspect::kYellow) yellow = true;
  }
  return green ? PhaseSignal::kGreen : yellow ? PhaseSignal::kYellow : PhaseSignal::kRed;
}

// SUMO's letter for what a group shows.
char LinkLetter(Aspect a) {
  switch (a) {
    case Aspect::kGreen:
      return 'G';
    case Aspect::kYellow:
      return 'y';
    case Aspect::kRed:
      return 'r';
    case Aspect::kFlashingYellow:
      return 'o';
    case Aspect::kFlashingRed:
    case Aspect::kOff:
      return 'O';
  }
  return '?';
}

bool Multiple(Duration d, Duration step) { return d % step == Duration{0}; }

// The smallest `ref + k * cycle` (k any integer) at or after `t`.
Duration NextCycleStart(Duration ref, Duration cycle, Duration t) {
  Duration d = (t - ref) % cycle;
  if (d < Duration{0}) d += cycle;
  return d == Duration{0} ? t : t + (cycle - d);
}

struct SumoStates {
  std::vector<std::pair<Duration, std::string>> records;  // in time order
};

SumoStates ReadStates(const fs::path& file, const std::string& tls) {
  pugi::xml_document doc;
  const pugi::xml_parse_result r = doc.load_file(file.c_str());
  AUTODRIVE_THROW_UNLESS(r, file.string()
                                << ": cannot read SUMO's states output: " << r.description());
  SumoStates out;
  for (pugi::xml_node n : doc.child("tlsStates").children("tlsState")) {
    if (tls != n.attribute("id").as_string()) continue;
    if (std::string(kProgramId) != n.attribute("programID").as_string()) continue;
    out.records.emplace_back(SumoTime(n.attribute("time"), file), n.attribute("state").as_string());
  }
  return out;
}

struct SwitchGreen {
  std::size_t link = 0;
  Duration begin{0}, end{0};
};

std::vector<SwitchGreen> ReadSwitches(
    const fs::path& file, const std::string& tls,
    const std::map<std::pair<std::string, std::string>, std::vector<std::size_t>>& link_of) {
  pugi::xml_document doc;
  const pugi::xml_parse_result r = doc.load_file(file.c_str());
  AUTODRIVE_THROW_UNLESS(r, file.string()
                                << ": cannot read SUMO's switch times output: " << r.description());
  std::vector<SwitchGreen> out;
  for (pugi::xml_node n : doc.child("tlsSwitches").children("tlsSwitch")) {
    if (tls != n.attribute("id").as_string()) continue;
    if (std::string(kProgramId) != n.attribute("programID").as_string()) continue;
    const auto key = std::make_pair(std::string(n.attribute("fromLane").as_string()),
                                    std::string(n.attribute("toLane").as_string()));
    const auto it = link_of.find(key);
    if (it == link_of.end()) continue;
    for (std::size_t link : it->second) {
      out.push_back(
          {link, SumoTime(n.attribute("begin"), file), SumoTime(n.attribute("end"), file)});
    }
  }
  return out;
}

// Counts the steps of the window at which our link states (`ours`: time and state) differ from
// SUMO's.
void CompareLinkStates(const SumoStates& states,
                       const std::vector<std::pair<Duration, std::string>>& ours, RunFacts& f) {
  std::size_t r = 0;
  for (const auto& [t, links] : ours) {
    while (r + 1 < states.records.size() && states.records[r + 1].first <= t) ++r;
    const std::string& sumo_links = states.records[r].second;
    ++f.link_steps;
    if (sumo_links == links) continue;
    ++f.link_steps_differing;
    if (!f.first_link_difference) {
      f.first_link_difference = t;
      f.first_link_ours = links;
      f.first_link_sumo = sumo_links;
    }
  }
}

// Checks SUMO's greens in the window (from its states) against its switch times output, link by
// link.
void CheckSwitchTimes(const std::vector<Interval>& sumo, const std::vector<SwitchGreen>& switches,
                      const NemaProgram& program, const std::string& file, RunFacts& f) {
  for (const Interval& i : sumo) {
    if (i.kind != IntervalKind::kGreen || i.begin < f.from || i.begin >= f.to) continue;
    for (std::size_t link : program.Find(i.phase)->links) {
      ++f.switch_greens_checked;
      const bool found = std::ranges::any_of(switches, [&](const SwitchGreen& s) {
        return s.link == link && s.begin == i.begin && s.end == i.end;
      });
      if (found) continue;
      ++f.switch_greens_disagreeing;
      if (f.switch_disagreements.size() < 10) {
        f.switch_disagreements.push_back(
            fmt::format("phase {} green {} - {} s: link {} has no such green in {}", i.phase,
                        ToSeconds(i.begin), ToSeconds(i.end), link, file));
      }
    }
  }
}

bool OnMinRecall(const NemaProgram& program, std::uint32_t phase) {
  return std::ranges::find(program.min_recall, phase) != program.min_recall.end();
}

bool OnRecall(const NemaProgram& program, std::uint32_t phase) {
  return OnMinRecall(program, phase) ||
         std::ranges::find(program.max_recall, phase) != program.max_recall.end();
}

// The random calls of `r` for the phases of `order` with a detector, for [calls_from, to), and a
// line saying how they were drawn (`file`: where they are written).
std::pair<CallScript, std::string> DrawCalls(const RandomCalls& r, const NemaProgram& program,
                                             const std::vector<std::uint32_t>& order, Duration to,
                                             Duration step, const fs::path& file) {
  // Those on recall take no calls (min recall: refused from a script; max recall: SUMO holds
  // them to their max whatever the calls).
  std::vector<std::uint32_t> called;
  std::string list;
  for (std::uint32_t n : order) {
    if (OnRecall(program, n)) continue;
    called.push_back(n);
    list += (list.empty() ? "" : ", ") + std::to_string(n);
  }
  const RandomCallParams& p = r.params;
  CallScript calls = RandomCallScript(called, r.seed, to, step, p);
  std::string note = fmt::format(
      "random, seed {}: per phase with a detector ({}), gaps geometric on the {} s grid with mean "
      "{} s, occupancies {:.0f}% {} - {} s (passing), {:.0f}% {} - {} s (queue), for [{}, {}) s; "
      "{} calls in {}",
      r.seed, list.empty() ? "none" : list, SumoSeconds(step), SumoSeconds(p.mean_gap),
      100 * (1 - p.queue_share), SumoSeconds(p.pass_min), SumoSeconds(p.pass_max),
      100 * p.queue_share, SumoSeconds(p.queue_min), SumoSeconds(p.queue_max),
      SumoSeconds(p.calls_from), SumoSeconds(to), calls.calls.size(), file.string());
  return {std::move(calls), std::move(note)};
}

// What the diagnosis needs of the run.
DiagnosisInput DiagnosisInputOf(const NemaProgram& program, const ComparisonInput& in,
                                const CallScript& calls, Duration step) {
  DiagnosisInput d;
  d.ring = in.phases;
  for (std::size_t k = 0; k < program.rings[0].size(); ++k) {
    if (program.rings[0][k] != 0) d.barrier_side[program.rings[0][k]] = static_cast<int>(k / 2);
  }
  for (const NemaPhase& p : program.phases) {
    d.timing[p.number] = {p.min_green, p.max_green, p.passage,
                          p.yellow,    p.red_clear, OnRecall(program, p.number)};
  }
  d.calls = calls;
  d.ours = in.ours;
  d.sumo = in.sumo;
  d.step = step;
  d.tolerance = in.tolerance;
  return d;
}

}  // namespace

std::string CheckWithSumo(const scm::City& city, const fs::path& additional, const fs::path& dir) {
  const maps::SumoExport net = maps::ExportSumo(city.map, dir.string());
  std::vector<std::string> argv = {"/bin/sh",
                                   "-c",
                                   "exec \"$0\" \"$@\" 2>&1",
                                   "sumo",
                                   "-n",
                                   net.net_file.string(),
                                   "-a",
                                   fs::absolute(additional).string(),
                                   "--end",
                                   "1",
                                   "--no-step-log",
                                   "true",
                                   "--xml-validation",
                                   "never",
                                   "--xml-validation.net",
                                   "never"};
  std::string output;
  int code = -1;
  {
    ChildProcess child(argv);
    child.CloseStdin();
    while (auto line = child.ReadLine(std::chrono::minutes(1))) output += *line + "\n";
    const std::optional<int> rc = child.Wait(std::chrono::seconds(10));
    code = rc ? *rc : child.Stop();
  }
  AUTODRIVE_THROW_UNLESS(code == 0 && output.find("Error") == std::string::npos,
                         "SUMO refused " << additional.string() << " with the network "
                                         << net.net_file.string() << " (exit code " << code
                                         << "):\n"
                                         << output);
  return output;
}

CrosscheckResult RunCrosscheck(const scm::City& city, const CrosscheckOptions& options) {
  CrosscheckOptions o = options;
  AUTODRIVE_THROW_UNLESS(o.duration || o.cycles >= 1,
                         "--cycles must be at least 1, got " << o.cycles);
  AUTODRIVE_THROW_UNLESS(o.step > Duration{0}, "the step must be > 0");
  AUTODRIVE_THROW_UNLESS(o.tolerance >= Duration{0}, "the tolerance must be >= 0");
  AUTODRIVE_THROW_UNLESS(!o.out_dir.empty(), "no output folder");
  const PlanRef ref = FindPlan(city, o.intersection, o.plan);
  const scm::IntersectionModel& x = *ref.model;
  const scm::Plan& plan = x.plans[ref.plan];
  NemaProgram program = NemaProgramOf(city, ref);
  const Duration cycle = program.cycle;  // the plan's, whatever the alterations do

  RunFacts f;
  f.city = city.config.name;
  f.intersection = x.name;
  f.plan = plan.name;
  f.tls = program.tls;
  f.cycles = o.duration ? 0 : o.cycles;
  f.duration = o.duration;
  f.step = o.step;
  f.tolerance = o.tolerance;
  f.cycle = cycle;
  f.plan_offset = program.plan_offset;
  f.sumo_offset = program.offset;
  f.coordinated_phase = program.coordinate_phases[0];
  f.fixed_time = program.coordinated;
  f.our_start = o.our_start;

  for (const auto& [number, max_green] : o.sumo_max_green) {
    auto it = std::ranges::find(program.phases, number, &NemaPhase::number);
    AUTODRIVE_THROW_UNLESS(it != program.phases.end(),
                           "cannot alter phase " << number << ": the plan has no such phase");
    AUTODRIVE_THROW_UNLESS(max_green >= it->min_green,
                           "cannot alter phase " << number << "'s max green below its min green");
    f.alterations.push_back(fmt::format("SUMO's phase {} max green {} s instead of {} s", number,
                                        SumoSeconds(max_green), SumoSeconds(it->max_green)));
    program.cycle += max_green - it->max_green;
    it->max_green = max_green;
  }

  // Both controllers change state only at steps: the plan's times must fall on them.
  const auto on_step = [&](Duration d, const std::string& what) {
    AUTODRIVE_THROW_UNLESS(Multiple(d, o.step), what << " (" << ToSeconds(d)
                                                     << " s) is not a whole number of steps of "
                                                     << ToSeconds(o.step) << " s");
  };
  for (const NemaPhase& p : program.phases) {
    const std::string name = fmt::format("phase {}'s", p.number);
    on_step(p.min_green, name + " min green");
    on_step(p.max_green, name + " max green");
    on_step(p.passage, name + " passage");
    on_step(p.yellow, name + " yellow");
    on_step(p.red_clear, name + " red clearance");
  }
  on_step(program.offset, "the offset");
  on_step(o.our_start, "--our-start");
  on_step(x.startup_flash + x.startup_all_red, "the start-up flash and all red");
  if (o.duration) on_step(*o.duration, "--duration");
  if (o.random_calls) Validate(o.random_calls->params, o.step);
  for (const PhaseCall& c : o.calls.calls) {
    AUTODRIVE_THROW_UNLESS(program.Find(c.phase) != nullptr, "the call script calls phase "
                                                                 << c.phase << ", which plan "
                                                                 << plan.name << " does not have");
    // Its calls would extend SUMO's green through SUMO's detector; ours has no detector there.
    AUTODRIVE_THROW_UNLESS(!OnMinRecall(program, c.phase),
                           "the call script calls phase "
                               << c.phase << ", which is on min recall in plan " << plan.name
                               << " (its groups have no detector): SUMO's detector would take "
                                  "the call, our controller has none to take it");
  }

  // The window. A fixed-time plan: from the first cycle start at which both run the plan: ours
  // after its start-up, SUMO after its transition (it starts phase 1 at its time 0 and comes
  // into step with its offset during its first cycle, unless time 0 is a cycle start). An
  // actuated plan: from the step after ours starts (the green it starts with is not compared:
  // SUMO's began before).
  f.our_plan_start = o.our_start + x.startup_flash + x.startup_all_red;
  const Duration both = std::max(f.our_plan_start, Duration{0});
  if (program.coordinated) {
    const Duration first = NextCycleStart(program.plan_offset, cycle, Duration{0});
    const Duration sumo_in_step = first == Duration{0} ? first : first + cycle;
    f.from = NextCycleStart(program.plan_offset, cycle, std::max(both, sumo_in_step));
  } else {
    f.from = both + o.step;
  }
  if (o.duration) {
    AUTODRIVE_THROW_UNLESS(*o.duration > f.from, "--duration " << ToSeconds(*o.duration)
                                                               << " s ends before the compared "
                                                                  "window starts, at "
                                                               << ToSeconds(f.from) << " s");
    f.to = *o.duration;
  } else {
    f.to = f.from + o.cycles * cycle;
  }
  f.end = f.to + cycle;
  // Our day clock: local midnight is SUMO's time -base, a whole number of cycles before 0 (so
  // that cycle zero is SUMO's time 0 + offset) and before our start.
  Duration base{0};
  if (o.our_start < Duration{0}) {
    base = -o.our_start;
    if (cycle > Duration{0}) base = NextCycleStart(Duration{0}, cycle, base);
  }
  AUTODRIVE_THROW_UNLESS(base + f.end <= kDay,
                         "the run (" << ToSeconds(f.end) << " s) does not fit in one day of the "
                                     << "controller's clock: ask for fewer --cycles");

  fs::create_directories(o.out_dir);
  const fs::path out = fs::absolute(o.out_dir);
  const maps::SumoExport net = maps::ExportSumo(city.map, (out / "network").string());
  AUTODRIVE_CHECK(net.junctions.at(x.id) == program.tls,
                  "junction " << net.junctions.at(x.id) << " vs " << program.tls);
  const maps::Intersection& map_x = city.map.intersection(x.id);
  for (std::size_t i = 0; i < map_x.movements.size(); ++i) {
    AUTODRIVE_CHECK(net.movement(map_x.movements[i]).tls_link_index == static_cast<int>(i),
                    "movement " << map_x.movements[i].value() << " is not link " << i);
  }
  NemaOutputs outputs;
  outputs.switch_times = out / "tls_switches.xml";
  outputs.states = out / "tls_states.xml";
  const fs::path additional = out / (program.tls + ".nema.add.xml");
  WriteFile(additional, NemaAdditionalXml(program, outputs));

  // Our side: groups and links.
  std::vector<std::uint32_t> order;  // ring order
  for (std::uint32_t n : program.rings[0]) {
    if (n != 0) order.push_back(n);
  }
  std::vector<const NemaPhase*> phases;
  for (std::uint32_t n : order) {
    phases.push_back(program.Find(n));
    std::string groups;
    for (std::size_t g : phases.back()->groups) {
      groups += fmt::format("{}group {} ({})", groups.empty() ? "" : ", ", x.groups[g].id.value(),
                            x.groups[g].name);
    }
    f.phase_groups.emplace_back(n, groups);
  }
  std::vector<std::vector<std::size_t>> group_links(x.groups.size());
  for (const NemaPhase* p : phases) {
    for (std::size_t g : p->groups) {
      for (MovementId m : x.groups[g].movements) {
        group_links[g].push_back(static_cast<std::size_t>(*net.movement(m).tls_link_index));
      }
    }
  }

  if (o.random_calls) {
    std::tie(o.calls, f.calls_note) =
        DrawCalls(*o.random_calls, program, order, f.to, o.step, out / "calls.txt");
    const std::string header = fmt::format(
        "autodrive-scm-nema crosscheck: {} plan {}, city {}\n{}\nreplay: crosscheck CITY {} {} "
        "--calls calls.txt {} --our-start {} --tolerance {} --compare {}",
        x.name, plan.name, city.config.name, f.calls_note, x.name, plan.name,
        o.duration ? "--duration " + SumoSeconds(*o.duration)
                   : fmt::format("--cycles {}", o.cycles),
        SumoSeconds(o.our_start), SumoSeconds(o.tolerance), ToString(o.compare));
    WriteFile(out / "calls.txt", CallScriptText(o.calls, header));
  } else if (!o.calls.calls.empty()) {
    f.calls_note = fmt::format("a script of {} calls", o.calls.calls.size());
  } else {
    f.calls_note = "none (recalls only)";
  }

  IntervalRecorder ours_record(order);
  IntervalRecorder sumo_record(order);
  std::vector<std::pair<Duration, std::string>> ours_links;  // in the window
  std::map<std::pair<std::string, std::string>, std::vector<std::size_t>> link_of;

  Simulation sumo({"sumo", "-n", net.net_file.string(), "-a", additional.string(), "--step-length",
                   SumoSeconds(o.step), "--end", SumoSeconds(f.end + o.step), "--no-step-log",
                   "true", "--log", (out / "sumo.log").string(), "--xml-validation", "never",
                   "--xml-validation.net", "never"});
  f.sumo_version = Sumo("version", [] { return libsumo::Simulation::getVersion().second; });
  Sumo("setProgram", [&] { libsumo::TrafficLight::setProgram(program.tls, kProgramId); });
  const auto controlled = Sumo(
      "getControlledLinks", [&] { return libsumo::TrafficLight::getControlledLinks(program.tls); });
  AUTODRIVE_THROW_UNLESS(controlled.size() == program.links,
                         "SUMO's traffic light " << program.tls << " has " << controlled.size()
                                                 << " links, the intersection " << program.links
                                                 << " movements");
  for (std::size_t i = 0; i < controlled.size(); ++i) {
    for (const libsumo::TraCILink& l : controlled[i]) link_of[{l.fromLane, l.toLane}].push_back(i);
  }
  // SUMO's detectors of each phase: <tls>_NEMA_D<phase>.<k>.
  std::map<std::uint32_t, std::vector<std::string>> detectors;
  const std::string prefix = program.tls + "_" + kProgramId + "_D";
  for (const std::string& id : Sumo("detectors", [] { return libsumo::LaneArea::getIDList(); })) {
    if (id.rfind(prefix, 0) != 0) continue;
    const std::string rest = id.substr(prefix.size());
    const std::size_t dot = rest.find('.');
    if (dot == std::string::npos || dot == 0) continue;
    detectors[static_cast<std::uint32_t>(std::stoul(rest.substr(0, dot)))].push_back(id);
  }
  for (const PhaseCall& c : o.calls.calls) {
    AUTODRIVE_THROW_UNLESS(detectors.contains(c.phase), "SUMO built no detector "
                                                            << prefix << c.phase << ".* for phase "
                                                            << c.phase);
  }
  std::map<std::uint32_t, int> sumo_call;  // the override set per called phase

  const MonoTime origin = MonoTime{} + std::chrono::hours(1) - std::min(o.our_start, Duration{0});
  const auto mono = [&](Duration t) { return origin + t; };
  scm::IntersectionController ours(x, mono(o.our_start), scm::Mode::kAuto, ref.plan);
  std::vector<bool> calls(x.groups.size(), false);
  std::vector<PhaseSignal> signals(order.size());
  const auto step_ours = [&](Duration t) {
    calls.assign(x.groups.size(), false);
    for (const NemaPhase* p : phases) {
      if (!o.calls.Called(p->number, t)) continue;
      for (std::size_t g : p->groups) calls[g] = true;
    }
    ours.Step(mono(t), calls, scm::DayClock::At(base + t));
  };
  for (Duration t = o.our_start; t < Duration{0}; t += o.step) step_ours(t);
  for (Duration t{0}; t <= f.end; t += o.step) {
    for (const auto& [phase, ids] : detectors) {
      const int want = o.calls.Called(phase, t) ? 1 : -1;
      if (sumo_call[phase] == want) continue;
      sumo_call[phase] = want;
      for (const std::string& id : ids) {
        Sumo("overrideVehicleNumber", [&] { libsumo::LaneArea::overrideVehicleNumber(id, want); });
      }
    }
    Sumo("step", [] { libsumo::Simulation::step(); });
    if (t < o.our_start) continue;
    step_ours(t);
    const std::vector<Aspect>& aspects = ours.aspects();
    for (std::size_t i = 0; i < phases.size(); ++i)
      signals[i] = OfGroups(aspects, phases[i]->groups);
    ours_record.Sample(t, signals);
    if (t >= f.from && t < f.to) {
      std::string links(program.links, 'r');
      for (std::size_t g = 0; g < x.groups.size(); ++g) {
        for (std::size_t l : group_links[g]) links[l] = LinkLetter(aspects[g]);
      }
      ours_links.emplace_back(t, std::move(links));
    }
  }
  sumo.Close();  // writes SUMO's outputs

  // SUMO's side, from its states output.
  const SumoStates states = ReadStates(outputs.states, program.tls);
  AUTODRIVE_THROW_UNLESS(!states.records.empty(), outputs.states.string()
                                                      << ": SUMO wrote no state of " << program.tls
                                                      << " program " << kProgramId);
  for (const auto& [t, state] : states.records) {
    for (std::size_t i = 0; i < phases.size(); ++i) signals[i] = OfLinks(state, phases[i]->links);
    sumo_record.Sample(t, signals);
  }
  CompareLinkStates(states, ours_links, f);
  CheckSwitchTimes(sumo_record.intervals(),
                   ReadSwitches(outputs.switch_times, program.tls, link_of), program,
                   outputs.switch_times.filename().string(), f);

  ComparisonInput in;
  in.phases = order;
  in.ours = ours_record.intervals();
  in.sumo = sumo_record.intervals();
  in.from = f.from;
  in.to = f.to;
  in.tolerance = o.tolerance;
  in.cycle = cycle;
  f.files_note = fmt::format(
      "files in {}: network/ (SUMO's network), {} (the NEMA program), {} and {} (SUMO's "
      "outputs), sumo.log, {}report.txt, report.json",
      out.string(), additional.filename().string(), outputs.states.filename().string(),
      outputs.switch_times.filename().string(), o.random_calls ? "calls.txt (the calls), " : "");

  CrosscheckResult result;
  result.verdicts.mode = o.compare;
  result.verdicts.pairs = Compare(in);
  result.verdicts.sequence = CompareSequences(in);
  result.verdicts.notes =
      Diagnose(result.verdicts.sequence, DiagnosisInputOf(program, in, o.calls, o.step));
  result.facts = std::move(f);
  result.passed = Passed(result.facts, result.verdicts);
  result.text = ReportText(result.facts, result.verdicts);
  result.text_report = out / "report.txt";
  result.json_report = out / "report.json";
  WriteFile(result.text_report, result.text);
  WriteFile(result.json_report, ReportJson(result.facts, result.verdicts));
  return result;
}

}  // namespace autodrive::traffic::nema
