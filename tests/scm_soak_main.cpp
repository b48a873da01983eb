// autodrive-soak-scm: the SCM for a long run, as a lab would run it for weeks, compressed: a grid
// city of N x N signalised intersections (default 32 x 32) on the simulated clock at many times
// real time (default 336x: a week of simulated operation in 30 minutes), with random operator
// commands (modes, plans, advances, resets, reads, a whole configuration applied now and then)
// and random V2I requests (pre-emption, priority, refused basic vehicles). It reports, as it
// goes and at the end:
//  - the daemon's resident memory (VmRSS, and its peak VmHWM) and its database's size on disk;
//  - every SPaT checked from outside (tests/spat_checker.h, which knows only the wire): every
//    min_end promise kept (except into fail-safe flash), and no two groups of one intersection
//    green or yellow together (the grid city runs one group per phase);
//  - every operator command answered, and how the V2I requests were answered.
// Exits 1 when a safety check failed, a command went unanswered or the daemon died. A
// benchmark (it prints figures), not a test: run it by hand, e.g.
//   CYCLONEDDS_URI=file://$PWD/config/dds/localhost.xml build/bin/autodrive-soak-scm
#include <fmt/format.h>
#include <sys/types.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <map>
#include <random>
#include <thread>
#include <tuple>

#include <CLI/CLI.hpp>

#include "autodrive_msgs/msg/MapData.h"
#include "autodrive_msgs/msg/SignalRequest.h"
#include "autodrive_msgs/msg/SignalRequestStatus.h"
#include "autodrive_msgs/msg/Spat.h"
#include "rosgraph_msgs/msg/Clock.h"

#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/process.h"
#include "common/shutdown.h"
#include "common/time.h"
#include "scm/benchmarks/bench_support.h"
#include "scm/operator/client.h"
#include "scm/store/store.h"
#include "tests/spat_checker.h"

namespace {

using namespace autodrive;
using Steady = std::chrono::steady_clock;
using std::chrono::milliseconds;
using std::chrono::seconds;
namespace fs = std::filesystem;

/// Set on SIGINT or SIGTERM: the soak ends early, stops the daemon and reports.
std::atomic<bool> g_interrupted{false};

struct Options {
  int grid = 32;
  double minutes = 30.0;
  double speed = 336.0;  // simulated seconds per second of wall time
  double clock_hz = 40.0;
  double commands_per_s = 4.0;
  double v2i_per_s = 10.0;
  double apply_every_s = 300.0;
  double keep_events_days = 1.0;
  double report_every_s = 60.0;
};

/// What the operator thread saw.
struct CommandCounts {
  std::atomic<std::uint64_t> ok{0}, refused{0}, unanswered{0}, applied{0};
};

/// Random operator commands from operator "bench" until `stop`, `rate` per second.
void RunOperator(dds::Participant& participant, const std::vector<std::string>& names,
                 const std::string& city_text, const Options& o, std::atomic<bool>& stop,
                 CommandCounts& counts) {
  scm::OperatorClient client(participant, "soak/operator/" + std::to_string(::getpid()), "bench");
  if (!client.WaitForScm(seconds(60))) {
    std::fprintf(stderr, "soak: the operator found no SCM within 60 s\n");
    return;
  }
  std::mt19937 rng(7);
  const auto pick = [&](std::size_t n) {
    return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng);
  };
  const auto period = std::chrono::duration<double>(1.0 / o.commands_per_s);
  auto next = Steady::now();
  auto next_apply = Steady::now() + std::chrono::duration<double>(o.apply_every_s);
  while (!stop.load()) {
    next += std::chrono::duration_cast<Steady::duration>(period);
    std::this_thread::sleep_until(next);
    std::string command;
    std::map<std::string, std::string> args;
    const std::string x = names[pick(names.size())];
    if (o.apply_every_s > 0 && Steady::now() >= next_apply) {
      next_apply += std::chrono::duration_cast<Steady::duration>(
          std::chrono::duration<double>(o.apply_every_s));
      command = "config_apply";
      args = {{"yaml", city_text},
              {"yaml_bytes", std::to_string(city_text.size())},
              {"yaml_hash", scm::ContentHash(city_text)},
              {"path", "soak/grid_city.yaml"}};
    } else {
      // Weighted: mostly back to fixed time, so that most of the city runs its plan.
      static const std::vector<std::pair<std::string, std::string>> kCommands = {
          {"status", ""},    {"show", ""},      {"events", ""},    {"intersections", ""},
          {"mode", "fixed"}, {"mode", "fixed"}, {"mode", "fixed"}, {"mode", "manual"},
          {"mode", "flash"}, {"mode", "dark"},  {"mode", "auto"},  {"advance", ""},
          {"advance", ""},   {"plan", "day"},   {"plan", "auto"},  {"reset", ""}};
      const auto& [name, value] = kCommands[pick(kCommands.size())];
      command = name;
      if (name != "status" && name != "intersections" && name != "events") args["intersection"] = x;
      if (name == "mode") args["mode"] = value;
      if (name == "plan") args["plan"] = value;
      if (name == "events") args["limit"] = "20";
    }
    // As scmctl: 120 s for an apply (the SCM builds the whole city first), 30 s otherwise.
    const auto timeout = command == "config_apply" ? seconds(120) : seconds(30);
    std::optional<scm::OperatorAnswer> answer;
    try {
      answer = client.Call(command, args, timeout);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "soak: %s could not be sent: %s\n", command.c_str(), e.what());
    }
    if (!answer) {
      ++counts.unanswered;
      std::fprintf(stderr, "soak: no answer to %s %s within %lld s\n", command.c_str(), x.c_str(),
                   static_cast<long long>(timeout.count()));
    } else if (answer->code == scm::ReplyCode::kOk) {
      ++counts.ok;
      if (command == "config_apply") ++counts.applied;
    } else {
      ++counts.refused;
      if (command == "config_apply") {
        std::fprintf(stderr, "soak: config apply refused: %s\n", answer->message.c_str());
      }
    }
  }
}

