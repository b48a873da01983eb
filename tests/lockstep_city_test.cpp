// The city in lockstep with real processes: the simulator, the light host and the SCM as staged
// controllers (the lights first, then the SCM, common/dds/lockstep.h "Stages"), the example
// driver as a plain one. Two runs with the same seed give the same cars' log and the same SPaT,
// byte for byte, with the signals running (start-up, then greens), and every process ends with
// the simulator's end; `autodrive-city up` runs such a city to its end and exits by itself.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <cerrno>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>

#include <nlohmann/json.hpp>

#include "common/config.h"
#include "tests/scm_processes.h"

namespace autodrive::test {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

class LockstepCity : public ScmProcesses {
 protected:
  // The Driving School with a simulator section of the test's own: lockstep, the paper's noise.
  std::string WriteLockstepCity() const {
    std::string text = CityText("driving_school");
    text.erase(text.find("\nsim:"));
    text +=
        "\nsim:\n  seed: 5\n  variability: {preset: paper}\n"
        "  service: {mode: lockstep, stages: [[lights], [scm]], controllers: [driver]}\n"
        "  vehicles:\n    - {name: nigel_1}\n    - {name: nigel_2}\n";
    return Write("lockstep_city.yaml", text);
  }

  struct RunResult {
    std::string log;   // the simulator's log of the cars
    std::string spat;  // every SPaT, one line each: stamp and each group's state and end times
    int greens = 0;    // SPaT lines with a green
  };

