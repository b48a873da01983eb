// autodrive-bench-scm: figures of the SCM as real processes.
//  1. SPaT for a grid city of N x N signalised intersections (default 32 x 32 = 1024) at 10 Hz:
//     the daemon's CPU per second of wall time, and the jitter of its SPaT ticks (stamp
//     intervals against 100 ms) and of their arrival at a subscriber.
//  2. Request to reply: `intersections` and `status` from an operator client to its reply, p50
//     and p99; SPaT goes meanwhile to a subscriber in a process of its own (as to a dashboard),
//     and is measured once more with the client's own process subscribed to SPaT as well (its
//     DDS receive thread then also takes the 200 kB SPaT samples, ten a second).
//  3. Command to lamp: `advance` in manual mode to the light's `signal_<i>/state` showing yellow,
//     through autodrive-scm and autodrive-infra, p50 and p99; with the processes placed by the
//     kernel, then all on one CPU, beside this machine's own wake-up lateness after idle (the
//     floor under each hop of the chain).
//  4. A flood: 10 clients sending 200 operator requests per second each (2,000/s) while the
//     grid city runs: SPaT's rate and jitter meanwhile, and how many requests were answered,
//     refused or left unanswered.
//  5. The DDS round trip of the same run (autodrive-bench-dds-latency), for reference.
#include <fmt/format.h>
#include <poll.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <system_error>
#include <thread>

#include <CLI/CLI.hpp>

#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "common/process.h"
#include "common/time.h"
#include "maps/builder.h"
#include "maps/grid_city.h"
#include "scm/benchmarks/bench_support.h"
#include "scm/operator/client.h"

