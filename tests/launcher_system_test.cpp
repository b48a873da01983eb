// autodrive-city with real processes: `up` (in a shell without CYCLONEDDS_URI) then `down`
// leaves nothing behind; a killed SCM is started again and the lights come back from flash
// through the start-up sequence; a killed process (a light host, the SCM itself) raises an alarm
// in the SCM's event log (`scmctl events`) and on the dashboard's live feed, and an event when
// it is back; a mixed city starts with a component off; a crash loop is reported; a bad city
// file is refused before any process starts.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <functional>
#include <mutex>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/config.h"
#include "tests/scm_processes.h"

// After Eigen (through scm_processes.h): httplib brings <resolv.h>, whose `_res` macro breaks
// Eigen's headers.
#include <httplib.h>

namespace autodrive::test {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using ::testing::HasSubstr;

double WallSeconds() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

class Launcher : public ScmProcesses {
 protected:
  // The Driving School as shipped (its lights: config/infra/driving_school.yaml), with
  // `launch` appended and the run folder in the test's folder.
  std::string WriteCity(const std::string& launch, const std::string& lights = "") {
    std::string text = config::ReadFile(Config("config/cities/driving_school.yaml"));
    const auto replace = [&](const std::string& from, const std::string& to) {
      const auto at = text.find(from);
      EXPECT_NE(at, std::string::npos) << from;
      if (at != std::string::npos) text.replace(at, from.size(), to);
    };
    replace("../maps/", Config("config/maps") + "/");
    replace("../cameras/", Config("config/cameras") + "/");
    const std::string city = (dir_ / "city.yaml").string();
    std::ofstream(city)
        << text << "\nlaunch:\n  run_dir: " << (dir_ / "run").string() << "\n  lights: "
        << (lights.empty() ? "{config: " + Config("config/infra/driving_school.yaml") + "}"
                           : lights)
        << "\n"
        << launch
        // The dashboard on when a test asks for it, on a free port.
        << (launch.find("dashboard:") == std::string::npos ? "  dashboard: {mode: off}\n" : "");
    return city;
  }

  std::unique_ptr<ChildProcess> Up(const std::string& city, std::vector<std::string> extra = {},
                                   std::vector<std::string> env = {},
                                   const std::string& log = "launcher.log") {
    std::vector<std::string> argv{Bin("autodrive-city"), "up", city, "--partition", partition_};
    argv.insert(argv.end(), extra.begin(), extra.end());
    ChildOptions options;
    options.extra_env = std::move(env);
    options.output_file = dir_ / log;
    return std::make_unique<ChildProcess>(ChildProcess::Start(argv, options));
  }

  /// The launcher's status.json, or a host's share's (status-HOST.json).
  nlohmann::json Status(const std::string& host = "") const {
    std::ifstream in(dir_ / "run" / (host.empty() ? "status.json" : "status-" + host + ".json"));
    if (!in) return {};
    try {
      return nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception&) {
      return {};
    }
  }

  // Waits until `pred(status)` holds (generous deadline); gives up when the launcher exits.
  template <typename P>
  nlohmann::json WaitStatus(ChildProcess& launcher, P pred, SteadyClock::duration timeout,
                            const std::string& host = "") {
    const auto end = SteadyClock::now() + timeout;
    for (;;) {
      nlohmann::json s = Status(host);
      if (!s.is_null() && pred(s)) return s;
      if (SteadyClock::now() > end || launcher.Wait(milliseconds(0))) return {};
      std::this_thread::sleep_for(milliseconds(100));
    }
  }

  static const nlohmann::json* Process(const nlohmann::json& s, const std::string& name) {
    for (const auto& p : s.at("processes")) {
      if (p.value("name", "") == name) return &p;
    }
    return nullptr;
  }

  static bool AllRunning(const nlohmann::json& s) {
    for (const auto& p : s.at("processes")) {
      if (p.value("phase", "") != "running") return false;
    }
    return true;
  }

  std::string LauncherLog(const std::string& log = "launcher.log") const {
    return config::ReadFile(dir_ / log);
  }

