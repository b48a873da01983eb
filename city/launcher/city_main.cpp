// autodrive-city: brings a whole city up from its file and down again (docs/launcher.md).
#include <fcntl.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <netdb.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "city/launcher/launch_config.h"
#include "city/launcher/supervisor.h"

#include "common/dds/participant.h"
#include "common/dds/program_options.h"
#include "common/error.h"
#include "common/ids.h"
#include "common/logging.h"
#include "common/process.h"
#include "common/shutdown.h"
#include "maps/district_domains.h"

namespace autodrive::launcher {
namespace {

using namespace std::chrono_literals;

void Say(const std::string& line) {
  const auto now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  char stamp[16];
  std::strftime(stamp, sizeof stamp, "%H:%M:%S", std::localtime(&now));
  std::printf("[%s] %s\n", stamp, line.c_str());
  std::fflush(stdout);
}

// Whether `pid` runs: a zombie (exited, not yet reaped by its parent) does not.
bool Alive(pid_t pid) {
  if (::kill(pid, 0) != 0 && errno == ESRCH) return false;
  std::ifstream stat(fmt::format("/proc/{}/stat", pid));
  std::string line;
  std::getline(stat, line);
  const auto paren = line.rfind(')');
  return paren == std::string::npos || paren + 2 >= line.size() || line[paren + 2] != 'Z';
}

// The pid of the launcher whose pid file is `pid_file`, if it runs.
std::optional<pid_t> RunningLauncher(const std::filesystem::path& pid_file) {
  std::ifstream in(pid_file);
  long pid = 0;
  if (!(in >> pid) || pid <= 0) return std::nullopt;
  if (!Alive(static_cast<pid_t>(pid))) return std::nullopt;
  // A pid reused by another program is not ours: its command line must be autodrive-city's.
  std::ifstream cmdline(fmt::format("/proc/{}/cmdline", pid));
  std::string argv0;
  std::getline(cmdline, argv0, '\0');
  if (std::filesystem::path(argv0).filename() != "autodrive-city") return std::nullopt;
  return static_cast<pid_t>(pid);
}

// The dashboard's tokens file, made with one new token for the city's first operator when it
// is not there (readable by its owner only).
void MakeTokens(const LaunchPlan::Dashboard& d) {
  if (std::filesystem::exists(d.tokens) || d.operator_name.empty()) return;
  std::filesystem::create_directories(d.tokens.parent_path());
  const std::string token = RandomToken();
  const int fd = ::open(d.tokens.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0600);
  if (fd < 0) throw InputError(fmt::format("{}: cannot create the tokens file", d.tokens.string()));
  const std::string line =
      fmt::format("# autodrive-dashboard operators: NAME TOKEN (docs/dashboard.md)\n{} {}\n",
                  d.operator_name, token);
  const bool ok = ::write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size());
  ::close(fd);
  if (!ok) throw InputError(fmt::format("{}: cannot write the tokens file", d.tokens.string()));
  Say(fmt::format("dashboard: a token for operator {} is in {}", d.operator_name,
                  d.tokens.string()));
}

struct UpOptions {
  std::string city;
  std::string bin_dir;
  std::string partition;
  std::string dashboard;  ///< HOST:PORT overriding launch.dashboard.listen
  std::string record;     ///< an MCAP file to record the whole run into (autodrive-record)
  std::string host;       ///< launch.hosts: start this host's share only
  double duration_s = 0;
};

// `up --record FILE`: autodrive-record records every topic of the run (cameras aside) into
// FILE, started first and stopped last, so that the file holds the run from the lights' first
// flash to their last. Never restarted: a restart would begin the file again.
void PlanRecorder(LaunchPlan& plan, const std::filesystem::path& bin_dir, const std::string& file) {
  const std::filesystem::path out = std::filesystem::absolute(file);
  AUTODRIVE_THROW_UNLESS(!std::filesystem::exists(out),
                         "--record: " << out.string()
                                      << " exists; choose another name (a recording is never "
                                         "overwritten)");
  AUTODRIVE_THROW_UNLESS(
      std::filesystem::is_directory(out.parent_path()),
      "--record: the folder " << out.parent_path().string() << " does not exist");
  AUTODRIVE_THROW_UNLESS(
      std::ranges::none_of(plan.processes, [](const ProcessPlan& p) { return p.name == "record"; }),
      "--record: the city already has a process named record");
  ProcessPlan recorder;
  recorder.name = "record";
  recorder.argv = {(bin_dir / "autodrive-record").string(), "record", "-o", out.string()};
  recorder.restart = Restart::kNever;
  recorder.log = plan.run_dir / "logs" / "record.log";
  recorder.city_program = true;
  plan.processes.insert(plan.processes.begin(), std::move(recorder));
}

// Refuses to start the city when the dashboard's HOST:PORT is taken: found now, before
// anything starts, not when the dashboard exits and takes the city down with it.
void CheckDashboardAddressFree(const std::string& listen) {
  const auto colon = listen.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == listen.size() ||
      listen.find_first_not_of("0123456789", colon + 1) != std::string::npos) {
    throw InputError(fmt::format("the dashboard's address \"{}\" is not HOST:PORT", listen));
  }
  const std::string host = listen.substr(0, colon);
  const std::string port = listen.substr(colon + 1);
  if (std::stoul(port) == 0) return;  // any free port
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE;
  addrinfo* found = nullptr;
  if (const int rc = ::getaddrinfo(host.c_str(), port.c_str(), &hints, &found); rc != 0) {
    throw InputError(fmt::format("the dashboard's address {}: {}", listen, ::gai_strerror(rc)));
  }
  std::unique_ptr<addrinfo, decltype(&::freeaddrinfo)> list(found, &::freeaddrinfo);
  for (const addrinfo* a = found; a != nullptr; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) continue;
    const int one = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);  // as the dashboard binds
    const bool bound = ::bind(fd, a->ai_addr, a->ai_addrlen) == 0;
    const int error = errno;
    ::close(fd);
    if (!bound && error == EADDRINUSE) {
      throw InputError(fmt::format(
          "the dashboard's address {} is taken by another program (`ss -ltnp 'sport = :{}'` "
          "shows which); nothing was started. Give the dashboard another address: "
          "`autodrive-city up --dashboard {}:{}` (scripts/run-city --dashboard {}:{}) or "
          "launch.dashboard.listen in the city file",
          listen, port, host, std::stoul(port) + 10, host, std::stoul(port) + 10));
    }
  }
}

