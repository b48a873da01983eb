// autodrive-bench-traffic: the co-simulation's real-time factor on one core with N SUMO cars on
// an n x n grid city (with the SCM running its intersections in another process), and its
// overhead over libsumo alone stepping the same network and demand.
#include <fmt/format.h>
#include <libsumo/libsumo.h>
#include <spdlog/spdlog.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include <CLI/CLI.hpp>

#include "traffic/cosim.h"
#include "traffic/lamp_inbox.h"
#include "traffic/lights.h"
#include "traffic/service.h"
#include "traffic/standalone.h"

#include "common/cpu_time.h"
#include "common/dds/participant.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "common/logging.h"
#include "common/process.h"
#include "maps/sumo.h"
#include "scm/benchmarks/bench_support.h"
#include "scm/core/city.h"

namespace {

using namespace autodrive;
using namespace autodrive::traffic;

// The lamps of SUMO's own stand-in program (maps::SumoOptions: per intersection each approach
// in turn green 12 s, yellow 3 s, all red 2 s), so that the co-simulation and libsumo alone run
// the same signal timing.
int GridLamp(const maps::Map& map, SignalHeadId h, double t) {
  const maps::SignalHead& head = map.signal_head(h);
  const maps::Intersection& x = map.intersection(head.intersection);
  static const maps::SumoOptions kProgram;
  const double green = ToSeconds(kProgram.green), yellow = ToSeconds(kProgram.yellow);
  const double phase = green + yellow + ToSeconds(kProgram.all_red);
  const double in_cycle = std::fmod(t, phase * static_cast<double>(x.approaches.size()));
  const auto k = static_cast<std::size_t>(in_cycle / phase);
  if (x.approaches[k].id != head.approach) return 1;
  const double in_phase = in_cycle - phase * static_cast<double>(k);
  return in_phase < green ? 3 : in_phase < green + yellow ? 2 : 1;
}

// What taking the lights' changes costs when the lights run in another process, as
// `autodrive-infra` does beside `autodrive-traffic`: Cyclone's receive thread takes each
// change off the socket, acknowledges it (the topic is reliable) and hands it to the
// LampInbox; that is this process's CPU, which the in-thread figure below ("lamps in", the
// lights writing in this process) does not see. A forked child writes the grid's changes
// step by step, `pace` apart (about the co-simulation's step at 100 cars); this process
// only receives (it blocks meanwhile, so its whole CPU time is the receiving).
// Call before this process makes any DDS participant (it forks).
struct LampReceipt {
  std::uint64_t lamps = 0;
  int steps = 0;
  double cpu_s = 0;
};

double ProcessCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

LampReceipt MeasureLampReceipt(const scm::City& city, const std::string& partition, int steps,
                               std::chrono::microseconds pace) {
  const std::vector<SignalHeadId> heads = LightBinding(city).heads();
  int ready[2], go[2];
  AUTODRIVE_THROW_UNLESS(::pipe(ready) == 0 && ::pipe(go) == 0, "pipe failed");
  const pid_t child = ::fork();
  AUTODRIVE_THROW_UNLESS(child >= 0, "fork failed");
  if (child == 0) {
    ::close(ready[0]);
    ::close(go[1]);
    int code = 1;
    try {
      dds::Participant p(dds::ParticipantOptions{{}, partition, {}});
      std::vector<std::unique_ptr<dds::Writer<msg::Int32>>> lights;
      for (const SignalHeadId h : heads) {
        lights.push_back(std::make_unique<dds::Writer<msg::Int32>>(p, dds::topics::SignalState(h)));
      }
      bool matched = true;
      for (const auto& w : lights)
        matched = matched && w->WaitForReaders(1, std::chrono::seconds(120));
      std::vector<int> shown(heads.size(), -1);
      const auto write_step = [&](int k) {
        for (std::size_t i = 0; i < heads.size(); ++i) {
          const int lamp = GridLamp(city.map, heads[i], 0.05 * k);
          if (lamp == shown[i]) continue;
          dds::Message<msg::Int32> m;
          m->data = lamp;
          lights[i]->Write(m);
          shown[i] = lamp;
        }
      };
      write_step(0);  // every head's first report: not measured
      for (const auto& w : lights) matched = matched && w->WaitForAcks(std::chrono::seconds(120));
      char c = matched ? 'r' : 'x';
      if (::write(ready[1], &c, 1) == 1 && matched && ::read(go[0], &c, 1) == 1) {
        auto next = std::chrono::steady_clock::now();
        for (int k = 1; k <= steps; ++k) {
          write_step(k);
          next += pace;
          std::this_thread::sleep_until(next);
        }
        for (const auto& w : lights) (void)w->WaitForAcks(std::chrono::seconds(120));
        code = 0;
      }
    } catch (...) {
    }
    std::_Exit(code);
  }
  ::close(ready[1]);
  ::close(go[0]);
  LampReceipt r;
  {
    dds::Participant p(dds::ParticipantOptions{{}, partition, {}});
    LampInbox inbox(p, heads);
    char c = 0;
    const bool ok = ::read(ready[0], &c, 1) == 1 && c == 'r';
    // Every head's first report is acknowledged; wait until each is taken too (an
    // acknowledgement may go out before the delivery), so that none counts as measured.
    for (const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(60);
         ok && inbox.received() < heads.size() && std::chrono::steady_clock::now() < end;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    const std::uint64_t first = inbox.received();
    const double cpu0 = ProcessCpuSeconds();
    int status = 0;
    if (ok && ::write(go[1], &c, 1) == 1) ::waitpid(child, &status, 0);
    r.cpu_s = ProcessCpuSeconds() - cpu0;
    if (!ok) {
      ::kill(child, SIGKILL);
      ::waitpid(child, &status, 0);
    }
    AUTODRIVE_THROW_UNLESS(ok && WIFEXITED(status) && WEXITSTATUS(status) == 0,
                           "the lights' process failed");
    r.lamps = inbox.received() - first;
    r.steps = steps;
  }
  ::close(ready[0]);
  ::close(go[1]);
  return r;
}

struct Result {
  int vehicles = 0;
  double cosim_cpu_s = 0, alone_cpu_s = 0, simulated_s = 0;
  // Where the co-simulation's CPU time went: lamps in, SUMO's own step, the rest of the step
  // (lights to SUMO, vehicles read back, all-way stops, routes), TrafficObjects out.
  double lamps_cpu_s = 0, sumo_cpu_s = 0, step_cpu_s = 0, publish_cpu_s = 0;
  std::int64_t collisions = 0, teleports = 0, lost = 0;
  std::int64_t late_lamps = 0;  // steps whose lamps reached the inbox only after a wait
};

// The lamps-in part of a co-simulation step: the lights' plan written on DDS (a writer per
// head, reporting changes as `autodrive-infra` does) and taken as `autodrive-traffic` takes them
// (LampInbox).
class BenchLights {
 public:
  BenchLights(const dds::Participant& participant, const std::vector<SignalHeadId>& heads)
      : heads_(heads), inbox_(participant, heads), lamps_(heads.size()), shown_(heads.size(), -1) {
    for (const SignalHeadId h : heads) {
      writers_.push_back(
          std::make_unique<dds::Writer<msg::Int32>>(participant, dds::topics::SignalState(h)));
    }
  }
  // The lights' plan at `t` (the bench's, not the co-simulation's: not counted).
  void Plan(const maps::Map& map, double t) {
    for (std::size_t i = 0; i < lamps_.size(); ++i) lamps_[i] = GridLamp(map, heads_[i], t);
  }
  // Lamps in: the changed heads' reports written, delivered (in this process Cyclone delivers
  // them to the inbox on this thread) and taken, and handed to SUMO's lights. Writing is the
  // lights' work in a real city: counting it here errs on the safe side. Returns the CPU time
  // spent waiting for a delivery (not the co-simulation's).
  double In(CoSimulation& sim, MonoTime now, Result& r) {
    for (std::size_t i = 0; i < lamps_.size(); ++i) {
      if (lamps_[i] == shown_[i]) continue;
      dds::Message<msg::Int32> lamp;
      lamp->data = lamps_[i];
      writers_[i]->Write(lamp);
      shown_[i] = lamps_[i];
      ++written_;
    }
    const double c_written = ThreadCpuSeconds();
    // Should delivery ever be asynchronous, the step waits for it (not counted).
    if (inbox_.received() < written_) ++r.late_lamps;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (inbox_.received() < written_ && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
    const double c_delivered = ThreadCpuSeconds();
    inbox_.Take(taken_);
    for (const LampInbox::Lamp& l : taken_) sim.ReportLamp(l.head, l.lamp, now);
    return c_delivered - c_written;
  }

 private:
  const std::vector<SignalHeadId>& heads_;
  LampInbox inbox_;
  std::vector<std::unique_ptr<dds::Writer<msg::Int32>>> writers_;
  std::vector<int> lamps_, shown_;
  std::vector<LampInbox::Lamp> taken_;
  std::uint64_t written_ = 0;
};

// The co-simulation's part of a run: `warmup` s, then `seconds` s measured. Fills `lane_names`
// with the map's names of SUMO's lanes (for libsumo alone's objects).
Result RunCoSimulation(const scm::City& city, const TrafficConfig& config, double warmup,
                       double seconds, const std::filesystem::path& dir,
                       const dds::Participant& participant,
                       std::unordered_map<std::string, std::string>& lane_names) {
  Result r;
  CoSimulation sim(city, config,
                   CoSimulation::Options{dir / fmt::format("cosim_{}", config.vehicles),
                                         nullptr,
                                         true,
                                         {},
                                         std::chrono::seconds(5)});
  dds::Writer<msg::TrafficObjects> writer(participant, dds::topics::Traffic());
  std::vector<msg::TrafficObject> buffer;
  msg::TrafficObjects m{};
  BenchLights lights(participant, sim.lights().heads());
  const auto step = [&](double t) {
    lights.Plan(city.map, t);
    const double c0 = ThreadCpuSeconds();
    const MonoTime now = MonoTime{} + FromSeconds(t);
    r.lamps_cpu_s -= lights.In(sim, now, r);
    const double c1 = ThreadCpuSeconds();
    sim.Step({}, now);
    const double c2 = ThreadCpuSeconds();
    FillTrafficObjects(sim.vehicles(), Time{} + FromSeconds(sim.time_s()), buffer, m);
    writer.Write(m);
    const double c3 = ThreadCpuSeconds();
    r.lamps_cpu_s += c1 - c0;
    r.step_cpu_s += c2 - c1;
    r.publish_cpu_s += c3 - c2;
  };
  while (sim.time_s() < warmup) step(sim.time_s());
  r = Result{};
  r.vehicles = static_cast<int>(sim.vehicles().size());
  const double sumo0 = sim.stats().sumo_step_cpu_s;
  const double s0 = sim.time_s();
  while (sim.time_s() < warmup + seconds - 1e-9) step(sim.time_s());
  r.cosim_cpu_s = r.lamps_cpu_s + r.step_cpu_s + r.publish_cpu_s;
  r.sumo_cpu_s = sim.stats().sumo_step_cpu_s - sumo0;
  r.step_cpu_s -= r.sumo_cpu_s;
  r.simulated_s = sim.time_s() - s0;
  for (const std::string& lane : libsumo::Lane::getIDList()) {
    lane_names.emplace(lane, sim.network().MapName(lane));
  }
  r.collisions = sim.stats().collisions;
  r.teleports = sim.stats().teleports;
  r.lost = sim.stats().arrived_unplanned;
  return r;
}

// libsumo alone on the same network and demand (SUMO's fixed programs instead of lamps): the
// CPU time of its `seconds` s of steps after `warmup`.
double RunAlone(const scm::City& city, const TrafficConfig& config, double warmup, double seconds,
                const std::filesystem::path& dir, const dds::Participant& participant,
                const std::unordered_map<std::string, std::string>& lane_names) {
  double alone_cpu_s = 0;
  const StandaloneFiles f =
      ExportStandalone(city, config, dir / fmt::format("alone_{}", config.vehicles),
                       FromSeconds(warmup + seconds + 60));
  libsumo::Simulation::start({"sumo", "-c", f.config_file.string(), "--step-length", "0.05",
                              "--no-step-log", "true", "--no-warnings", "true"});
  while (libsumo::Simulation::getTime() < warmup) libsumo::Simulation::step();
  // SUMO's steps alone are timed; between them its vehicles go out as TrafficObjects (not
  // timed), so that the SCM beside it has the same work as in the co-simulation: the SCM's
  // load slows this thread too (a shared cache, a shared host), by 10 to 30% on the
  // development VM, and the comparison should not count it as the co-simulation's.
  dds::Writer<msg::TrafficObjects> writer(participant, dds::topics::Traffic());
  std::vector<TrafficVehicle> vehicles;
  std::vector<msg::TrafficObject> buffer;
  msg::TrafficObjects m{};
  const double scale = maps::SumoOptions{}.scale;
  while (libsumo::Simulation::getTime() < warmup + seconds - 1e-9) {
    const double t0 = ThreadCpuSeconds();
    libsumo::Simulation::step();
    alone_cpu_s += ThreadCpuSeconds() - t0;
    vehicles.clear();
    for (const std::string& id : libsumo::Vehicle::getIDList()) {
      TrafficVehicle& v = vehicles.emplace_back();
      v.id = id;
      // As CoSimulation reads its cars: SUMO gives the front bumper; the object is the body.
      const libsumo::TraCIPosition p = libsumo::Vehicle::getPosition(id);
      v.yaw_rad = YawFromSumoAngle(libsumo::Vehicle::getAngle(id));
      const double length = libsumo::Vehicle::getLength(id);
      const Eigen::Vector2d heading(std::cos(v.yaw_rad), std::sin(v.yaw_rad));
      v.centre = (Eigen::Vector2d(p.x, p.y) - heading * (length / 2)) / scale;
      v.length_m = length / scale;
      v.width_m = libsumo::Vehicle::getWidth(id) / scale;
      v.speed_mps = libsumo::Vehicle::getSpeed(id) / scale;
      const auto name = lane_names.find(libsumo::Vehicle::getLaneID(id));
      if (name != lane_names.end()) v.map_lane = name->second;
    }
    FillTrafficObjects(vehicles, Time{} + FromSeconds(libsumo::Simulation::getTime()), buffer, m);
    writer.Write(m);
  }
  libsumo::Simulation::close();
  return alone_cpu_s;
}

Result Run(const scm::City& city, int cars, double seconds, const std::filesystem::path& dir,
           const dds::Participant& participant) {
  TrafficConfig config;
  config.vehicles = cars;
  const double warmup = 10.0;
  std::unordered_map<std::string, std::string> lane_names;
  Result r = RunCoSimulation(city, config, warmup, seconds, dir, participant, lane_names);
  r.alone_cpu_s = RunAlone(city, config, warmup, seconds, dir, participant, lane_names);
  return r;
}

// The figures of one size: the median of `runs`, printed.
void Report(int n, const std::vector<Result>& runs, const std::optional<LampReceipt>& receipt,
            std::optional<double> scm_cpu_per_run) {
  const auto median = [&](double Result::*field) {
    std::vector<double> v;
    for (const Result& r : runs) v.push_back(r.*field);
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  Result r = runs.front();
  for (double Result::*f : {&Result::cosim_cpu_s, &Result::alone_cpu_s, &Result::lamps_cpu_s,
                            &Result::sumo_cpu_s, &Result::step_cpu_s, &Result::publish_cpu_s}) {
    r.*f = median(f);
  }
  for (const Result& x : runs) {
    r.collisions = std::max(r.collisions, x.collisions);
    r.teleports = std::max(r.teleports, x.teleports);
    r.lost = std::max(r.lost, x.lost);
    r.late_lamps = std::max(r.late_lamps, x.late_lamps);
  }
  std::printf("%8d %9.2fx %11.2fx %11.2fx %10.2f %lld/%lld/%lld%s\n", r.vehicles,
              r.simulated_s / r.cosim_cpu_s, r.simulated_s / r.alone_cpu_s,
              r.cosim_cpu_s / r.alone_cpu_s, 1000 * r.cosim_cpu_s / (r.simulated_s / 0.05),
              static_cast<long long>(r.collisions), static_cast<long long>(r.teleports),
              static_cast<long long>(r.lost),
              r.vehicles < n ? fmt::format(" (room for {} of {})", r.vehicles, n).c_str() : "");
  const double steps = r.simulated_s / 0.05;
  std::printf(
      "         per step: lamps in %.3f ms, SUMO's step %.3f ms (alone %.3f ms), co-sim "
      "%.3f ms, TrafficObjects out %.3f ms; all of it over SUMO's own step: %.2fx\n",
      1000 * r.lamps_cpu_s / steps, 1000 * r.sumo_cpu_s / steps, 1000 * r.alone_cpu_s / steps,
      1000 * r.step_cpu_s / steps, 1000 * r.publish_cpu_s / steps, r.cosim_cpu_s / r.sumo_cpu_s);
  if (receipt) {
    // The lamps as received from another process in place of the in-process figure.
    const double received_s = receipt->cpu_s / receipt->steps * steps;
    std::printf(
        "         with the lamps received from another process instead (%.3f ms a step): "
        "overhead %.2fx\n",
        1000 * received_s / steps, (r.cosim_cpu_s - r.lamps_cpu_s + received_s) / r.alone_cpu_s);
  }
  if (r.late_lamps > 0) {
    std::printf(
        "         (in %lld steps the lamps reached the inbox on another thread: its CPU is "
        "not counted)\n",
        static_cast<long long>(r.late_lamps));
  }
  if (scm_cpu_per_run) {
    std::printf("         (the SCM used %.2f s of CPU per run meanwhile)\n", *scm_cpu_per_run);
  }
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-bench-traffic: the SUMO co-simulation on one core: real-time factor with N "
      "SUMO cars on an n x n grid city (each step: lamps to SUMO's lights, SUMO's step, the cars "
      "read back and published as TrafficObjects on DDS), with the SCM running the city's "
      "intersections in its own process, and the overhead over libsumo alone on the same "
      "network and demand; first, what receiving the lights' changes from another process costs "
      "(as autodrive-traffic receives them from autodrive-infra). Goals: >= 1,000 cars at >= 1x "
      "real time, overhead <= 1.5x."};
  std::vector<int> cars{100, 1000, 5000};
  int grid = 32;
  double seconds = 60;
  bool with_scm = true;
  int repeat = 3;
  app.add_option("--cars", cars, "SUMO cars (repeat or comma-separate)")->delimiter(',');
  app.add_option("--grid", grid, "intersections per side")->check(CLI::Range(2, 64));
  app.add_option("--seconds", seconds, "simulated seconds measured (after 10 s of warm-up)")
      ->check(CLI::Range(1.0, 3600.0));
  app.add_flag("!--no-scm", with_scm, "do not run the SCM beside it");
  app.add_option("--repeat", repeat, "runs per size (each figure is their median)")
      ->check(CLI::Range(1, 99));
  int lamp_steps = 4000;
  app.add_option("--lamp-steps", lamp_steps,
                 "steps of the lights' changes received from another process, to measure what "
                 "receiving them costs (0: skip)")
      ->check(CLI::Range(0, 1000000));
  CLI11_PARSE(app, argc, argv);
  InitLogging("autodrive-bench-traffic", spdlog::level::warn);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    fmt::format("autodrive_bench_traffic_{}", ::getpid());
  std::filesystem::create_directories(dir);
  const std::filesystem::path city_file = bench::WriteGridCity(grid, dir);
  std::printf("building the %d x %d grid city...\n", grid, grid);
  std::fflush(stdout);
  const scm::City city = scm::LoadCity(city_file);
  const std::string partition = fmt::format("bench_traffic_{}", ::getpid());
  // Before any participant of this process (it forks).
  std::optional<LampReceipt> receipt;
  if (lamp_steps > 0) {
    std::printf("receiving the lights' changes from another process (%d steps)...\n", lamp_steps);
    std::fflush(stdout);
    receipt =
        MeasureLampReceipt(city, partition + "_lamps", lamp_steps, std::chrono::microseconds(500));
    std::printf(
        "lights' changes received from another process (as autodrive-traffic receives them "
        "from autodrive-infra), %d steps 0.5 ms apart: %llu changes, %.2f us of this process's "
        "CPU each, %.3f ms per step\n",
        receipt->steps, static_cast<unsigned long long>(receipt->lamps),
        1e6 * receipt->cpu_s / static_cast<double>(std::max<std::uint64_t>(receipt->lamps, 1)),
        1e3 * receipt->cpu_s / receipt->steps);
    std::fflush(stdout);
  }
  std::unique_ptr<ChildProcess> scm;
  if (with_scm) {
    scm = std::make_unique<ChildProcess>(std::vector<std::string>{
        bench::Bin("autodrive-scm"), "--config", city_file.string(), "--db",
        (dir / "scm.db").string(), "--partition", partition, "--log-level", "warn"});
  }
  dds::Participant participant(dds::ParticipantOptions{{}, partition, {}});
  std::printf("grid %dx%d (%zu intersections, %zu lanes), %.0f simulated s per run, SCM %s\n", grid,
              grid, city.map.intersections.size(), city.map.lanes.size(), seconds,
              with_scm ? "running" : "not running");
  std::printf("%8s %10s %12s %12s %10s %s\n", "cars", "co-sim RTF", "libsumo RTF", "overhead",
              "ms/step", "collisions/teleports/lost");
  std::fflush(stdout);
  for (const int n : cars) {
    // The machine's noise (a shared VM) moves CPU times by tens of percent from run to run:
    // each figure is the median of `repeat` runs, the co-simulation and libsumo alone in turn.
    std::vector<Result> runs;
    const double scm_cpu0 = scm ? bench::CpuSeconds(scm->pid()) : 0.0;
    for (int k = 0; k < repeat; ++k) runs.push_back(Run(city, n, seconds, dir, participant));
    const double scm_cpu = scm ? bench::CpuSeconds(scm->pid()) - scm_cpu0 : 0.0;
    Report(n, runs, receipt,
           scm ? std::optional<double>(scm_cpu / repeat) : std::optional<double>());
  }
  if (scm) scm->Stop();
  std::filesystem::remove_all(dir);
  return 0;
}