  /// The dashboard's port, from the launcher's line "dashboard: http://127.0.0.1:PORT/" (it
  /// prints it once the city is up), or 0 when it does not come.
  int DashboardPort() const {
    const std::regex line("dashboard: http://127\\.0\\.0\\.1:([0-9]+)/");
    for (const auto end = SteadyClock::now() + seconds(60); SteadyClock::now() < end;) {
      std::smatch m;
      const std::string log = LauncherLog();
      if (std::regex_search(log, m, line)) return std::stoi(m[1]);
      std::this_thread::sleep_for(milliseconds(50));
    }
    return 0;
  }

  /// The SCM's event log as `scmctl --json events` prints it, since `since` (seconds).
  std::vector<nlohmann::json> ScmctlEvents(double since) const {
    const Output out =
        Scmctl({"--json", "events", "--since", fmt::format("{:.3f}", since), "--limit", "1000"});
    std::vector<nlohmann::json> events;
    const nlohmann::json j = nlohmann::json::parse(out.text, nullptr, false);
    if (j.is_discarded() || !j.contains("values")) return events;
    for (const auto& [id, e] : j["values"].items()) events.push_back(e);
    return events;
  }

  /// Runs `scmctl events` until an event with `code` about `device` is in the log (the SCM may
  /// be restarting: scmctl then has no answer); the first such event, or nothing.
  std::optional<nlohmann::json> WaitScmctlEvent(const std::string& code, const std::string& device,
                                                double since) const {
    for (const auto end = SteadyClock::now() + seconds(90); SteadyClock::now() < end;) {
      for (const auto& e : ScmctlEvents(since)) {
        if (e.value("code", "") == code && e.value("device", "") == device) return e;
      }
      std::this_thread::sleep_for(milliseconds(100));
    }
    return std::nullopt;
  }

  /// The first live event (on /autodrive/scm/events) with `code` about `device`, waiting up to
  /// `timeout`; `at` is set to when this test saw it.
  std::optional<dds::Message<msg::Event>> WaitLiveEvent(const std::string& code,
                                                        const std::string& device,
                                                        SteadyClock::duration timeout, double& at) {
    for (const auto end = SteadyClock::now() + timeout; SteadyClock::now() < end;) {
      events_->WaitForData(milliseconds(100));
      for (auto& m : events_->TakeAll()) {
        if (dds::View(m->code) == code && dds::View(m->device_id) == device) {
          at = WallSeconds();
          return std::move(m);
        }
      }
    }
    return std::nullopt;
  }
};

/// An event of the dashboard's feed with `code` about `device`.
auto FeedEvent(const std::string& code, const std::string& device) {
  return [code, device](const nlohmann::json& e) {
    return e.value("code", "") == code && e.value("device", "") == device;
  };
}

bool Alive(int pid) { return pid > 0 && (::kill(pid, 0) == 0 || errno != ESRCH); }

/// The dashboard's live feed (GET /api/stream, server-sent events) as the page reads it: every
/// event object it carries (those of the first `state` message, of `event` and of `events`),
/// read by a thread of its own until the feed is destroyed, connecting again when the dashboard
/// restarts.
class DashboardFeed {
 public:
  DashboardFeed(std::string host, int port) : host_(std::move(host)), port_(port) {
    thread_ = std::thread([this] { Run(); });
  }
  DashboardFeed(const DashboardFeed&) = delete;
  DashboardFeed& operator=(const DashboardFeed&) = delete;
  ~DashboardFeed() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
      if (client_ != nullptr) client_->stop();
    }
    thread_.join();
  }

  /// The first event object for which `pred` holds, waiting up to `timeout` for it.
  std::optional<nlohmann::json> WaitFor(const std::function<bool(const nlohmann::json&)>& pred,
                                        SteadyClock::duration timeout) {
    std::unique_lock lock(mutex_);
    std::optional<nlohmann::json> found;
    cv_.wait_for(lock, timeout, [&] {
      for (const auto& e : events_) {
        if (pred(e)) {
          found = e;
          return true;
        }
      }
      return false;
    });
    return found;
  }
  /// Every event seen, one line each: for failure messages.
  std::string Seen() {
    std::lock_guard lock(mutex_);
    std::string out;
    for (const auto& e : events_) out += e.dump() + "\n";
    return out;
  }

 private:
  void Run() {
    for (;;) {
      httplib::Client client(host_, port_);
      client.set_read_timeout(10, 0);
      {
        std::lock_guard lock(mutex_);
        if (stop_) return;
        client_ = &client;
      }
      std::string buffer;
      client.Get("/api/stream", [&](const char* data, std::size_t n) {
        buffer.append(data, n);
        for (auto end = buffer.find("\n\n"); end != std::string::npos; end = buffer.find("\n\n")) {
          Take(buffer.substr(0, end));
          buffer.erase(0, end + 2);
        }
        std::lock_guard lock(mutex_);
        return !stop_;
      });
      {
        std::lock_guard lock(mutex_);
        client_ = nullptr;
        if (stop_) return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the dashboard restarts
    }
  }
  // One SSE message: "event: NAME" and "data: JSON" lines.
  void Take(const std::string& message) {
    std::string name, data;
    std::istringstream lines(message);
    for (std::string line; std::getline(lines, line);) {
      if (line.rfind("event: ", 0) == 0) name = line.substr(7);
      if (line.rfind("data: ", 0) == 0) data += line.substr(6);
    }
    const nlohmann::json j = nlohmann::json::parse(data, nullptr, false);
    if (j.is_discarded()) return;
    std::vector<nlohmann::json> got;
    if (name == "event" && j.contains("event")) got.push_back(j["event"]);
    if ((name == "events" || name == "state") && j.contains("events")) {
      for (const auto& e : j["events"]) got.push_back(e);
    }
    if (got.empty()) return;
    {
      std::lock_guard lock(mutex_);
      events_.insert(events_.end(), got.begin(), got.end());
    }
    cv_.notify_all();
  }

  const std::string host_;
  const int port_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<nlohmann::json> events_;
  httplib::Client* client_ = nullptr;
  bool stop_ = false;
  std::thread thread_;
};