int Up(const UpOptions& o) {
  const std::filesystem::path bin_dir = o.bin_dir.empty() ? ExecutableDir() : o.bin_dir;
  LaunchPlan plan = PlanCity(o.city, bin_dir);
  SelectHost(plan, o.host);
  if (!o.record.empty()) PlanRecorder(plan, bin_dir, o.record);
  if (!o.dashboard.empty()) {
    if (!plan.dashboard) {
      throw InputError("--dashboard: the city's dashboard is off (launch.dashboard.mode)");
    }
    for (ProcessPlan& p : plan.processes) {
      if (p.name != "dashboard") continue;
      const auto at = std::ranges::find(p.argv, std::string("--listen"));
      if (at != p.argv.end() && at + 1 != p.argv.end()) *(at + 1) = o.dashboard;
    }
    plan.dashboard->url = fmt::format("http://{}/", o.dashboard);
  }
  if (!o.partition.empty()) {
    for (ProcessPlan& p : plan.processes) {
      if (p.city_program) {
        p.argv.insert(p.argv.end(), {"--partition", o.partition});
      }
      p.env.push_back("AUTODRIVE_PARTITION=" + o.partition);
    }
  }
  const std::string host_option = o.host.empty() ? "" : " --host " + o.host;
  if (const auto pid = RunningLauncher(plan.pid_file)) {
    throw InputError(fmt::format(
        "the city {} is already up{} (autodrive-city, pid {}); `autodrive-city down {}{}` stops "
        "it",
        plan.city_name, o.host.empty() ? "" : " on host " + o.host, *pid, o.city, host_option));
  }
  if (plan.dashboard) {
    for (const ProcessPlan& p : plan.processes) {
      const auto at = std::ranges::find(p.argv, std::string("--listen"));
      if (p.name == "dashboard" && at != p.argv.end() && at + 1 != p.argv.end()) {
        CheckDashboardAddressFree(*(at + 1));
      }
    }
  }
  std::atomic<bool> stop{false};
  ShutdownSignals signals([&](int) { stop.store(true); });
  StopWithParentIfAsked();
  // Without CYCLONEDDS_URI every program of the city takes the shipped loopback configuration
  // (config/dds/localhost.xml); the launcher must too, or it would not hear their readiness.
  // The children inherit the variable it sets.
  dds::UseShippedDdsConfigUnlessSet();
  dds::ParticipantOptions participant_options;
  participant_options.partition = o.partition;
  // DDS Security from the environment, as every program of the city takes it; the launcher's
  // own identity is /autodrive/launcher (role `launcher`: it reads what readiness needs and
  // writes its process table).
  // The children inherit the environment and each takes its own default enclave, so an
  // enclave override in the environment would give them all the launcher's (docs/security.md).
  participant_options.security = dds::SecurityOptions::FromEnvironment();
  if (participant_options.security->enclave.empty()) {
    participant_options.security->enclave = "/autodrive/launcher";
  }
  participant_options.ros_node = dds::RosNodeFor("/autodrive/launcher");
  dds::Participant participant(participant_options);
  // A city of districts: the districts' SCMs and light hosts are heard on their domains, and
  // the process table goes there too. The launcher's own domain, where the simulator, the driver
  // and SUMO run, must be no district's (the simulator would refuse it).
  std::vector<std::unique_ptr<dds::Participant>> district_domains;
  std::vector<const dds::Participant*> districts;
  for (const auto& [name, domain] : plan.districts) {
    district_domains.push_back(
        maps::JoinDistrictDomain(participant, participant_options, name, domain));
    districts.push_back(district_domains.back().get());
  }
  std::filesystem::create_directories(plan.run_dir);
  std::ofstream(plan.pid_file) << ::getpid() << '\n';
  if (plan.dashboard) MakeTokens(*plan.dashboard);
  Say(fmt::format("city {}: {} processes{}; run folder {}", plan.city_name, plan.processes.size(),
                  plan.host.empty() ? "" : fmt::format(" (host {}'s share)", plan.host),
                  plan.run_dir.string()));
  int code = 0;
  {
    Supervisor supervisor(plan, participant, Say, districts);
    try {
      supervisor.Up(stop);
      if (!stop.load()) {
        Say(
            fmt::format("city {} is up{}. `autodrive-city status {}{}` shows it, Ctrl-C or "
                        "`autodrive-city down {}{}` stops it",
                        plan.city_name, plan.host.empty() ? "" : " (host " + plan.host + ")",
                        o.city, host_option, o.city, host_option));
        if (plan.dashboard) {
          std::string url = plan.dashboard->url;
          std::ifstream(plan.dashboard->url_file) >> url;
          Say(fmt::format("dashboard: {} (operators' tokens in {})", url,
                          plan.dashboard->tokens.string()));
        }
      }
      std::jthread timer;
      if (o.duration_s > 0) {
        timer = std::jthread([&](std::stop_token token) {
          const auto end = std::chrono::steady_clock::now() +
                           std::chrono::duration_cast<std::chrono::nanoseconds>(
                               std::chrono::duration<double>(o.duration_s));
          while (!token.stop_requested() && std::chrono::steady_clock::now() < end) {
            std::this_thread::sleep_for(50ms);
          }
          stop.store(true);
        });
      }
      supervisor.Supervise(stop);
      // Not stopped: every process ended on its own with none to start again (a lockstep run
      // whose simulator ended). The run's result is theirs.
      if (!stop.load()) {
        for (const ProcessState& s : supervisor.states()) {
          if (s.last_exit.value_or(0) != 0) code = 1;
        }
      }
    } catch (const LaunchError& e) {
      std::fprintf(stderr, "autodrive-city: %s\n", e.what());
      code = 1;
    }
    Say("stopping the city (the lights last)");
    supervisor.Down();
  }
  std::filesystem::remove(plan.pid_file);
  Say("stopped");
  return code;
}

