// autodrive-bench-scm: figures of the SCM as real processes.
//  1. SPaT for a grid city of N x N signalised intersections (default 32 x 32 = 1024) at 10 Hz:
//     the daemon's CPU per second of wall time, and the jitter of its SPaT ticks (stamp
//     intervals against 100 ms) and of their arrival at a subscriber.
//  2. Command-to-lamp latency: scmctl's request (`advance` in manual mode) to the light's
//     `signal_<i>/state` showing the new aspect, through autodrive-scm and autodrive-infra, p50
//     and p99; next to the DDS round trip of the same run (autodrive-bench-dds-latency).
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include <CLI/CLI.hpp>

#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/process.h"
#include "common/time.h"
#include "maps/builder.h"
#include "maps/grid_city.h"
#include "scm/client.h"

namespace {

using namespace autodrive;
using Steady = std::chrono::steady_clock;
using std::chrono::milliseconds;
namespace fs = std::filesystem;

double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(p * static_cast<double>(v.size() - 1) + 0.5);
  return v[std::min(i, v.size() - 1)];
}

/// utime + stime of a process, seconds.
double CpuSeconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto close = text.rfind(')');
  std::istringstream fields(text.substr(close + 2));
  std::string f;
  double ticks = 0;
  for (int i = 3; i <= 15; ++i) {
    fields >> f;
    if (i == 14 || i == 15) ticks += std::stod(f);
  }
  return ticks / static_cast<double>(::sysconf(_SC_CLK_TCK));
}

std::string Bin(const std::string& name) { return (fs::path(ExecutableDir()) / name).string(); }

void SpatBenchmark(int n, double seconds, const std::string& partition, const fs::path& dir) {
  std::printf("== SPaT of a %d x %d grid city (%d signalised intersections), 10 Hz\n", n, n, n * n);
  const maps::Layout layout = maps::GridCity(n, n, "signal");
  config::SaveFile(layout, (dir / "grid.yaml").string());
  const maps::Map map = maps::Build(layout);
  std::string city =
      "name: grid\nmap: grid.yaml\ndevices: {wait_for_lights: false}\nintersections:\n";
  for (const auto& x : map.intersections) {
    city += "  - name: " + x.name +
            "\n    groups: [{id: 1, name: e, approaches: [east]}, {id: 2, name: n, approaches: "
            "[north]}, {id: 3, name: w, approaches: [west]}, {id: 4, name: s, approaches: "
            "[south]}]\n    plans: [{name: day, phases: [{groups: [1], green_s: 8.0}, {groups: "
            "[2], green_s: 8.0}, {groups: [3], green_s: 8.0}, {groups: [4], green_s: 8.0}]}]\n";
  }
  { std::ofstream(dir / "grid_city.yaml") << city; }
  dds::Participant participant(dds::ParticipantOptions{{}, partition, {}});
  dds::Reader<msg::Spat> spat(participant, dds::topics::Spat().name, dds::Qos::Stream(64));
  ChildProcess scm({Bin("autodrive-scm"), "--config", (dir / "grid_city.yaml").string(),
                    "--partition", partition, "--db", (dir / "grid.db").string(), "--log-level",
                    "warn"});
  // Wait for the first SPaT (the SCM builds the map first), then a settling second.
  if (!spat.WaitForData(std::chrono::seconds(120))) {
    std::printf("   no SPaT within 120 s\n");
    return;
  }
  std::this_thread::sleep_for(std::chrono::seconds(1));
  (void)spat.TakeAll();
  const double cpu0 = CpuSeconds(scm.pid());
  const auto t0 = Steady::now();
  std::vector<double> stamp_gaps_ms, arrival_gaps_ms;
  std::optional<Time> last_stamp;
  std::optional<Steady::time_point> last_arrival;
  std::size_t groups = 0;
  int messages = 0;
  while (Steady::now() - t0 < std::chrono::duration<double>(seconds)) {
    spat.WaitForData(milliseconds(20));
    for (auto& m : spat.TakeAll()) {
      const auto now = Steady::now();
      const Time stamp = dds::FromMsg(m->header.stamp);
      if (last_stamp) stamp_gaps_ms.push_back(ToSeconds(stamp - *last_stamp) * 1e3);
      if (last_arrival) {
        arrival_gaps_ms.push_back(
            std::chrono::duration<double, std::milli>(now - *last_arrival).count());
      }
      last_stamp = stamp;
      last_arrival = now;
      groups = 0;
      for (const auto& x : dds::Elements(m->intersections)) groups += x.signal_groups._length;
      ++messages;
    }
  }
  const double wall = std::chrono::duration<double>(Steady::now() - t0).count();
  const double cpu = CpuSeconds(scm.pid()) - cpu0;
  scm.Stop();
  auto jitter = [](const std::vector<double>& gaps) {
    std::vector<double> j;
    for (double g : gaps) j.push_back(std::abs(g - 100.0));
    return j;
  };
  std::printf("   %d SPaT messages in %.1f s (%.2f Hz), %zu signal groups each\n", messages, wall,
              messages / wall, groups);
  std::printf("   autodrive-scm CPU: %.3f s per second of wall time (%.1f%% of one core)\n",
              cpu / wall, 100.0 * cpu / wall);
  std::printf(
      "   tick jitter (SPaT stamp interval vs 100 ms): p50 %.2f ms, p99 %.2f ms, max %.2f ms\n",
      Percentile(jitter(stamp_gaps_ms), 0.5), Percentile(jitter(stamp_gaps_ms), 0.99),
      Percentile(jitter(stamp_gaps_ms), 1.0));
  std::printf("   arrival jitter at a subscriber: p50 %.2f ms, p99 %.2f ms\n",
              Percentile(jitter(arrival_gaps_ms), 0.5), Percentile(jitter(arrival_gaps_ms), 0.99));
}