TEST_F(Launcher, UpThenDownLeavesNoProcessBehind) {
  const std::string city = WriteCity(
      "  sim: {mode: off}\n  eye: {mode: off}\n  dashboard: {mode: on, listen: "
      "\"127.0.0.1:0\"}\n");
  // As in a new shell, with no CYCLONEDDS_URI: the launcher takes the shipped loopback
  // configuration as its children do, or it would never hear that they are ready.
  auto up = Up(city, {}, {"CYCLONEDDS_URI="});
  const auto s = WaitStatus(*up, AllRunning, seconds(120));
  ASSERT_FALSE(s.is_null()) << LauncherLog();
  std::set<std::string> names;
  std::vector<int> pids;
  for (const auto& p : s.at("processes")) {
    names.insert(p.value("name", ""));
    pids.push_back(p.value("pid", -1));
  }
  EXPECT_EQ(names, (std::set<std::string>{"dashboard", "lights", "scm"}));
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  // The address the dashboard serves on (port 0: the one it got), and its operator's token.
  // The launcher prints it just after it marks every process running: wait for the line.
  for (const auto end = std::chrono::steady_clock::now() + seconds(30);
       LauncherLog().find("dashboard: http://") == std::string::npos &&
       std::chrono::steady_clock::now() < end;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_THAT(LauncherLog(), HasSubstr("dashboard: http://127.0.0.1:"));
  EXPECT_THAT(LauncherLog(), ::testing::Not(HasSubstr("http://127.0.0.1:0/")));
  EXPECT_THAT(config::ReadFile(dir_ / "run" / "dashboard.tokens"),
              ::testing::ContainsRegex("\nlab [0-9a-f]{32}\n"));
  EXPECT_EQ(std::filesystem::status(dir_ / "run" / "dashboard.tokens").permissions() &
                std::filesystem::perms::group_all,
            std::filesystem::perms::none);
  const Output down = RunCaptured({Bin("autodrive-city"), "down", city});
  EXPECT_EQ(down.code, 0) << down.text;
  EXPECT_EQ(up->Wait(milliseconds(60000)), std::optional<int>(0)) << LauncherLog();
  for (const int pid : pids) EXPECT_FALSE(Alive(pid)) << pid;
  // The lights stopped last: the launcher's log says so in that order.
  const std::string log = LauncherLog();
  EXPECT_LT(log.find("stopping scm"), log.find("stopping lights")) << log;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "run" / "launcher.pid"));
}

