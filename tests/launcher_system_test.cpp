// autodrive-city with real processes: `up` then `down` leaves nothing behind; a killed SCM is
// started again and the lights come back from flash through the start-up sequence; a mixed
// city starts with a component off; a crash loop is reported; a bad city file is refused
// before any process starts.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <fstream>
#include <set>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/config.h"
#include "tests/scm_processes.h"

namespace autodrive::test {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using ::testing::HasSubstr;

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

  std::unique_ptr<ChildProcess> Up(const std::string& city, std::vector<std::string> extra = {}) {
    std::vector<std::string> argv{Bin("autodrive-city"), "up", city, "--partition", partition_};
    argv.insert(argv.end(), extra.begin(), extra.end());
    ChildOptions options;
    options.output_file = dir_ / "launcher.log";
    return std::make_unique<ChildProcess>(ChildProcess::Start(argv, options));
  }

  nlohmann::json Status() const {
    std::ifstream in(dir_ / "run" / "status.json");
    if (!in) return {};
    try {
      return nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception&) {
      return {};
    }
  }

  // Waits until `pred(status)` holds (generous deadline); gives up when the launcher exits.
  template <typename P>
  nlohmann::json WaitStatus(ChildProcess& launcher, P pred, SteadyClock::duration timeout) {
    const auto end = SteadyClock::now() + timeout;
    for (;;) {
      nlohmann::json s = Status();
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

  std::string LauncherLog() const { return config::ReadFile(dir_ / "launcher.log"); }
};

bool Alive(int pid) { return pid > 0 && (::kill(pid, 0) == 0 || errno != ESRCH); }

TEST_F(Launcher, UpThenDownLeavesNoProcessBehind) {
  const std::string city = WriteCity(
      "  sim: {mode: off}\n  eye: {mode: off}\n  dashboard: {mode: on, listen: "
      "\"127.0.0.1:0\"}\n");
  auto up = Up(city);
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
  EXPECT_THAT(LauncherLog(), HasSubstr("failing is in a crash loop"));
  const Output status = RunCaptured({Bin("autodrive-city"), "status", city});
  EXPECT_THAT(status.text, HasSubstr("crash-loop"));
  up->Stop(milliseconds(60000));
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
