#include "city/launcher/supervisor.h"

#include <fmt/chrono.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <deque>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>
#include <thread>

#include <nlohmann/json.hpp>

#include "city/launcher/process_table.h"

#include "common/dds/messages.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/process.h"

namespace autodrive::launcher {
namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

std::string Iso(std::chrono::system_clock::time_point t) {
  return fmt::format("{:%Y-%m-%dT%H:%M:%S}Z", std::chrono::floor<std::chrono::seconds>(t));
}

constexpr std::string_view kStartMark = "==== autodrive-city: starting ";

// The last lines of a log since the process's last start, to say why it failed (the log holds
// the earlier runs too).
std::string Tail(const std::filesystem::path& log, std::size_t lines) {
  std::ifstream in(log);
  std::deque<std::string> last;
  for (std::string line; std::getline(in, line);) {
    if (line.starts_with(kStartMark)) last.clear();
    last.push_back(line);
    if (last.size() > lines) last.pop_front();
  }
  std::string out;
  for (const std::string& l : last) out += "    " + l + "\n";
  return out;
}

}  // namespace

const char* PhaseName(Phase phase) {
  switch (phase) {
    case Phase::kWaiting:
      return "waiting";
    case Phase::kStarting:
      return "starting";
    case Phase::kRunning:
      return "running";
    case Phase::kExited:
      return "exited";
    case Phase::kCrashLoop:
      return "crash-loop";
    case Phase::kStopped:
      return "stopped";
  }
  return "?";
}

struct Supervisor::Impl {
  struct Process {
    const ProcessPlan* plan = nullptr;
    std::optional<ChildProcess> child;
    ProcessState state;
    std::deque<Clock::time_point> exits;  // within the crash-loop window
    Clock::time_point start_at{};         // when to start it again
  };

  // What the launcher hears and says on one DDS domain: its own, or a district's.
  struct Domain {
    std::optional<std::uint32_t> district;         // unset: the launcher's own domain
    dds::Reader<msg::Heartbeat> scm_heartbeats;    // the SCM's (sender "scm")
    dds::Reader<msg::Heartbeat> infra_heartbeats;  // the device hosts' (sender "infra/<name>")
    ProcessTableWriter table;  // the processes for the SCM (/autodrive/scm/processes)

    Domain(const dds::Participant& participant, std::optional<std::uint32_t> id,
           const LaunchPlan& plan)
        : district(id),
          scm_heartbeats(participant, dds::topics::Heartbeat()),
          infra_heartbeats(participant, dds::topics::InfraHeartbeat()),
          table(participant, plan.city_name, plan.host) {}
  };

  LaunchPlan plan;
  std::function<void(const std::string&)> say;
  std::vector<std::unique_ptr<Domain>> domains;  // the launcher's own first
  dds::Reader<msg::Clock> clock;
  dds::Reader<msg::TrafficObjects> traffic;
  LauncherState launcher_state = LauncherState::kStarting;
  mutable std::mutex mutex;  // guards the states
  std::vector<Process> processes;
  // "domain|sender|city" of heartbeats since the last drain (domain: empty for the launcher's)
  std::set<std::string> heard;
  bool heard_clock = false, heard_traffic = false;

  Impl(LaunchPlan p, const dds::Participant& participant,
       const std::vector<const dds::Participant*>& districts,
       std::function<void(const std::string&)> s)
      : plan(std::move(p)),
        say(std::move(s)),
        clock(participant, dds::topics::Clock()),
        traffic(participant, dds::topics::Traffic()) {
    domains.push_back(std::make_unique<Domain>(participant, std::nullopt, plan));
    for (const dds::Participant* d : districts) {
      domains.push_back(std::make_unique<Domain>(*d, d->domain_id(), plan));
    }
    for (const ProcessPlan& pp : plan.processes) {
      if (pp.ready.domain && std::ranges::none_of(domains, [&](const auto& d) {
            return d->district == pp.ready.domain;
          })) {
        throw LaunchError(
            fmt::format("{} is ready on DDS domain {}, which the launcher has not "
                        "joined",
                        pp.name, *pp.ready.domain));
      }
    }
    std::filesystem::create_directories(plan.run_dir / "logs");
    for (const ProcessPlan& pp : plan.processes) {
      Process& process = processes.emplace_back();
      process.plan = &pp;
      process.state.name = pp.name;
      process.state.log = pp.log.string();
      process.state.since = std::chrono::system_clock::now();
      process.state.detail = "not started yet";
    }
    Publish();
  }