TEST_F(Launcher, AKilledScmIsStartedAgainAndTheLightsComeBackThroughTheStartUpSequence) {
  const std::string city = WriteCity("  sim: {mode: off}\n  eye: {mode: off}\n");
  auto up = Up(city);
  const auto s = WaitStatus(*up, AllRunning, seconds(120));
  ASSERT_FALSE(s.is_null()) << LauncherLog();
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  const int scm = Process(s, "scm")->value("pid", -1);
  ASSERT_GT(scm, 0);
  // What each head shows (its own topic: nothing of one head hides another's).
  std::vector<std::unique_ptr<dds::Reader<msg::Int32>>> lamps;
  for (std::uint32_t h = 1; h <= 4; ++h) {
    lamps.push_back(std::make_unique<dds::Reader<msg::Int32>>(
        *participant_, dds::topics::SignalState(SignalHeadId{h})));
  }
  for (auto& r : lamps) (void)r->TakeAll();  // what they showed before: no evidence of after
  ::kill(scm, SIGKILL);
  // The lights flash, then the SCM is back: start-up flash, all red, a plan. They flash on
  // their own when the SCM has been silent for their heartbeat time-out (0.8 s), or as soon as
  // a new SCM session takes over; then the new SCM's start-up flash. Either way a head goes
  // dark between its flashes, which it never does while a plan runs.
  bool dark = false;
  const auto dark_by = SteadyClock::now() + seconds(10);
  while (!dark && SteadyClock::now() < dark_by) {
    lamps.front()->WaitForData(milliseconds(50));
    for (auto& r : lamps) {
      for (const auto& m : r->TakeAll()) dark = dark || m->data == 0;
    }
  }
  ASSERT_TRUE(dark) << "no head flashed within 10 s of the SCM's death\n" << LauncherLog();
  const auto again = WaitStatus(
      *up,
      [](const nlohmann::json& st) {
        const auto* p = Process(st, "scm");
        return p != nullptr && p->value("starts", 0) == 2 && p->value("phase", "") == "running";
      },
      seconds(60));
  ASSERT_FALSE(again.is_null()) << LauncherLog();
  EXPECT_NE(Process(again, "scm")->value("pid", -1), scm);
  const auto standby = WaitSpat(
      [](const msg::Spat& sp) {
        const auto* x = FindIntersection(sp, "driving_school_crossing");
        return x != nullptr &&
               (x->status & autodrive_msgs_msg_IntersectionState_Constants_STANDBY_OPERATION) != 0;
      },
      seconds(20));
  ASSERT_TRUE(standby) << "no start-up flash after the restart";
  ASSERT_TRUE(WaitSpat(AnyGreen, seconds(30)));
  EXPECT_THAT(LauncherLog(), HasSubstr("scm exited with code 137: starting it again"));
  up->Stop(milliseconds(60000));
}