int Down(const std::string& city, const std::string& host, double timeout_s) {
  const std::filesystem::path run_dir = RunDirOf(city);
  const auto pid = RunningLauncher(PidFileOf(run_dir, host));
  if (!pid) {
    std::printf("the city is not up%s (no launcher in %s)\n",
                host.empty() ? "" : (" on host " + host).c_str(), run_dir.c_str());
    return 0;
  }
  ::kill(*pid, SIGTERM);
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::nanoseconds>(
                                             std::chrono::duration<double>(timeout_s));
  while (std::chrono::steady_clock::now() < deadline) {
    if (!Alive(*pid)) {
      std::printf("stopped\n");
      return 0;
    }
    std::this_thread::sleep_for(100ms);
  }
  std::fprintf(stderr, "autodrive-city: the launcher (pid %d) is still stopping after %.0f s\n",
               *pid, timeout_s);
  return 1;
}

int Status(const std::string& city, const std::string& host, bool json) {
  const std::filesystem::path run_dir = RunDirOf(city);
  const std::filesystem::path file = StatusFileOf(run_dir, host);
  std::ifstream in(file);
  if (!in) {
    std::printf("the city has not run here (no %s)\n", file.c_str());
    return 1;
  }
  const nlohmann::json j = nlohmann::json::parse(in);
  const bool up = RunningLauncher(PidFileOf(run_dir, host)).has_value();
  if (json) {
    nlohmann::json out = j;
    out["up"] = up;
    std::printf("%s\n", out.dump(2).c_str());
    return up ? 0 : 3;
  }
  std::printf("city %s%s: %s (as of %s)\n", j.value("city", "?").c_str(),
              host.empty() ? "" : (", host " + host).c_str(), up ? "up" : "not running",
              j.value("updated", "?").c_str());
  std::size_t width = 12;  // a district's lights_<district> may be longer
  for (const auto& p : j.at("processes")) width = std::max(width, p.value("name", "?").size());
  std::printf("%s\n", fmt::format("{:<{}} {:<10} {:>8} {:>7} {:>9}  {}", "process", width, "state",
                                  "pid", "starts", "last exit", "since")
                          .c_str());
  for (const auto& p : j.at("processes")) {
    const std::string last = p["last_exit"].is_null() ? "-" : p["last_exit"].dump();
    std::printf("%s\n", fmt::format("{:<{}} {:<10} {:>8} {:>7} {:>9}  {}", p.value("name", "?"),
                                    width, p.value("phase", "?"), p.value("pid", -1),
                                    p.value("starts", 0), last, p.value("since", "?"))
                            .c_str());
  }
  return up ? 0 : 3;
}