  void SetPhase(Process& p, Phase phase, std::string detail) {
    {
      std::lock_guard lock(mutex);
      p.state.phase = phase;
      p.state.pid = p.child && p.child->running() ? p.child->pid() : -1;
      p.state.since = std::chrono::system_clock::now();
      p.state.detail = std::move(detail);
    }
    Publish();
  }

  std::vector<ProcessState> Snapshot() const {
    std::lock_guard lock(mutex);
    std::vector<ProcessState> out;
    out.reserve(processes.size());
    for (const Process& p : processes) out.push_back(p.state);
    return out;
  }

  // What changed goes out at once: status.json and the process table.
  void Publish() {
    const std::vector<ProcessState> states = Snapshot();
    WriteStatus(states);
    WriteTables(states);
  }

  // The process table on every domain: each district's SCM watches the whole city's processes.
  void WriteTables(const std::vector<ProcessState>& states) {
    for (const auto& d : domains) d->table.Write(launcher_state, states);
  }

  // The table at least every ProcessTableWriter::kPeriod, also when nothing changes.
  void PublishIfDue() {
    if (std::ranges::any_of(domains, [](const auto& d) { return d->table.due(); })) {
      WriteTables(Snapshot());
    }
  }

  // status.json, replaced whole (written beside and renamed).
  void WriteStatus(const std::vector<ProcessState>& states) const {
    nlohmann::json j;
    j["city"] = plan.city_name;
    j["city_file"] = plan.city_file.string();
    j["launcher_pid"] = ::getpid();
    if (!plan.host.empty()) j["host"] = plan.host;
    j["updated"] = Iso(std::chrono::system_clock::now());
    nlohmann::json list = nlohmann::json::array();
    for (const ProcessState& s : states) {
      nlohmann::json e;
      e["name"] = s.name;
      e["phase"] = PhaseName(s.phase);
      e["pid"] = s.pid;
      e["starts"] = s.starts;
      e["last_exit"] = s.last_exit ? nlohmann::json(*s.last_exit) : nlohmann::json();
      e["exits"] = s.exits;
      e["since"] = Iso(s.since);
      e["detail"] = s.detail;
      e["log"] = s.log;
      list.push_back(std::move(e));
    }
    j["processes"] = std::move(list);
    // A plan made by hand (the tests) may leave it unset.
    const std::filesystem::path file =
        plan.status_file.empty() ? StatusFileOf(plan.run_dir, plan.host) : plan.status_file;
    std::filesystem::path tmp = file;
    tmp += ".tmp";
    {
      std::ofstream out(tmp);
      out << j.dump(2) << '\n';
    }
    std::error_code ec;
    std::filesystem::rename(tmp, file, ec);
  }

  void Drain() {
    dds::Message<msg::Heartbeat> hb;
    for (const auto& d : domains) {
      const std::string domain = d->district ? std::to_string(*d->district) : "";
      for (auto* reader : {&d->scm_heartbeats, &d->infra_heartbeats}) {
        while (reader->TakeOne(hb)) {
          heard.insert(fmt::format("{}|{}|{}", domain, dds::View(hb->sender), dds::View(hb->city)));
        }
      }
    }
    dds::Message<msg::Clock> c;
    while (clock.TakeOne(c)) heard_clock = true;
    dds::Message<msg::TrafficObjects> t;
    while (traffic.TakeOne(t)) heard_traffic = true;
  }

  bool Ready(const ProcessPlan& p) const {
    switch (p.ready.kind) {
      case Readiness::Kind::kNone:
        return true;
      case Readiness::Kind::kHeartbeat:
        return heard.contains(fmt::format("{}|{}|{}",
                                          p.ready.domain ? std::to_string(*p.ready.domain) : "",
                                          p.ready.sender, plan.city_name));
      case Readiness::Kind::kClock:
        return heard_clock;
      case Readiness::Kind::kTraffic:
        return heard_traffic;
      case Readiness::Kind::kFile:
        return std::filesystem::exists(p.ready.file);
    }
    return false;
  }