TEST_F(Launcher, AKilledLightHostRaisesAnAlarmInTheLogAndOnTheDashboardAndAnEventWhenBack) {
  const std::string city = WriteCity(
      "  sim: {mode: off}\n  eye: {mode: off}\n  dashboard: {mode: on, listen: "
      "\"127.0.0.1:0\"}\n");
  auto up = Up(city);
  const auto s = WaitStatus(*up, AllRunning, seconds(120));
  ASSERT_FALSE(s.is_null()) << LauncherLog();
  const int port = DashboardPort();
  ASSERT_GT(port, 0) << LauncherLog();
  DashboardFeed feed("127.0.0.1", port);
  const int lights = Process(s, "lights")->value("pid", -1);
  ASSERT_GT(lights, 0);
  (void)events_->TakeAll();  // what came before

  const double killed_at = WallSeconds();
  ASSERT_EQ(::kill(lights, SIGKILL), 0);
  // The alarm, live on the events topic: the figure of how long it took (not asserted: the
  // machine may be loaded).
  double live_at = 0;
  const auto live = WaitLiveEvent("process_exited", "process/lights", seconds(60), live_at);
  ASSERT_TRUE(live.has_value()) << LauncherLog();
  std::printf("process_exited on the events topic %.0f ms after the kill\n",
              (live_at - killed_at) * 1000.0);
  EXPECT_EQ((*live)->severity, autodrive_msgs_msg_Event_Constants_ALARM);

  // In the SCM's event log, as scmctl shows it.
  const auto logged = WaitScmctlEvent("process_exited", "process/lights", killed_at - 60);
  ASSERT_TRUE(logged.has_value()) << LauncherLog();
  std::printf("process_exited in scmctl events %.0f ms after the kill\n",
              (WallSeconds() - killed_at) * 1000.0);
  EXPECT_EQ(logged->value("severity", ""), "alarm");
  EXPECT_TRUE(logged->value("active", false));
  EXPECT_THAT(logged->value("message", ""),
              HasSubstr("process lights (pid " + std::to_string(lights)));
  EXPECT_THAT(logged->value("message", ""), HasSubstr("killed by signal 9 (SIGKILL)"));
  EXPECT_THAT(logged->value("message", ""), HasSubstr("(restart 1)"));
  EXPECT_GE(logged->value("stamp", 0.0), killed_at - 0.001) << "stamped when it died";
  EXPECT_EQ(logged->value("id", 0), static_cast<int>((*live)->event_id))
      << "one event: the same id live and in the log";

  // On the dashboard's live feed: an active alarm (the page's severity 2).
  const auto shown = feed.WaitFor(FeedEvent("process_exited", "process/lights"), seconds(60));
  ASSERT_TRUE(shown.has_value());
  std::printf("process_exited on the dashboard's feed by %.0f ms after the kill\n",
              (WallSeconds() - killed_at) * 1000.0);
  EXPECT_EQ((*shown)["severity"], 2);
  EXPECT_EQ((*shown)["active"], true);
  EXPECT_EQ((*shown)["id"], logged->value("id", 0));

  // Started again (after a second) and ready: an information that clears the alarm.
  const auto back = WaitScmctlEvent("process_restarted", "process/lights", killed_at - 60);
  ASSERT_TRUE(back.has_value()) << LauncherLog();
  EXPECT_EQ(back->value("severity", ""), "info");
  EXPECT_FALSE(back->value("active", true));
  EXPECT_THAT(back->value("message", ""), HasSubstr("is running again (restart 1)"));
  EXPECT_THAT(back->value("message", ""), HasSubstr("killed by signal 9 (SIGKILL)"));
  EXPECT_GT(back->value("stamp", 0.0), logged->value("stamp", 0.0));
  const auto back_shown =
      feed.WaitFor(FeedEvent("process_restarted", "process/lights"), seconds(60));
  ASSERT_TRUE(back_shown.has_value());
  EXPECT_EQ((*back_shown)["severity"], 0) << "information";
  // Logged once each, though the launcher repeats its table every second: two more tables.
  dds::Reader<msg::ProcessTable> tables(*participant_, dds::topics::Processes());
  int more = 0;
  for (const auto end = SteadyClock::now() + seconds(30); more < 3 && SteadyClock::now() < end;) {
    tables.WaitForData(milliseconds(200));
    more += static_cast<int>(tables.TakeAll().size());
  }
  EXPECT_GE(more, 3) << "the launcher's table every second (the first: its last, latched)";
  int exits = 0;
  for (const auto& e : ScmctlEvents(killed_at - 60)) {
    exits += e.value("code", "") == "process_exited" ? 1 : 0;
  }
  EXPECT_EQ(exits, 1);
  up->Stop(milliseconds(60000));
}