  // One run on a partition of its own: lights and SCM first (the SCM's MAP says it is up), then
  // the driver and the simulator for `duration_s` simulated seconds.
  RunResult RunOnce(const std::string& name, const std::string& city, int duration_s) {
    const std::string partition = partition_ + "_" + name;
    dds::Participant participant(dds::ParticipantOptions{{}, partition, {}});
    dds::Reader<msg::Spat> spat(participant, dds::topics::Spat().name, dds::Qos::Stream(100000));
    dds::Reader<msg::MapData> map(participant, dds::topics::Map());
    ChildProcess lights({Bin("autodrive-infra"), "--config",
                         Config("config/infra/driving_school.yaml"), "--partition", partition,
                         "--lockstep", "lights", "--log-level", "warn"});
    // At simulated time 0 it is 00:00 UTC: the schedule's evening plan (actuated) runs.
    ChildProcess scm({Bin("autodrive-scm"), "--config", city, "--partition", partition, "--db",
                      (dir_ / (name + ".db")).string(), "--lockstep", "scm", "--log-level", "warn"},
                     {"TZ=UTC"});
    dds::Message<msg::MapData> m;
    const auto end = SteadyClock::now() + seconds(120);
    while (!map.TakeOne(m) && SteadyClock::now() < end) (void)map.WaitForData(milliseconds(200));
    EXPECT_LT(SteadyClock::now(), end) << name << ": no MAP from the SCM";
    const std::string log = (dir_ / (name + ".csv")).string();
    ChildProcess driver({Bin("autodrive-example-driver"), "--city", city, "--partition", partition,
                         "--lockstep", "driver", "--log-level", "warn"});
    ChildProcess sim({Bin("autodrive-sim"), "--city", city, "--partition", partition, "--duration",
                      std::to_string(duration_s), "--log", log, "--log-level", "warn"});
    EXPECT_EQ(sim.Wait(milliseconds(600'000)), std::optional<int>(0)) << name;
    for (ChildProcess* p : {&driver, &scm, &lights}) {
      EXPECT_EQ(p->Wait(milliseconds(60'000)), std::optional<int>(0))
          << name << ": a controller ends with the simulator";
    }
    RunResult r;
    std::ifstream in(log, std::ios::binary);
    r.log.assign(std::istreambuf_iterator<char>(in), {});
    dds::Message<msg::Spat> s;
    while (spat.TakeOne(s)) {
      std::string line = fmt::format("{}.{:09d}", s->header.stamp.sec, s->header.stamp.nanosec);
      bool green = false;
      for (const auto& x : dds::Elements(s->intersections)) {
        for (const auto& g : dds::Elements(x.signal_groups)) {
          line += fmt::format(" {}:{}:{}.{:09d}:{}.{:09d}", g.signal_group, g.event_state,
                              g.min_end_time.sec, g.min_end_time.nanosec, g.max_end_time.sec,
                              g.max_end_time.nanosec);
          green = green || IsGreen(g.event_state);
        }
      }
      r.spat += line + "\n";
      r.greens += green ? 1 : 0;
    }
    return r;
  }
};

TEST_F(LockstepCity, TwoRunsWithTheSameSeedGiveTheSameCarsAndTheSameSpat) {
  const std::string city = WriteLockstepCity();
  const RunResult a = RunOnce("first", city, 25);
  const RunResult b = RunOnce("second", city, 25);
  // 2,501 control periods of two cars, and a header.
  EXPECT_EQ(std::count(a.log.begin(), a.log.end(), '\n'), 1 + 2 * 2501);
  EXPECT_TRUE(a.log == b.log) << "the two runs' cars differ";
  // SPaT at 10 Hz of simulated time: about 250 messages, the same in both runs.
  EXPECT_GE(std::count(a.spat.begin(), a.spat.end(), '\n'), 240) << a.spat;
  EXPECT_EQ(a.spat, b.spat);
  // Start-up (flash 3 s, all red 7 s) is over well before 25 s: the plan's greens came.
  EXPECT_GT(a.greens, 0) << a.spat;
}

// `autodrive-city up` of a city in lockstep (5 simulated seconds): it starts each controller
// with its name, and exits 0 by itself once every process ended with the run, leaving none.
TEST_F(LockstepCity, UpRunsALockstepCityToTheSimulatorsEndAndExitsByItself) {
  std::string text = config::ReadFile(WriteLockstepCity());
  text.replace(text.find("controllers: [driver]}"), 22, "controllers: [driver], duration_s: 5}");
  text += "launch:\n  run_dir: " + (dir_ / "run").string() +
          "\n  lights: {config: " + Config("config/infra/driving_school.yaml") +
          "}\n  eye: {mode: off}\n  dashboard: {mode: off}\n";
  const std::string city = Write("up.yaml", text);
  const Output up = RunCaptured({Bin("autodrive-city"), "up", city, "--partition", partition_});
  EXPECT_EQ(up.code, 0) << up.text;
  EXPECT_THAT(up.text, ::testing::HasSubstr("--lockstep lights"));
  EXPECT_THAT(up.text, ::testing::HasSubstr("--lockstep scm"));
  EXPECT_THAT(up.text, ::testing::HasSubstr("--lockstep driver"));
  EXPECT_THAT(up.text,
              ::testing::HasSubstr("sim exited with code 0: not started again (restart: never)"));
  EXPECT_THAT(up.text, ::testing::HasSubstr("every process ended and none is to be started again"));
  const nlohmann::json status =
      nlohmann::json::parse(config::ReadFile(dir_ / "run" / "status.json"));
  for (const auto& p : status.at("processes")) {
    EXPECT_EQ(p.value("phase", ""), "stopped") << p.dump();
    EXPECT_EQ(p.value("last_exit", -1), 0) << p.dump();
  }
  // Every process `up` started ("NAME is up (pid N)") is gone.
  const std::regex started("is up \\(pid ([0-9]+)\\)");
  int pids = 0;
  for (auto it = std::sregex_iterator(up.text.begin(), up.text.end(), started);
       it != std::sregex_iterator(); ++it, ++pids) {
    const int pid = std::stoi((*it)[1].str());
    EXPECT_TRUE(::kill(pid, 0) != 0 && errno == ESRCH) << "pid " << pid << " is still there";
  }
  EXPECT_EQ(pids, 4) << up.text;
}

}  // namespace
}  // namespace autodrive::test