int Logs(const std::string& city, const std::string& name, std::size_t lines, bool follow) {
  const std::filesystem::path log = RunDirOf(city) / "logs" / (name + ".log");
  if (!std::filesystem::exists(log)) {
    throw InputError(
        fmt::format("no log {} (`autodrive-city status` names the processes)", log.string()));
  }
  std::ifstream in(log, std::ios::binary);
  std::deque<std::string> last;
  for (std::string line; std::getline(in, line);) {
    last.push_back(std::move(line));
    if (last.size() > lines) last.pop_front();
  }
  for (const std::string& l : last) std::printf("%s\n", l.c_str());
  std::fflush(stdout);
  if (!follow) return 0;
  // Until Ctrl-C: what is appended (a process started again appends to its log).
  std::atomic<bool> stop{false};
  ShutdownSignals signals([&](int) { stop.store(true); });
  StopWithParentIfAsked();
  std::uintmax_t offset = std::filesystem::file_size(log);
  while (!stop.load()) {
    std::this_thread::sleep_for(200ms);
    std::error_code ec;
    const std::uintmax_t size = std::filesystem::file_size(log, ec);
    if (ec || size == offset) continue;
    if (size < offset) offset = 0;  // truncated
    std::ifstream more(log, std::ios::binary);
    more.seekg(static_cast<std::streamoff>(offset));
    std::string chunk(static_cast<std::size_t>(size - offset), '\0');
    more.read(chunk.data(), static_cast<std::streamsize>(chunk.size()));
    std::fwrite(chunk.data(), 1, static_cast<std::size_t>(more.gcount()), stdout);
    std::fflush(stdout);
    offset += static_cast<std::uintmax_t>(more.gcount());
  }
  return 0;
}