TEST_F(Launcher, AKilledScmLogsItsOwnDeathOnceBackStampedWhenItDied) {
  const std::string city = WriteCity(
      "  sim: {mode: off}\n  eye: {mode: off}\n  dashboard: {mode: on, listen: "
      "\"127.0.0.1:0\"}\n");
  auto up = Up(city);
  const auto s = WaitStatus(*up, AllRunning, seconds(120));
  ASSERT_FALSE(s.is_null()) << LauncherLog();
  const int port = DashboardPort();
  ASSERT_GT(port, 0) << LauncherLog();
  DashboardFeed feed("127.0.0.1", port);
  const int scm = Process(s, "scm")->value("pid", -1);
  ASSERT_GT(scm, 0);
  // The first SCM's events are on the dashboard already (the ids the next SCM must not reuse).
  ASSERT_TRUE(feed.WaitFor(FeedEvent("scm_started", ""), seconds(60)).has_value());
  (void)events_->TakeAll();

  const double killed_at = WallSeconds();
  ASSERT_EQ(::kill(scm, SIGKILL), 0);
  // Nobody can log it while the SCM is dead: the SCM started again logs it from the launcher's
  // last table, stamped when it died.
  double live_at = 0;
  const auto live = WaitLiveEvent("process_exited", "process/scm", seconds(60), live_at);
  ASSERT_TRUE(live.has_value()) << LauncherLog();
  std::printf("the SCM's own death on the events topic %.0f ms after the kill\n",
              (live_at - killed_at) * 1000.0);
  const auto logged = WaitScmctlEvent("process_exited", "process/scm", killed_at - 60);
  ASSERT_TRUE(logged.has_value()) << LauncherLog();
  std::printf("the SCM's own death in scmctl events %.0f ms after the kill\n",
              (WallSeconds() - killed_at) * 1000.0);
  EXPECT_EQ(logged->value("severity", ""), "alarm");
  EXPECT_THAT(logged->value("message", ""),
              HasSubstr("process scm (pid " + std::to_string(scm) + ", on "));
  EXPECT_THAT(logged->value("message", ""), HasSubstr("killed by signal 9 (SIGKILL)"));
  EXPECT_THAT(logged->value("message", ""), HasSubstr("restart 1"));
  // Stamped when it died: after the kill, and before the new SCM started.
  std::optional<double> restarted_scm;
  for (const auto& e : ScmctlEvents(killed_at)) {
    if (e.value("code", "") == "scm_started") restarted_scm = e.value("stamp", 0.0);
  }
  ASSERT_TRUE(restarted_scm.has_value());
  EXPECT_GE(logged->value("stamp", 0.0), killed_at - 0.001);
  EXPECT_LT(logged->value("stamp", 0.0), *restarted_scm)
      << "stamped with the time of the death, not when the new SCM learnt of it";

  // On the dashboard, which outlived the SCM: the new SCM's events are new to it (their ids
  // go on from the log's, never those of the first SCM's events again).
  const auto shown = feed.WaitFor(FeedEvent("process_exited", "process/scm"), seconds(60));
  ASSERT_TRUE(shown.has_value()) << logged->dump() << "\n" << feed.Seen();
  std::printf("the SCM's own death on the dashboard's feed by %.0f ms after the kill\n",
              (WallSeconds() - killed_at) * 1000.0);
  EXPECT_EQ((*shown)["severity"], 2);
  EXPECT_EQ((*shown)["id"], logged->value("id", 0));

  const auto back = WaitScmctlEvent("process_restarted", "process/scm", killed_at - 60);
  ASSERT_TRUE(back.has_value()) << LauncherLog();
  EXPECT_THAT(back->value("message", ""), HasSubstr("is running again (restart 1)"));
  ASSERT_TRUE(feed.WaitFor(FeedEvent("process_restarted", "process/scm"), seconds(60)))
      << back->dump() << "\n"
      << feed.Seen();
  up->Stop(milliseconds(60000));
}