/// A movement a vehicle may ask for: intersection, ingress lane, egress lane.
using Movement = std::tuple<std::uint32_t, std::uint32_t, std::uint32_t>;

std::vector<Movement> Movements(const msg::MapData& map) {
  std::vector<Movement> out;
  for (const auto& x : dds::Elements(map.intersections)) {
    for (const auto& lane : dds::Elements(x.lanes)) {
      for (const auto& c : dds::Elements(lane.connections)) {
        out.emplace_back(x.intersection_id, lane.lane_id, c.connecting_lane_id);
      }
    }
  }
  return out;
}

bool Moving(std::uint8_t s) {
  return test::IsGreen(s) ||
         s == autodrive_msgs_msg_SignalGroupState_Constants_PROTECTED_CLEARANCE ||
         s == autodrive_msgs_msg_SignalGroupState_Constants_PERMISSIVE_CLEARANCE;
}

double FileMb(const fs::path& p) {
  std::error_code ec;
  const auto size = fs::file_size(p, ec);
  return ec ? 0.0 : static_cast<double>(size) / 1e6;
}

int Soak(const Options& o) {
  const std::string partition = "soak_scm_" + std::to_string(::getpid());
  const fs::path dir = fs::temp_directory_path() / partition;
  fs::create_directories(dir);
  const fs::path city = bench::WriteGridCity(o.grid, dir);
  const std::string city_text = config::ReadFile(city.string());
  const fs::path db = dir / "soak.db";
  std::printf(
      "== soak: %d x %d grid city on the simulated clock at %.0fx real time for %.0f min "
      "(%.1f simulated days); %.1f operator commands/s, %.1f V2I requests/s, a config "
      "apply every %.0f s; events kept %.1f days\n",
      o.grid, o.grid, o.speed, o.minutes, o.minutes * 60 * o.speed / 86400, o.commands_per_s,
      o.v2i_per_s, o.apply_every_s, o.keep_events_days);
  std::fflush(stdout);

  dds::Participant participant(dds::ParticipantOptions{{}, partition, {}});
  dds::Writer<msg::Clock> clock(participant, dds::topics::Clock());
  dds::Reader<msg::Spat> spat(participant, dds::topics::Spat().name, dds::Qos::Stream(64));
  dds::Reader<msg::MapData> map(participant, dds::topics::Map());
  dds::Writer<msg::SignalRequest> requests(participant, dds::topics::SignalRequests());
  dds::Reader<msg::SignalRequestStatus> statuses(participant, dds::topics::SignalRequestStatus());
  ChildProcess scm({bench::Bin("autodrive-scm"), "--config", city.string(), "--partition",
                    partition, "--db", db.string(), "--clock", "sim", "--log-level", "error",
                    "--keep-events-days", fmt::format("{}", o.keep_events_days)});
  if (!clock.WaitForReaders(1, seconds(120))) {
    std::printf("   the SCM did not subscribe to /clock within 120 s\n");
    return 1;
  }
  // The simulation starts at midnight UTC of today; the clock is paced by the wall clock.
  const auto wall_now = std::chrono::system_clock::now().time_since_epoch();
  const Time sim0 = Time(std::chrono::duration_cast<Duration>(wall_now) -
                         std::chrono::duration_cast<Duration>(wall_now) % std::chrono::hours(24));
  const auto publish = [&](Time t) {
    msg::Clock m{};
    m.clock = dds::ToMsg(t);
    clock.Write(m);
  };
  // The SCM starts once it has a time: the simulator publishes /clock all along (a single
  // message could go before the SCM's reader has matched our writer).
  bool have_map = false;
  for (const auto until = Steady::now() + seconds(120); !have_map && Steady::now() < until;) {
    publish(sim0);
    have_map = map.WaitForData(milliseconds(100));
  }
  if (!have_map) {
    std::printf("   no MAP within 120 s\n");
    return 1;
  }
  const auto map_msg = map.TakeOne();
  const std::vector<Movement> movements = Movements(**map_msg);
  std::vector<std::string> names;
  for (const auto& x : dds::Elements((*map_msg)->intersections))
    names.emplace_back(dds::View(x.name));
  std::printf("   %zu intersections, %zu movements in the MAP\n", names.size(), movements.size());

  std::atomic<bool> stop{false};
  CommandCounts commands;
  std::jthread operator_thread(
      [&] { RunOperator(participant, names, city_text, o, stop, commands); });

  test::SpatChecker checker;
  std::uint64_t conflicts = 0, spat_messages = 0, v2i_sent = 0;
  std::map<std::uint8_t, std::uint64_t> v2i_answers;
  std::vector<std::string> conflict_examples;
  std::mt19937 rng(11);
  double rss_warm = 0, rss_max = 0, rss_end = 0, db_warm = 0, db_max = 0, db_end = 0;
  bool died = false;

  const auto t0 = Steady::now();
  const auto end = t0 + std::chrono::duration_cast<Steady::duration>(
                            std::chrono::duration<double>(o.minutes * 60));
  const auto clock_period = std::chrono::duration<double>(1.0 / o.clock_hz);
  const auto v2i_period = std::chrono::duration<double>(1.0 / o.v2i_per_s);
  auto next_clock = t0, next_v2i = t0, next_report = t0;
  const auto elapsed = [&] { return std::chrono::duration<double>(Steady::now() - t0).count(); };
  double cpu0 = bench::CpuSeconds(scm.pid());
  std::printf("   %8s %9s %8s %8s %8s %6s %9s %8s %6s %6s %9s %9s\n", "wall_min", "sim_days",
              "rss_MB", "hwm_MB", "db_MB", "cpu%", "spat", "changes", "viol", "confl", "cmd_ok",
              "v2i_sent");
  while (Steady::now() < end && !g_interrupted.load()) {
    const auto now = Steady::now();
    if (now >= next_clock) {
      next_clock += std::chrono::duration_cast<Steady::duration>(clock_period);
      publish(sim0 + FromSeconds(elapsed() * o.speed));
    }
    if (now >= next_v2i && !movements.empty()) {
      next_v2i += std::chrono::duration_cast<Steady::duration>(v2i_period);
      const auto& [id, in, out] =
          movements[std::uniform_int_distribution<std::size_t>(0, movements.size() - 1)(rng)];
      const int kind = std::uniform_int_distribution<int>(0, 9)(rng);
      dds::Message<msg::SignalRequest> r;
      dds::SetString(r->vehicle_id, fmt::format("soak_{}", kind * 7 % 23));
      r->request_id = static_cast<std::uint32_t>(++v2i_sent);
      r->request_type = kind < 3   ? autodrive_msgs_msg_SignalRequest_Constants_PREEMPTION
                        : kind < 7 ? autodrive_msgs_msg_SignalRequest_Constants_PRIORITY
                        : kind < 9 ? autodrive_msgs_msg_SignalRequest_Constants_PREEMPTION
                                   : autodrive_msgs_msg_SignalRequest_Constants_CANCEL;
      r->vehicle_role = kind < 3   ? autodrive_msgs_msg_SignalRequest_Constants_EMERGENCY
                        : kind < 7 ? autodrive_msgs_msg_SignalRequest_Constants_TRANSIT
                                   : autodrive_msgs_msg_SignalRequest_Constants_BASIC;
      r->intersection_id = id;
      r->in_lane_id = in;
      r->out_lane_id = out;
      r->duration.sec = 5 + kind;
      requests.Write(r);
    }
    for (auto& m : statuses.TakeAll()) ++v2i_answers[m->status];
    for (auto& m : spat.TakeAll()) {
      ++spat_messages;
      checker.Add(*m);
      for (const auto& x : dds::Elements(m->intersections)) {
        int moving = 0;
        for (const auto& g : dds::Elements(x.signal_groups))
          moving += Moving(g.event_state) ? 1 : 0;
        if (moving > 1) {
          ++conflicts;
          if (conflict_examples.size() < 10) {
            conflict_examples.push_back(
                fmt::format("{} at {:.3f}: {} groups green or yellow", dds::View(x.name),
                            ToSeconds(dds::FromMsg(m->header.stamp)), moving));
          }
        }
      }
    }
    if (now >= next_report) {
      next_report += std::chrono::duration_cast<Steady::duration>(
          std::chrono::duration<double>(o.report_every_s));
      if (auto code = scm.Wait(milliseconds(0))) {
        std::printf("   autodrive-scm exited with %d\n", *code);
        died = true;
        break;
      }
      const double rss = bench::StatusKb(scm.pid(), "VmRSS") / 1024;
      const double hwm = bench::StatusKb(scm.pid(), "VmHWM") / 1024;
      const double db_mb = FileMb(db) + FileMb(dir / "soak.db-wal");
      const double cpu = bench::CpuSeconds(scm.pid());
      const double wall_min = elapsed() / 60;
      std::printf("   %8.1f %9.2f %8.1f %8.1f %8.2f %6.1f %9llu %8zu %6zu %6llu %9llu %8llu\n",
                  wall_min, elapsed() * o.speed / 86400, rss, hwm, db_mb,
                  100.0 * (cpu - cpu0) / o.report_every_s,
                  static_cast<unsigned long long>(spat_messages), checker.changes(),
                  checker.violations().size(), static_cast<unsigned long long>(conflicts),
                  static_cast<unsigned long long>(commands.ok.load()),
                  static_cast<unsigned long long>(v2i_sent));
      std::fflush(stdout);
      cpu0 = cpu;
      if (wall_min >= 2.0 && rss_warm == 0) rss_warm = rss, db_warm = db_mb;
      rss_max = std::max(rss_max, rss);
      db_max = std::max(db_max, db_mb);
      rss_end = rss;
      db_end = db_mb;
    }
    spat.WaitForData(milliseconds(2));
  }
  stop = true;
  operator_thread.join();
  const double sim_days = elapsed() * o.speed / 86400;
  std::uint64_t monitor_violations = 0;
  if (!died) {
    scm::OperatorClient reader(participant, "soak/status/" + std::to_string(::getpid()));
    if (reader.WaitForScm(seconds(30))) {
      if (auto a = reader.Call("status", {}, seconds(30))) {
        std::printf("   the SCM's status at the end: %s\n", a->message.c_str());
        for (const auto& [k, v] : a->values) {
          std::printf("     %s: %s\n", k.c_str(), scm::ValueText(v).c_str());
        }
        if (const auto& n = a->Value("monitor_violations"); n.is_number_unsigned()) {
          monitor_violations = n.get<std::uint64_t>();
        }
      } else {
        ++commands.unanswered;
      }
    }
    const int code = scm.Stop(milliseconds(10000));
    if (code != 0) {
      std::printf("   autodrive-scm stopped with exit code %d\n", code);
      died = true;
    }
  }
  std::printf("== soak result: %.1f simulated days in %.1f min\n", sim_days, elapsed() / 60);
  std::printf("   resident memory: %.1f MB after 2 min, %.1f MB at most, %.1f MB at the end\n",
              rss_warm, rss_max, rss_end);
  std::printf(
      "   database (with its WAL): %.2f MB after 2 min, %.2f MB at most, %.2f MB at the end\n",
      db_warm, db_max, db_end);
  std::printf(
      "   SPaT: %llu messages checked, %zu state changes, %zu min_end violations, %llu "
      "conflicts; the SCM's own monitor: %llu violations\n",
      static_cast<unsigned long long>(spat_messages), checker.changes(),
      checker.violations().size(), static_cast<unsigned long long>(conflicts),
      static_cast<unsigned long long>(monitor_violations));
  for (std::size_t i = 0; i < std::min<std::size_t>(10, checker.violations().size()); ++i) {
    std::printf("     %s\n", checker.violations()[i].c_str());
  }
  for (const auto& c : conflict_examples) std::printf("     %s\n", c.c_str());
  std::printf(
      "   operator commands: %llu ok, %llu refused, %llu unanswered (%llu configurations "
      "applied)\n",
      static_cast<unsigned long long>(commands.ok.load()),
      static_cast<unsigned long long>(commands.refused.load()),
      static_cast<unsigned long long>(commands.unanswered.load()),
      static_cast<unsigned long long>(commands.applied.load()));
  std::printf(
      "   V2I: %llu requests sent; answers: granted %llu, rejected %llu, completed %llu, "
      "cancelled %llu, other %llu\n",
      static_cast<unsigned long long>(v2i_sent),
      static_cast<unsigned long long>(
          v2i_answers[autodrive_msgs_msg_SignalRequestStatus_Constants_GRANTED]),
      static_cast<unsigned long long>(
          v2i_answers[autodrive_msgs_msg_SignalRequestStatus_Constants_REJECTED]),
      static_cast<unsigned long long>(
          v2i_answers[autodrive_msgs_msg_SignalRequestStatus_Constants_COMPLETED]),
      static_cast<unsigned long long>(
          v2i_answers[autodrive_msgs_msg_SignalRequestStatus_Constants_CANCELLED]),
      static_cast<unsigned long long>(
          v2i_answers[autodrive_msgs_msg_SignalRequestStatus_Constants_RECEIVED] +
          v2i_answers[autodrive_msgs_msg_SignalRequestStatus_Constants_PROCESSING]));
  std::fflush(stdout);
  const bool failed = died || !checker.violations().empty() || conflicts > 0 ||
                      monitor_violations > 0 || commands.unanswered.load() > 0;
  std::error_code ec;
  fs::remove_all(dir, ec);
  return failed ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-soak-scm: runs autodrive-scm with a grid city of N x N intersections on the "
      "simulated clock at many times real time, with random operator commands and V2I "
      "requests; reports its resident memory and database size as it goes, checks every SPaT "
      "from outside (min_end promises, conflicting greens) and every command's answer. Exits 1 "
      "when a check failed. Run with CYCLONEDDS_URI set to config/dds/localhost.xml."};
  Options o;
  app.add_option("--grid", o.grid, "grid city size N (N x N intersections)")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  app.add_option("--minutes", o.minutes, "wall-clock minutes to run")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--speed", o.speed, "simulated seconds per second of wall time")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--clock-hz", o.clock_hz, "/clock messages per second of wall time")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 1000.0));
  app.add_option("--commands", o.commands_per_s, "operator commands per second of wall time")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--v2i", o.v2i_per_s, "V2I requests per second of wall time")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--apply-every", o.apply_every_s,
                 "seconds of wall time between two applies of the city's configuration (0: never)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--keep-events-days", o.keep_events_days,
                 "the SCM's event retention, simulated days")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--report-every", o.report_every_s, "seconds of wall time between two reports")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);
  autodrive::ShutdownSignals signals([](int) { g_interrupted = true; });
  try {
    return Soak(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-soak-scm: %s\n", e.what());
    return 1;
  }
}