void LatencyBenchmark(int samples, const std::string& partition, const fs::path& dir) {
  std::printf("== command to lamp feedback: scmctl advance -> signal_<i>/state, %d samples\n",
              samples);
  // The Driving School at a tenth of its timings, so that a phase turns over in about a second.
  std::string city = config::internal::ReadFile(fs::path(ExecutableDir()) /
                                                "../../config/cities/driving_school.yaml");
  const std::string map_path =
      fs::canonical(fs::path(ExecutableDir()) / "../../config/maps/driving_school.yaml").string();
  city.replace(city.find("map: ../maps/driving_school.yaml"), 32, "map: " + map_path);
  city.replace(city.find("time_scale: 1.0"), 15, "time_scale: 0.1");
  { std::ofstream(dir / "fast_school.yaml") << city; }
  std::string infra = config::internal::ReadFile(fs::path(ExecutableDir()) /
                                                 "../../config/infra/driving_school.yaml");
  infra.replace(infra.find("map: ../maps/driving_school.yaml"), 32, "map: " + map_path);
  { std::ofstream(dir / "infra.yaml") << infra; }
  ChildProcess lights({Bin("autodrive-infra"), "--config", (dir / "infra.yaml").string(),
                       "--partition", partition, "--log-level", "warn"});
  ChildProcess scm({Bin("autodrive-scm"), "--config", (dir / "fast_school.yaml").string(),
                    "--partition", partition, "--db", (dir / "school.db").string(), "--log-level",
                    "warn"});
  scm::OperatorClient client(dds::ParticipantOptions{{}, partition, {}}, "bench");
  if (!client.WaitForScm(std::chrono::seconds(20))) {
    std::printf("   no SCM\n");
    return;
  }
  std::vector<std::unique_ptr<dds::Reader<msg::Int32>>> states;
  for (std::uint32_t h = 1; h <= 4; ++h) {
    states.push_back(std::make_unique<dds::Reader<msg::Int32>>(
        client.participant(), dds::topics::SignalState(SignalHeadId(h))));
  }
  std::this_thread::sleep_for(std::chrono::seconds(2));
  (void)client.Call("mode", {{"intersection", "driving_school_crossing"}, {"mode", "manual"}},
                    std::chrono::seconds(5));
  std::vector<double> lamp_ms, reply_ms;
  int tries = 0;
  while (static_cast<int>(lamp_ms.size()) < samples && tries++ < samples * 10) {
    // Wait for a green that has served its min green (0.5 s at this scale).
    std::this_thread::sleep_for(milliseconds(700));
    for (auto& s : states) (void)s->TakeAll();
    const auto t0 = Steady::now();
    const auto answer = client.Call("advance", {{"intersection", "driving_school_crossing"}},
                                    std::chrono::seconds(5));
    const auto t_reply = Steady::now();
    if (!answer || answer->result != 0 || answer->message != "advancing") continue;
    bool seen = false;
    while (!seen && Steady::now() - t0 < std::chrono::seconds(2)) {
      for (auto& s : states) {
        for (auto& m : s->TakeAll()) {
          if (m->data == 2) seen = true;  // yellow
        }
      }
      if (!seen) std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    if (!seen) continue;
    lamp_ms.push_back(std::chrono::duration<double, std::milli>(Steady::now() - t0).count());
    reply_ms.push_back(std::chrono::duration<double, std::milli>(t_reply - t0).count());
  }
  std::printf("   request -> reply: p50 %.2f ms, p99 %.2f ms\n", Percentile(reply_ms, 0.5),
              Percentile(reply_ms, 0.99));
  std::printf("   request -> lamp state: p50 %.2f ms, p99 %.2f ms (%zu samples)\n",
              Percentile(lamp_ms, 0.5), Percentile(lamp_ms, 0.99), lamp_ms.size());
  scm.Stop();
  lights.Stop();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-bench-scm: SPaT publication for a grid city of N x N intersections (CPU, tick "
      "jitter) and the command-to-lamp latency through autodrive-scm and autodrive-infra, next "
      "to the DDS round trip of the same run. Run with CYCLONEDDS_URI set to "
      "config/dds/localhost.xml."};
  int n = 32;
  double seconds = 20.0;
  int samples = 50;
  app.add_option("--grid", n, "grid city size N (N x N intersections)")->capture_default_str();
  app.add_option("--seconds", seconds, "how long to measure SPaT")->capture_default_str();
  app.add_option("--samples", samples, "command-to-lamp samples")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  const std::string partition = "bench_scm_" + std::to_string(::getpid());
  const fs::path dir = fs::temp_directory_path() / partition;
  fs::create_directories(dir);
  try {
    SpatBenchmark(n, seconds, partition + "_spat", dir);
    LatencyBenchmark(samples, partition + "_lamp", dir);
    std::printf("== DDS round trip in the same run (autodrive-bench-dds-latency)\n");
    std::fflush(stdout);
    ChildProcess dds({Bin("autodrive-bench-dds-latency"), "--samples", "4000", "--rounds", "4"});
    while (auto line = dds.ReadLine(milliseconds(60000))) std::printf("   %s\n", line->c_str());
    dds.Wait(milliseconds(10000));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-bench-scm: %s\n", e.what());
    fs::remove_all(dir);
    return 1;
  }
  fs::remove_all(dir);
  return 0;
}