namespace {

using namespace autodrive;
using Steady = std::chrono::steady_clock;
using std::chrono::milliseconds;
namespace fs = std::filesystem;

using bench::Bin;
using bench::CpuSeconds;
using bench::Percentile;
using bench::Source;
using bench::WriteGridCity;

/// Watches SPaT: rate and jitter of the stamps and arrivals.
struct SpatWatch {
  std::vector<double> stamp_gaps_ms, arrival_gaps_ms;
  std::optional<Time> last_stamp;
  std::optional<Steady::time_point> last_arrival;
  std::size_t groups = 0;
  int messages = 0;
  void Take(dds::Reader<msg::Spat>& spat) {
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
  static std::vector<double> Jitter(const std::vector<double>& gaps) {
    std::vector<double> j;
    for (double g : gaps) j.push_back(std::abs(g - 100.0));
    return j;
  }
  void Print(double wall) const {
    std::printf("   %d SPaT messages in %.1f s (%.2f Hz), %zu signal groups each\n", messages, wall,
                messages / wall, groups);
    std::printf(
        "   tick jitter (SPaT stamp interval vs 100 ms): p50 %.2f ms, p99 %.2f ms, max %.2f ms\n",
        Percentile(Jitter(stamp_gaps_ms), 0.5), Percentile(Jitter(stamp_gaps_ms), 0.99),
        Percentile(Jitter(stamp_gaps_ms), 1.0));
    std::printf("   SPaT interval: p99 %.1f ms, max %.1f ms\n", Percentile(stamp_gaps_ms, 0.99),
                Percentile(stamp_gaps_ms, 1.0));
    std::printf("   arrival jitter at a subscriber: p50 %.2f ms, p99 %.2f ms\n",
                Percentile(Jitter(arrival_gaps_ms), 0.5),
                Percentile(Jitter(arrival_gaps_ms), 0.99));
  }
};

/// `--spat-subscriber`: takes SPaT in a process of its own until its stdin closes, then prints
/// how many messages it took.
int SpatSubscriber(const std::string& partition) {
  dds::Participant participant(dds::ParticipantOptions{{}, partition, {}});
  dds::Reader<msg::Spat> spat(participant, dds::topics::Spat().name, dds::Qos::Stream(64));
  std::size_t taken = 0;
  for (;;) {
    spat.WaitForData(milliseconds(50));
    taken += spat.TakeAll().size();
    pollfd in{STDIN_FILENO, POLLIN, 0};
    if (::poll(&in, 1, 0) > 0) {
      char buffer[64];
      if (::read(STDIN_FILENO, buffer, sizeof buffer) <= 0) break;
    }
  }
  std::printf("%zu\n", taken);
  return 0;
}

/// `intersections` and `status`, `requests` of each, 7 ms apart; p50 and p99 of request to reply.
void RequestToReply(dds::Participant& participant, const char* label, int requests) {
  scm::OperatorClient client(participant, "bench_latency", std::string("bench"));
  client.WaitForScm(std::chrono::seconds(10));
  for (const char* command : {"intersections", "status"}) {
    std::vector<double> ms;
    for (int i = 0; i < requests; ++i) {
      const auto t0 = Steady::now();
      const auto a = client.Call(command, {}, std::chrono::seconds(5));
      if (a) ms.push_back(std::chrono::duration<double, std::milli>(Steady::now() - t0).count());
      std::this_thread::sleep_for(milliseconds(7));
    }
    std::printf("   %s, %s: p50 %.2f ms, p99 %.2f ms (%zu requests)\n", command, label,
                Percentile(ms, 0.5), Percentile(ms, 0.99), ms.size());
  }
}

/// SPaT as a subscriber takes it, and the SCM's CPU, for `seconds` of wall time.
void WatchSpat(dds::Reader<msg::Spat>& spat_reader, pid_t scm_pid, double seconds) {
  SpatWatch watch;
  const double cpu0 = CpuSeconds(scm_pid);
  const auto t0 = Steady::now();
  while (Steady::now() - t0 < std::chrono::duration<double>(seconds)) {
    spat_reader.WaitForData(milliseconds(20));
    watch.Take(spat_reader);
  }
  const double wall = std::chrono::duration<double>(Steady::now() - t0).count();
  const double cpu = CpuSeconds(scm_pid) - cpu0;
  watch.Print(wall);
  std::printf("   autodrive-scm CPU: %.3f s per second of wall time (%.1f%% of one core)\n",
              cpu / wall, 100.0 * cpu / wall);
}

/// The requests the flood's clients sent, by client, and the answers that came back.
struct FloodLedger {
  std::mutex mutex;
  std::map<std::string, std::set<std::uint64_t>> sent, answered;
  std::uint64_t ok = 0, refused = 0;
};

/// One flood client: `status` and `show` requests at `rate` per second until `t0 + flood_for`.
void FloodClient(dds::Participant& participant, int c, double rate, Steady::time_point t0,
                 std::chrono::duration<double> flood_for, FloodLedger& ledger) {
  const std::string id = "flood_" + std::to_string(c);
  dds::Writer<msg::OperatorRequest> writer(participant, dds::topics::OperatorRequests());
  writer.WaitForReaders(1, std::chrono::seconds(10));
  const auto period = std::chrono::duration<double>(1.0 / rate);
  std::uint64_t k = 0;
  auto next = Steady::now();
  while (Steady::now() - t0 < flood_for) {
    dds::Message<msg::OperatorRequest> m;
    dds::SetString(m->client_id, id);
    m->request_id = ++k;
    dds::SetString(m->command, k % 2 ? "status" : "show");
    if (k % 2 == 0) {
      dds::ResizeSequence(m->arguments, 1);
      dds::SetString(dds::Elements(m->arguments)[0].key, "intersection");
      dds::SetString(dds::Elements(m->arguments)[0].value, "x_r1c1");
    }
    try {
      writer.Write(m);
      std::lock_guard lock(ledger.mutex);
      ledger.sent[id].insert(k);
    } catch (const std::exception&) {
    }
    next += std::chrono::duration_cast<Steady::duration>(period);
    std::this_thread::sleep_until(next);
  }
}

/// `clients` flood the SCM with `rate` requests/s each for `seconds`, while SPaT is watched.
void FloodBenchmark(dds::Participant& participant, dds::Reader<msg::Spat>& spat_reader,
                    pid_t scm_pid, double seconds, int clients, double rate) {
  FloodLedger ledger;
  std::atomic<bool> stop{false};
  dds::Reader<msg::OperatorReply> replies(participant, dds::topics::OperatorReplies());
  std::thread collector([&] {
    while (!stop.load()) {
      replies.WaitForData(milliseconds(20));
      for (auto& r : replies.TakeAll()) {
        const std::string client(dds::View(r->client_id));
        if (!client.starts_with("flood_")) continue;
        std::lock_guard lock(ledger.mutex);
        if (ledger.answered[client].insert(r->request_id).second) {
          (r->result == 0 ? ledger.ok : ledger.refused)++;
        }
      }
    }
  });
  std::vector<std::thread> senders;
  const auto flood_for = std::chrono::duration<double>(seconds);
  const auto t0 = Steady::now();
  for (int c = 0; c < clients; ++c) {
    senders.emplace_back([&, c] { FloodClient(participant, c, rate, t0, flood_for, ledger); });
  }
  SpatWatch watch;
  (void)spat_reader.TakeAll();
  const double cpu0 = CpuSeconds(scm_pid);
  while (Steady::now() - t0 < flood_for) {
    spat_reader.WaitForData(milliseconds(20));
    watch.Take(spat_reader);
  }
  for (auto& t : senders) t.join();
  const double wall = std::chrono::duration<double>(Steady::now() - t0).count();
  const double cpu = CpuSeconds(scm_pid) - cpu0;
  // Answers still in flight: wait for them (a moment, not a test).
  std::this_thread::sleep_for(std::chrono::seconds(3));
  stop = true;
  collector.join();
  std::size_t total = 0, missing = 0;
  for (const auto& [client, ids] : ledger.sent) {
    total += ids.size();
    for (auto id : ids) missing += ledger.answered[client].count(id) == 0 ? 1u : 0u;
  }
  std::printf(
      "   %zu requests sent (%.0f/s): %llu answered ok, %llu refused (rate limit), %zu "
      "unanswered\n",
      total, static_cast<double>(total) / wall, static_cast<unsigned long long>(ledger.ok),
      static_cast<unsigned long long>(ledger.refused), missing);
  watch.Print(wall);
  std::printf("   autodrive-scm CPU during the flood: %.1f%% of one core\n", 100.0 * cpu / wall);
}

void SpatAndFloodBenchmark(int n, double seconds, int requests, int clients, double rate,
                           const std::string& partition, const fs::path& dir) {
  std::printf("== SPaT of a %d x %d grid city (%d signalised intersections), 10 Hz\n", n, n, n * n);
  std::fflush(stdout);
  const fs::path city = WriteGridCity(n, dir);
  dds::Participant participant(dds::ParticipantOptions{{}, partition, {}});
  std::optional<dds::Reader<msg::Spat>> spat_reader;
  spat_reader.emplace(participant, dds::topics::Spat().name, dds::Qos::Stream(64));
  ChildProcess subscriber({Bin("autodrive-bench-scm"), "--spat-subscriber", partition});
  ChildProcess scm({Bin("autodrive-scm"), "--config", city.string(), "--partition", partition,
                    "--db", (dir / "grid.db").string(), "--log-level", "error"});
  if (!spat_reader->WaitForData(std::chrono::seconds(120))) {
    std::printf("   no SPaT within 120 s\n");
    return;
  }
  std::this_thread::sleep_for(std::chrono::seconds(2));  // settle (not a test: a benchmark)
  (void)spat_reader->TakeAll();
  WatchSpat(*spat_reader, scm.pid(), seconds);

  // Request to reply, with the grid city running.
  std::printf("== request -> reply: scmctl-like requests to the grid city's SCM\n");
  RequestToReply(participant, "client's process also subscribed to SPaT", requests);
  spat_reader.reset();
  RequestToReply(participant, "SPaT to another process only", requests);
  spat_reader.emplace(participant, dds::topics::Spat().name, dds::Qos::Stream(64));
  (void)spat_reader->WaitForData(std::chrono::seconds(10));

  // The flood.
  std::printf("== flood: %d clients x %.0f operator requests/s while the grid city runs\n", clients,
              rate);
  std::fflush(stdout);
  FloodBenchmark(participant, *spat_reader, scm.pid(), seconds, clients, rate);
  scm.Stop();
  subscriber.CloseStdin();
  if (auto taken = subscriber.ReadLine(milliseconds(5000))) {
    std::printf("   the separate SPaT subscriber took %s SPaT messages\n", taken->c_str());
  }
  subscriber.Stop();
}

// The calling thread runs on `cpu` only, with every thread and process it starts from then on,
// until destroyed.
class OnOneCpu {
 public:
  explicit OnOneCpu(std::optional<std::size_t> cpu) {
    if (!cpu) return;
    if (::sched_getaffinity(0, sizeof(saved_), &saved_) != 0) {
      throw std::system_error(errno, std::generic_category(), "sched_getaffinity");
    }
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(*cpu, &one);
    if (::sched_setaffinity(0, sizeof(one), &one) != 0) {
      throw std::system_error(errno, std::generic_category(), "sched_setaffinity");
    }
    pinned_ = true;
  }
  OnOneCpu(const OnOneCpu&) = delete;
  OnOneCpu& operator=(const OnOneCpu&) = delete;
  ~OnOneCpu() {
    if (pinned_) (void)::sched_setaffinity(0, sizeof(saved_), &saved_);
  }