  void Start(Process& p) {
    Drain();
    heard.clear();
    heard_clock = heard_traffic = false;
    {
      std::ofstream(p.plan->log, std::ios::app) << fmt::format(
          "{}{} at {} ====\n", kStartMark, p.plan->name, Iso(std::chrono::system_clock::now()));
    }
    if (p.plan->ready.kind == Readiness::Kind::kFile) {
      std::error_code ec;
      std::filesystem::remove(p.plan->ready.file, ec);  // the last run's
    }
    ChildOptions options;
    options.extra_env = p.plan->env;
    // Its name in the process table: the ROS 2 node it appears as (common/dds/ros_graph.h).
    options.extra_env.push_back("AUTODRIVE_PROCESS_NAME=" + p.plan->name);
    options.output_file = p.plan->log;
    options.own_session = true;
    p.child.emplace(ChildProcess::Start(p.plan->argv, options));
    int starts = 0;
    {
      std::lock_guard lock(mutex);
      starts = ++p.state.starts;
    }
    SetPhase(p, Phase::kStarting,
             starts == 1 ? "starting" : fmt::format("starting again (restart {})", starts - 1));
  }

  // What a running process's row says: how often it was restarted, and why last.
  static std::string RunningDetail(const ProcessState& s) {
    if (s.starts <= 1 || !s.exit) return "running";
    return fmt::format("running (restart {}); last exit: {}", s.starts - 1, ToString(*s.exit));
  }

  // Records an exit on its own (not a stop of ours) of `p`, whose child has been reaped.
  void RecordExit(Process& p, const ExitStatus& status) {
    std::lock_guard lock(mutex);
    p.state.last_exit = status.code;
    ++p.state.exits;
    p.state.exit = status;
    p.state.exit_pid = p.state.pid;
    p.state.exited_at = std::chrono::system_clock::now();
  }

  static ExitStatus StatusOf(const ChildProcess& child, int code) {
    return child.exit_status().value_or(ExitStatus{code, 0});
  }

  // Waits until `p` is ready; throws LaunchError when it exits first or takes too long.
  void AwaitReady(Process& p, const std::atomic<bool>& stop) {
    const auto deadline = Clock::now() + p.plan->ready_timeout;
    for (;;) {
      Drain();
      if (Ready(*p.plan)) break;
      if (const auto code = p.child->Wait(0ms)) {
        const ExitStatus status = StatusOf(*p.child, *code);
        RecordExit(p, status);
        SetPhase(p, Phase::kStopped, fmt::format("{} before it was ready", ToString(status)));
        throw LaunchError(
            fmt::format("{} exited with code {} before it was ready; its log ({}):\n{}",
                        p.plan->name, *code, p.plan->log.string(), Tail(p.plan->log, 15)));
      }
      if (stop.load()) return;
      if (Clock::now() > deadline) {
        throw LaunchError(fmt::format(
            "{} was not ready in {:.0f} s (no {} yet); its log ({}):\n{}", p.plan->name,
            std::chrono::duration<double>(p.plan->ready_timeout).count(),
            p.plan->ready.kind == Readiness::Kind::kHeartbeat ? "heartbeat" : "sample on its topic",
            p.plan->log.string(), Tail(p.plan->log, 15)));
      }
      PublishIfDue();
      std::this_thread::sleep_for(50ms);
    }
    SetPhase(p, Phase::kRunning, RunningDetail(p.state));
    say(fmt::format("{} is up (pid {})", p.plan->name, p.child->pid()));
  }

  void Up(const std::atomic<bool>& stop) {
    for (Process& p : processes) {
      if (stop.load()) return;
      say(fmt::format("starting {}: {}", p.plan->name, fmt::join(p.plan->argv, " ")));
      Start(p);
      AwaitReady(p, stop);
    }
  }

  void Supervise(const std::atomic<bool>& stop) {
    launcher_state = LauncherState::kRunning;
    WriteTables(Snapshot());
    while (!stop.load()) {
      const auto now = Clock::now();
      for (Process& p : processes) {
        if (p.child && p.child->running()) {
          const auto code = p.child->Wait(0ms);
          if (!code) {
            if (p.state.phase == Phase::kStarting) {
              Drain();
              if (Ready(*p.plan)) {
                SetPhase(p, Phase::kRunning, RunningDetail(p.state));
                say(fmt::format("{} is up again (pid {})", p.plan->name, p.child->pid()));
              }
            }
            continue;
          }
          Exited(p, StatusOf(*p.child, *code), now);
        } else if ((p.state.phase == Phase::kExited || p.state.phase == Phase::kCrashLoop) &&
                   now >= p.start_at) {
          say(fmt::format("starting {} again (start {})", p.plan->name, p.state.starts + 1));
          try {
            Start(p);
          } catch (const std::exception& e) {
            say(fmt::format("{} could not be started: {}", p.plan->name, e.what()));
            Exited(p, ExitStatus{127, 0}, now);
          }
        }
      }
      PublishIfDue();
      if (std::ranges::all_of(processes,
                              [](const Process& p) { return p.state.phase == Phase::kStopped; })) {
        say("every process ended and none is to be started again");
        return;
      }
      std::this_thread::sleep_for(50ms);
    }
  }