// systemd units for a lab host: the city as one service (`autodrive-city up`), which starts
// and stops its processes in order, with the paths of docs/launcher.md. A city spread over
// hosts (launch.hosts) gets a unit per host, each starting that host's share (`up --host`).
void WriteUnit(const LaunchPlan& plan, const std::filesystem::path& dir, const std::string& user,
               const std::string& dds_config) {
  const std::string unit =
      plan.host.empty() ? fmt::format("autodrive-city-{}.service", plan.city_name)
                        : fmt::format("autodrive-city-{}-{}.service", plan.city_name, plan.host);
  const auto grace = std::chrono::duration_cast<std::chrono::seconds>(plan.stop_grace).count();
  std::ofstream f(dir / unit);
  f << "# Generated by autodrive-city install-units (docs/launcher.md). The launcher starts the\n"
    << "# city's processes in order and stops them in reverse, so that the lights flash last:\n"
    << "# systemd signals it alone (KillMode=mixed) and kills what is left only at the end.\n"
    << "[Unit]\n"
    << fmt::format("Description=AutoDRIVE smart city {}{} ({})\n", plan.city_name,
                   plan.host.empty() ? "" : ", host " + plan.host, plan.city_file.string())
    << "Wants=network-online.target\nAfter=network-online.target\n\n"
    << "[Service]\nType=simple\n";
  if (!user.empty()) f << "User=" << user << "\n";
  f << fmt::format("ExecStart={}/autodrive-city up {}{}\n", ExecutableDir(),
                   plan.city_file.string(), plan.host.empty() ? "" : " --host " + plan.host)
    << fmt::format("WorkingDirectory={}\n", plan.run_dir.string())
    << fmt::format("Environment=CYCLONEDDS_URI=file://{}\n", dds_config) << "KillMode=mixed\n"
    << fmt::format("TimeoutStopSec={}\n", grace * static_cast<long>(plan.processes.size()) + 30)
    << "Restart=on-failure\nRestartSec=2\n\n"
    << "[Install]\nWantedBy=multi-user.target\n";
  f.close();
  AUTODRIVE_THROW_UNLESS(!f.fail(), "writing " << (dir / unit).string() << " failed");
  std::printf(
      "wrote %s%s\ninstall: sudo cp %s /etc/systemd/system/ && sudo systemctl daemon-reload "
      "&& sudo systemctl enable --now %s\n",
      (dir / unit).c_str(), plan.host.empty() ? "" : (" (on host " + plan.host + ")").c_str(),
      (dir / unit).c_str(), unit.c_str());
}

int InstallUnits(const std::string& city, const std::string& host, const std::string& out_dir,
                 const std::string& user, const std::string& dds_config) {
  const LaunchPlan whole = PlanCity(city, ExecutableDir());
  const std::filesystem::path dir = out_dir;
  std::filesystem::create_directories(dir);
  std::vector<std::string> hosts;
  if (!host.empty()) {
    hosts.push_back(host);
  } else {
    for (const auto& [name, processes] : whole.hosts) hosts.push_back(name);
  }
  if (hosts.empty()) {
    WriteUnit(whole, dir, user, dds_config);
    return 0;
  }
  for (const std::string& h : hosts) {
    LaunchPlan share = whole;
    SelectHost(share, h);
    WriteUnit(share, dir, user, dds_config);
  }
  return 0;
}

int Check(const std::string& city, const std::string& bin_dir) {
  const LaunchPlan plan = PlanCity(city, bin_dir.empty() ? ExecutableDir() : bin_dir);
  std::printf("city %s: run folder %s\n", plan.city_name.c_str(), plan.run_dir.c_str());
  std::size_t width = 10;
  for (const ProcessPlan& p : plan.processes) width = std::max(width, p.name.size());
  for (const auto& [name, domain] : plan.districts) {
    std::printf("district %s: DDS domain %u\n", name.c_str(), domain);
  }
  for (const ProcessPlan& p : plan.processes) {
    std::printf("  %s\n", fmt::format("{:<{}} {}", p.name, width, fmt::join(p.argv, " ")).c_str());
  }
  return 0;
}

}  // namespace
}  // namespace autodrive::launcher