TEST_F(Launcher, AMixedCityStartsWithTheLightsOffAndTheScmAlone) {
  // The lights run elsewhere (here: nowhere): the SCM comes up and publishes SPaT alone.
  const std::string city = WriteCity("  sim: {mode: off}\n  eye: {mode: off}\n", "{mode: off}");
  auto up = Up(city);
  const auto s = WaitStatus(*up, AllRunning, seconds(120));
  ASSERT_FALSE(s.is_null()) << LauncherLog();
  EXPECT_EQ(Process(s, "lights"), nullptr);
  ASSERT_NE(Process(s, "scm"), nullptr);
  up->Stop(milliseconds(60000));
}

TEST_F(Launcher, ACrashLoopIsReportedNotHidden) {
  const std::string city = WriteCity(
      "  sim: {mode: off}\n  eye: {mode: off}\n  crash_loop_exits: 3\n"
      "  agents:\n    - {name: failing, command: [/bin/false], restart: always}\n");
  auto up = Up(city);
  const auto s = WaitStatus(
      *up,
      [](const nlohmann::json& st) {
        const auto* p = Process(st, "failing");
        return p != nullptr && p->value("phase", "") == "crash-loop";
      },
      seconds(120));
  ASSERT_FALSE(s.is_null()) << LauncherLog();
  EXPECT_EQ(Process(s, "failing")->value("starts", 0), 3);
  // The launcher writes status.json, then its log line: wait for the line.
  const auto end = SteadyClock::now() + seconds(30);
  while (LauncherLog().find("failing is in a crash loop") == std::string::npos &&
         SteadyClock::now() < end) {
    std::this_thread::sleep_for(milliseconds(50));  // paces the reads of the log
  }
  EXPECT_THAT(LauncherLog(), HasSubstr("failing is in a crash loop"));
  const Output status = RunCaptured({Bin("autodrive-city"), "status", city});
  EXPECT_THAT(status.text, HasSubstr("crash-loop"));
  up->Stop(milliseconds(60000));
}