 private:
  cpu_set_t saved_{};
  bool pinned_ = false;
};

// How long this machine takes to wake a thread blocked on a pipe, on another CPU and on the
// same CPU, when the system has been idle: the floor under every hop of a chain of processes
// that wait for each other. On bare metal either takes tens of microseconds; a virtual CPU
// that halts when idle can take milliseconds to come back.
void WakeUpFloor(int samples, Duration idle) {
  const unsigned cpus = std::thread::hardware_concurrency();
  for (const std::size_t target : {std::size_t{1}, std::size_t{0}}) {
    if (target >= cpus) continue;
    std::printf(
        "== this machine: waking a thread on CPU %zu from CPU 0 after %lld ms idle, %d samples\n",
        target, static_cast<long long>(std::chrono::duration_cast<milliseconds>(idle).count()),
        samples);
    std::fflush(stdout);
    int to[2], back[2];
    if (::pipe(to) != 0 || ::pipe(back) != 0) {
      throw std::system_error(errno, std::generic_category(), "pipe");
    }
    std::thread woken([&] {
      const OnOneCpu pinned(target);
      std::int64_t sent = 0;
      for (int i = 0; i < samples; ++i) {
        if (::read(to[0], &sent, sizeof sent) != sizeof sent) break;
        const std::int64_t took = Steady::now().time_since_epoch().count() - sent;
        if (::write(back[1], &took, sizeof took) != sizeof took) break;
      }
    });
    std::vector<double> wake_ms;
    {
      const OnOneCpu pinned(std::size_t{0});
      for (int i = 0; i < samples; ++i) {
        std::this_thread::sleep_for(idle);
        const std::int64_t now = Steady::now().time_since_epoch().count();
        std::int64_t took = 0;
        if (::write(to[1], &now, sizeof now) != sizeof now) break;
        if (::read(back[0], &took, sizeof took) != sizeof took) break;
        wake_ms.push_back(
            std::chrono::duration<double, std::milli>(Steady::duration(took)).count());
      }
    }
    ::close(to[1]);  // ends the woken thread's loop if this one ended early
    woken.join();
    for (const int fd : {to[0], back[0], back[1]}) ::close(fd);
    std::printf("   woken after: p50 %.2f ms, p99 %.2f ms, max %.2f ms\n", Percentile(wake_ms, 0.5),
                Percentile(wake_ms, 0.99), Percentile(wake_ms, 1.0));
  }
}

// `cpu`: run the SCM, the light host and this client on that CPU alone (their DDS threads
// too), so that no hop of the chain waits for another CPU to wake; otherwise the kernel places
// them.
void LampLatencyBenchmark(int samples, const std::string& partition, const fs::path& dir,
                          std::optional<std::size_t> cpu) {
  std::printf("== command to lamp feedback: advance -> signal_<i>/state, %d samples, %s\n", samples,
              cpu ? fmt::format("every process on CPU {}", *cpu).c_str()
                  : "the processes placed by the kernel");
  std::fflush(stdout);
  const OnOneCpu pinned(cpu);
  // The Driving School with short (but legal) timings, so that a phase turns over quickly.
  const fs::path src = Source();
  std::string city = config::ReadFile(src / "config/cities/driving_school.yaml");
  const std::string map_path = (src / "config/maps/driving_school.yaml").string();
  const auto replace = [](std::string& text, const std::string& from, const std::string& to) {
    const auto at = text.find(from);
    if (at == std::string::npos) throw InputError("benchmark: the shipped file has no " + from);
    text.replace(at, from.size(), to);
  };
  replace(city, "map: ../maps/driving_school.yaml", "map: " + map_path);
  replace(city, "min_yellow_s: 3.0\n  min_red_clearance_s: 1.0\n  min_green_s: 4.0",
          "min_yellow_s: 1.0\n  min_red_clearance_s: 0.5\n  min_green_s: 1.0");
  // A 0.5 s red clearance clears the box only for a car at 3 m/s: fine for a loop benchmark.
  replace(city, "{name: nigel, length_m: 0.318, speed_mps: 0.2}",
          "{name: fast, length_m: 0.318, speed_mps: 3.0}");
  replace(city, "{min_green_s: 5.0, max_green_s: 15.0, yellow_s: 3.0, red_clearance_s: 7.0}",
          "{min_green_s: 1.0, max_green_s: 15.0, yellow_s: 1.0, red_clearance_s: 0.5}");
  replace(city, "start_up: {flash_s: 3.0, all_red_s: 7.0}",
          "start_up: {flash_s: 1.0, all_red_s: 1.0}");
  { std::ofstream(dir / "fast_school.yaml") << city; }
  std::string infra = config::ReadFile(src / "config/infra/driving_school.yaml");
  replace(infra, "map: ../maps/driving_school.yaml", "map: " + map_path);
  { std::ofstream(dir / "infra.yaml") << infra; }
  ChildProcess lights({Bin("autodrive-infra"), "--config", (dir / "infra.yaml").string(),
                       "--partition", partition, "--log-level", "error"});
  ChildProcess scm({Bin("autodrive-scm"), "--config", (dir / "fast_school.yaml").string(),
                    "--partition", partition, "--db", (dir / "school.db").string(), "--log-level",
                    "error"});
  dds::Participant participant(dds::ParticipantOptions{{}, partition, {}});
  scm::OperatorClient client(participant, "bench", std::string("lab"));
  if (!client.WaitForScm(std::chrono::seconds(20))) {
    std::printf("   no SCM\n");
    return;
  }
  std::vector<std::unique_ptr<dds::Reader<msg::Int32>>> states, commands;
  for (std::uint32_t h = 1; h <= 4; ++h) {
    states.push_back(std::make_unique<dds::Reader<msg::Int32>>(
        participant, dds::topics::SignalState(SignalHeadId(h))));
    commands.push_back(std::make_unique<dds::Reader<msg::Int32>>(
        participant, dds::topics::SignalCommand(SignalHeadId(h))));
  }
  std::this_thread::sleep_for(std::chrono::seconds(4));  // through the start-up
  (void)client.Call("mode", {{"intersection", "driving_school_crossing"}, {"mode", "manual"}},
                    std::chrono::seconds(5));
  std::vector<double> lamp_ms, reply_ms, command_ms;
  int tries = 0;
  while (static_cast<int>(lamp_ms.size()) < samples && tries++ < samples * 10) {
    // Wait for a green that has served its min green (1 s) after the last clearance (1.5 s).
    std::this_thread::sleep_for(milliseconds(2700));
    for (auto& s : states) (void)s->TakeAll();
    for (auto& s : commands) (void)s->TakeAll();
    const auto t0 = Steady::now();
    const auto answer = client.Call("advance", {{"intersection", "driving_school_crossing"}},
                                    std::chrono::seconds(5));
    const auto t_reply = Steady::now();
    if (!answer || answer->code != scm::ReplyCode::kOk || answer->message != "advancing") continue;
    bool seen = false;
    std::optional<Steady::time_point> t_command;
    while (!seen && Steady::now() - t0 < std::chrono::seconds(2)) {
      for (auto& s : commands) {
        for (auto& m : s->TakeAll()) {
          if (m->data == 2 && !t_command) t_command = Steady::now();
        }
      }
      for (auto& s : states) {
        for (auto& m : s->TakeAll()) {
          if (m->data == 2) seen = true;  // yellow
        }
      }
      if (!seen) std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
    if (!seen) continue;
    lamp_ms.push_back(std::chrono::duration<double, std::milli>(Steady::now() - t0).count());
    reply_ms.push_back(std::chrono::duration<double, std::milli>(t_reply - t0).count());
    if (t_command) {
      command_ms.push_back(std::chrono::duration<double, std::milli>(*t_command - t0).count());
    }
  }
  std::printf("   request -> reply: p50 %.2f ms, p99 %.2f ms\n", Percentile(reply_ms, 0.5),
              Percentile(reply_ms, 0.99));
  std::printf("   request -> the SCM's light command seen here: p50 %.2f ms, p99 %.2f ms\n",
              Percentile(command_ms, 0.5), Percentile(command_ms, 0.99));
  std::printf("   request -> lamp state: p50 %.2f ms, p99 %.2f ms (%zu samples)\n",
              Percentile(lamp_ms, 0.5), Percentile(lamp_ms, 0.99), lamp_ms.size());
  scm.Stop();
  lights.Stop();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-bench-scm: the SCM's figures as real processes: SPaT for a grid city of N x N "
      "intersections (CPU, tick jitter), request-to-reply latency, command-to-lamp latency "
      "through autodrive-scm and autodrive-infra, and a flood of operator requests; next to the "
      "DDS round trip of the same run. Run with CYCLONEDDS_URI set to config/dds/localhost.xml."};
  int n = 32;
  double seconds = 20.0;
  int samples = 50;
  int requests = 1000;
  int clients = 10;
  double rate = 200.0;
  bool skip_lamp = false;
  bool only_lamp = false;
  std::string spat_subscriber;
  app.add_option("--grid", n, "grid city size N (N x N intersections)")->capture_default_str();
  app.add_option("--seconds", seconds, "how long to measure SPaT and the flood")
      ->capture_default_str();
  app.add_option("--requests", requests, "request-to-reply samples per command")
      ->capture_default_str();
  app.add_option("--samples", samples, "command-to-lamp samples")->capture_default_str();
  app.add_option("--clients", clients, "flood clients")->capture_default_str();
  app.add_option("--rate", rate, "requests per second per flood client")->capture_default_str();
  app.add_flag("--skip-lamp", skip_lamp, "skip the command-to-lamp measurement");
  app.add_flag("--only-lamp", only_lamp, "run only the command-to-lamp measurement")
      ->excludes("--skip-lamp");
  app.add_option("--spat-subscriber", spat_subscriber,
                 "internal: take SPaT on this partition until stdin closes")
      ->group("");
  CLI11_PARSE(app, argc, argv);
  if (!spat_subscriber.empty()) return SpatSubscriber(spat_subscriber);
  const std::string partition = "bench_scm_" + std::to_string(::getpid());
  const fs::path dir = fs::temp_directory_path() / partition;
  fs::create_directories(dir);
  try {
    if (!only_lamp) {
      SpatAndFloodBenchmark(n, seconds, requests, clients, rate, partition + "_spat", dir);
    }
    if (!skip_lamp) {
      WakeUpFloor(50, milliseconds(300));
      LampLatencyBenchmark(samples, partition + "_lamp", dir, std::nullopt);
      LampLatencyBenchmark(samples, partition + "_lamp1", dir, std::size_t{0});
    }
    if (!only_lamp) {
      std::printf("== DDS round trip in the same run (autodrive-bench-dds-latency)\n");
      std::fflush(stdout);
      ChildProcess dds({Bin("autodrive-bench-dds-latency"), "--samples", "4000", "--rounds", "4"});
      while (auto line = dds.ReadLine(milliseconds(60000))) std::printf("   %s\n", line->c_str());
      dds.Wait(milliseconds(10000));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-bench-scm: %s\n", e.what());
    fs::remove_all(dir);
    return 1;
  }
  fs::remove_all(dir);
  return 0;
}