int main(int argc, char** argv) {
  using namespace autodrive;
  using namespace autodrive::launcher;
  CLI::App app{
      "autodrive-city: brings a whole city up from its file (the lights, the SCM, the "
      "simulator and its driver, the Eye, SUMO's traffic, the dashboard and the user's agents, "
      "as its launch section says), keeps it up, and takes it down in order so that the lights "
      "flash last. See docs/launcher.md."};
  app.require_subcommand(1);
  UpOptions up;
  auto* up_cmd = app.add_subcommand(
      "up", "start the city's processes in order and keep them up until Ctrl-C or `down`");
  up_cmd->add_option("city", up.city, "city file")->required()->check(CLI::ExistingFile);
  up_cmd->add_option("--duration", up.duration_s, "stop after this many seconds (0: never)")
      ->check(CLI::Range(0.0, 1e9));
  up_cmd->add_option("--partition", up.partition, "DDS partition for every process");
  up_cmd->add_option("--dashboard", up.dashboard,
                     "the dashboard's HOST:PORT (instead of launch.dashboard.listen; port 0: any "
                     "free one)");
  up_cmd->add_option("--record", up.record,
                     "record the run into this MCAP file (rosbag2-compatible; cameras aside): "
                     "autodrive-record, started first and stopped last");
  up_cmd->add_option("--host", up.host,
                     "start only this host's share of the city (launch.hosts; its own status and "
                     "pid files)");
  up_cmd->add_option("--bin-dir", up.bin_dir,
                     "where the city's programs are (default: beside autodrive-city)");
  std::string city, name, out_dir, user, bin_dir, host;
  double timeout_s = 120;
  bool json = false, follow = false;
  std::size_t lines = 50;
  std::string dds_config = "/etc/autodrive/dds/lab.xml";
  auto* down_cmd = app.add_subcommand("down", "stop the city that `up` runs");
  down_cmd->add_option("city", city, "city file")->required()->check(CLI::ExistingFile);
  down_cmd->add_option("--timeout", timeout_s, "seconds to wait for it to stop")
      ->capture_default_str();
  down_cmd->add_option("--host", host, "the share of this host (launch.hosts)");
  auto* status_cmd = app.add_subcommand("status", "each process of the city and its state");
  status_cmd->add_option("city", city, "city file")->required()->check(CLI::ExistingFile);
  status_cmd->add_flag("--json", json, "as JSON");
  status_cmd->add_option("--host", host, "the share of this host (launch.hosts)");
  auto* logs_cmd = app.add_subcommand("logs", "a process's log");
  logs_cmd->add_option("city", city, "city file")->required()->check(CLI::ExistingFile);
  logs_cmd->add_option("name", name, "the process (lights, scm, sim, driver, eye, traffic, ...)")
      ->required();
  logs_cmd->add_option("-n,--lines", lines, "last lines")->capture_default_str();
  logs_cmd->add_flag("-f,--follow", follow, "then what is appended, until Ctrl-C");
  auto* units_cmd =
      app.add_subcommand("install-units",
                         "write the systemd unit that runs the city on boot (one per host with "
                         "launch.hosts)");
  units_cmd->add_option("city", city, "city file")->required()->check(CLI::ExistingFile);
  units_cmd->add_option("--out", out_dir, "folder to write the unit into")->required();
  units_cmd->add_option("--user", user, "the user the city runs as");
  units_cmd->add_option("--host", host,
                        "only this host's unit (launch.hosts; without it, one unit per host)");
  units_cmd->add_option("--dds-config", dds_config, "the lab's Cyclone DDS file")
      ->capture_default_str();
  auto* check_cmd = app.add_subcommand(
      "check", "load the city file as `up` would and print the processes it would start");
  check_cmd->add_option("city", city, "city file")->required()->check(CLI::ExistingFile);
  check_cmd->add_option("--bin-dir", bin_dir, "where the city's programs are");
  try {
    app.parse(argc, argv);
    InitLogging("autodrive-city", spdlog::level::warn);
    if (up_cmd->parsed()) return Up(up);
    if (down_cmd->parsed()) return Down(city, host, timeout_s);
    if (status_cmd->parsed()) return Status(city, host, json);
    if (logs_cmd->parsed()) return Logs(city, name, lines, follow);
    if (units_cmd->parsed()) return InstallUnits(city, host, out_dir, user, dds_config);
    if (check_cmd->parsed()) return Check(city, bin_dir);
    return 2;
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-city: %s\n", e.what());
    return 1;
  }
}