// A city of districts from one file (docs/districts.md), its shares on two hosts: uptown's light
// host and SCM on one, downtown's on the other. Each is ready on its district's domain, each
// district's SCM hears both hosts' process tables (it logs the other district's SCM's death),
// and a killed district SCM is started again at once.
TEST_F(Launcher, ACityOfDistrictsStartsEachDistrictsScmAndLightsOnItsDomainFromOneFile) {
  const auto [up_lights, down_lights] = SmallTownDistrictLights();
  const std::string city =
      Write("city.yaml",
            SmallTownInDistricts() +
                fmt::format("launch:\n  run_dir: {}\n  lights:\n    districts: {{uptown: {}, "
                            "downtown: {}}}\n  sim: {{mode: off}}\n  eye: {{mode: off}}\n"
                            "  traffic: {{mode: off}}\n  dashboard: {{mode: off}}\n  hosts:\n"
                            "    up_host: [lights_uptown, scm_uptown]\n"
                            "    down_host: [lights_downtown, scm_downtown]\n",
                            (dir_ / "run").string(), up_lights, down_lights));
  // The launcher's own domain may be no district's.
  const Output refused =
      RunCaptured({"env", fmt::format("ROS_DOMAIN_ID={}", Uptown()), Bin("autodrive-city"), "up",
                   city, "--host", "up_host", "--partition", partition_});
  EXPECT_EQ(refused.code, 1) << refused.text;
  EXPECT_THAT(
      refused.text,
      HasSubstr(fmt::format("district uptown is on DDS domain {}, this program's own", Uptown())));

  auto up = Up(city, {"--host", "up_host"}, {}, "up_host.log");
  auto down = Up(city, {"--host", "down_host"}, {}, "down_host.log");
  const auto up_status = WaitStatus(*up, AllRunning, seconds(120), "up_host");
  ASSERT_FALSE(up_status.is_null()) << LauncherLog("up_host.log");
  const auto down_status = WaitStatus(*down, AllRunning, seconds(120), "down_host");
  ASSERT_FALSE(down_status.is_null()) << LauncherLog("down_host.log");
  EXPECT_NE(Process(up_status, "scm_uptown"), nullptr);
  EXPECT_NE(Process(down_status, "lights_downtown"), nullptr);

  // Each district's SCM runs its intersection on its domain, where its lights follow it.
  dds::Participant up_domain(dds::ParticipantOptions{Uptown(), partition_, {}});
  dds::Participant down_domain(dds::ParticipantOptions{Downtown(), partition_, {}});
  const auto green_on = [&](dds::Participant& domain, const std::string& intersection) {
    dds::Reader<msg::Spat> spat(domain, dds::topics::Spat().name, dds::Qos::Stream(64));
    for (const auto end = SteadyClock::now() + seconds(60); SteadyClock::now() < end;) {
      spat.WaitForData(milliseconds(100));
      for (const auto& m : spat.TakeAll()) {
        const auto* x = FindIntersection(*m, intersection);
        if (x != nullptr && AnyGreen(*m)) return true;
      }
    }
    return false;
  };
  EXPECT_TRUE(green_on(up_domain, "north_t")) << LauncherLog("up_host.log");
  EXPECT_TRUE(green_on(down_domain, "centre")) << LauncherLog("down_host.log");

  // Killing downtown's SCM: started again at once by its host's launcher, and uptown's SCM,
  // which hears that launcher's table on its own domain, logs the death.
  dds::Reader<msg::Event> up_events(up_domain, dds::topics::Events());
  const int scm = Process(down_status, "scm_downtown")->value("pid", -1);
  ASSERT_GT(scm, 0);
  ::kill(scm, SIGKILL);
  bool logged = false;
  for (const auto end = SteadyClock::now() + seconds(60); !logged && SteadyClock::now() < end;) {
    up_events.WaitForData(milliseconds(100));
    for (const auto& e : up_events.TakeAll()) {
      logged = logged || (dds::View(e->code) == "process_exited" &&
                          dds::View(e->device_id) == "process/scm_downtown");
    }
  }
  EXPECT_TRUE(logged) << "uptown's SCM did not log downtown's SCM's death";
  const auto again = WaitStatus(
      *down,
      [](const nlohmann::json& st) {
        const auto* p = Process(st, "scm_downtown");
        return p != nullptr && p->value("starts", 0) == 2 && p->value("phase", "") == "running";
      },
      seconds(60), "down_host");
  ASSERT_FALSE(again.is_null()) << LauncherLog("down_host.log");
  EXPECT_THAT(LauncherLog("down_host.log"),
              HasSubstr("scm_downtown exited with code 137: starting it again"));
  EXPECT_TRUE(green_on(down_domain, "centre")) << LauncherLog("down_host.log");

  for (const char* host : {"up_host", "down_host"}) {
    const Output out = RunCaptured({Bin("autodrive-city"), "down", city, "--host", host});
    EXPECT_EQ(out.code, 0) << out.text;
  }
  EXPECT_EQ(up->Wait(milliseconds(60000)), std::optional<int>(0)) << LauncherLog("up_host.log");
  EXPECT_EQ(down->Wait(milliseconds(60000)), std::optional<int>(0)) << LauncherLog("down_host.log");
}

TEST_F(Launcher, ABadCityFileIsRefusedBeforeAnyProcessStarts) {
  // A misspelt key in the traffic section: the traffic program would refuse it at its start,
  // after the lights and the SCM; the launcher refuses the whole city first.
  const std::string city = WriteCity("  sim: {mode: off}\n  eye: {mode: off}\n") + "";
  std::ofstream(city, std::ios::app) << "traffic:\n  vehicle: 3\n";
  const Output out = RunCaptured({Bin("autodrive-city"), "up", city, "--partition", partition_});
  EXPECT_EQ(out.code, 1) << out.text;
  EXPECT_THAT(out.text, HasSubstr("traffic.vehicle"));
  EXPECT_FALSE(std::filesystem::exists(dir_ / "run" / "logs")) << out.text;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "run" / "status.json")) << out.text;
}

}  // namespace
}  // namespace autodrive::test