  void Exited(Process& p, const ExitStatus& status, Clock::time_point now) {
    RecordExit(p, status);
    const int code = status.code;
    const Restart r = p.plan->restart;
    if (r == Restart::kNever || (r == Restart::kOnFailure && code == 0)) {
      const char* policy = r == Restart::kNever ? "never" : "on-failure";
      SetPhase(p, Phase::kStopped,
               fmt::format("{}; not started again (restart: {})", ToString(status), policy));
      say(fmt::format("{} exited with code {}: not started again (restart: {})", p.plan->name, code,
                      policy));
      return;
    }
    p.exits.push_back(now);
    while (!p.exits.empty() && now - p.exits.front() > plan.crash_loop_window) {
      p.exits.pop_front();
    }
    const int restart = p.state.starts;  // the next start is this restart
    if (static_cast<int>(p.exits.size()) >= plan.crash_loop_exits) {
      p.start_at = p.exits.front() + plan.crash_loop_window;
      SetRestartAt(p, p.start_at - now);
      const double window_s = std::chrono::duration<double>(plan.crash_loop_window).count();
      const double in_s = std::chrono::duration<double>(p.start_at - now).count();
      SetPhase(p, Phase::kCrashLoop,
               fmt::format("{}; crash loop: {} exits within {:.0f} s; restart {} in {:.0f} s",
                           ToString(status), p.exits.size(), window_s, restart, in_s));
      say(fmt::format(
          "{} is in a crash loop: it exited {} times in {:.0f} s (last code {}); it starts again "
          "in {:.0f} s. Its log ({}):\n{}",
          p.plan->name, p.exits.size(), window_s, code, in_s, p.plan->log.string(),
          Tail(p.plan->log, 10)));
      return;
    }
    // The SCM at once (the lights flash until it is back); the others after a second.
    p.start_at = p.plan->program == "scm" ? now : now + 1s;
    SetRestartAt(p, p.start_at - now);
    SetPhase(p, Phase::kExited,
             fmt::format("{}; restart {} in {:.1f} s", ToString(status), restart,
                         std::chrono::duration<double>(p.start_at - now).count()));
    say(fmt::format("{} exited with code {}: starting it again", p.plan->name, code));
  }

  // The wall-clock time of a restart `in` from now, for the table.
  void SetRestartAt(Process& p, Clock::duration in) {
    std::lock_guard lock(mutex);
    p.state.restart_at = std::chrono::system_clock::now() +
                         std::chrono::duration_cast<std::chrono::system_clock::duration>(in);
  }

  void Down() {
    launcher_state = LauncherState::kStopping;
    WriteTables(Snapshot());
    for (auto it = processes.rbegin(); it != processes.rend(); ++it) {
      Process& p = *it;
      if (p.child && p.child->running()) {
        say(fmt::format("stopping {} (pid {})", p.plan->name, p.child->pid()));
        const int code =
            p.child->Stop(std::chrono::duration_cast<std::chrono::milliseconds>(plan.stop_grace));
        {
          std::lock_guard lock(mutex);
          p.state.last_exit = code;
        }
      }
      if (p.state.phase != Phase::kWaiting && p.state.phase != Phase::kStopped) {
        SetPhase(p, Phase::kStopped, "stopped by the launcher");
      }
    }
  }
};

Supervisor::Supervisor(LaunchPlan plan, const dds::Participant& participant,
                       std::function<void(const std::string&)> say,
                       const std::vector<const dds::Participant*>& districts)
    : impl_(std::make_unique<Impl>(std::move(plan), participant, districts, std::move(say))) {}

Supervisor::~Supervisor() {
  try {
    impl_->Down();
  } catch (...) {
  }
}

void Supervisor::Up(const std::atomic<bool>& stop) { impl_->Up(stop); }
void Supervisor::Supervise(const std::atomic<bool>& stop) { impl_->Supervise(stop); }
void Supervisor::Down() { impl_->Down(); }

std::vector<ProcessState> Supervisor::states() const {
  std::lock_guard lock(impl_->mutex);
  std::vector<ProcessState> out;
  for (const auto& p : impl_->processes) out.push_back(p.state);
  return out;
}

}  // namespace autodrive::launcher
