// The V2I examples (examples/: follower, GLOSA, emergency, transit) and the paper's two case
// studies (parking on the car's own localisation, behavioural cloning) driving their shipped
// scenarios through the scenario runner, judged by its metrics (docs/scenarios.md), never by
// what the agents say: each on the public topics only, against the real SCM, lights, simulator
// and SUMO, in lockstep. The sweeps over 20 seeds behind examples/README.md's figures are not
// run here (minutes each); one seed of each is.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/config.h"
#include "common/process.h"
#include "common/test_support.h"

namespace autodrive {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using std::chrono::milliseconds;

std::string Bin(const std::string& name) {
  const char* dir = std::getenv("AUTODRIVE_BINARY_DIR");
  return std::string(dir ? dir : ".") + "/bin/" + name;
}

struct Outcome {
  int code = -1;
  std::string output;
  json report;
  json run;  ///< the report's run metrics
  std::string agent_log;
};

class V2iExamples : public ::testing::Test {
 protected:
  // The shipped scenario `name`, its city found from the test's folder, `edit` applied.
  Outcome RunShipped(const std::string& name, const std::function<void(std::string&)>& edit = {},
                     const std::vector<std::string>& env = {}) {
    std::string text = config::ReadFile(test::SourceDir() / "config/scenarios" / (name + ".yaml"));
    text.replace(text.find("city: ../cities/"), 16,
                 "city: " + (test::SourceDir() / "config/cities/").string());
    if (edit) edit(text);
    const fs::path file = dir_.path() / (name + ".yaml");
    config::WriteFile(file, text);
    const fs::path out = dir_.path() / name;
    std::vector<std::string> environment = env;
    environment.push_back(fmt::format("AUTODRIVE_TEST_TAG={}", dir_.str()));
    ChildProcess p(
        {Bin("autodrive-scenario"), "run", file.string(), "--out", out.string(), "--quiet"},
        environment);
    Outcome r;
    while (auto line = p.ReadLine(milliseconds(600'000))) r.output += *line + "\n";
    r.code = p.Wait(milliseconds(60'000)).value_or(-1);
    if (fs::exists(out / "report.json")) {
      r.report = json::parse(config::ReadFile(out / "report.json"));
      r.run = r.report["metrics"]["run"];
    }
    if (fs::exists(out / "run/logs/agent_nigel_1.log")) {
      r.agent_log = config::ReadFile(out / "run/logs/agent_nigel_1.log");
    }
    return r;
  }

  test::TempDir dir_{"v2i_examples"};
};

// The follower on MAP and SPaT through the Driving School's crossing twice, among SUMO's cars,
// with the paper's noise: no collision, no red run, its goal reached.
TEST_F(V2iExamples, TheFollowerDrivesTheFigureOfEightOnSpatWithoutAnInfraction) {
  const Outcome r = RunShipped("v2i_follower_driving_school");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.run["collisions"], 0) << r.run.dump();
  EXPECT_EQ(r.run["red_light_violations"], 0);
  EXPECT_EQ(r.run["stop_sign_violations"], 0);
  EXPECT_GE(r.run["route_completion"].get<double>(), 0.99);
  EXPECT_GE(r.run["background_trips"].get<int>(), 1) << "SUMO's cars drove beside it";
  EXPECT_EQ(r.agent_log.find("off the lanes"), std::string::npos) << r.agent_log;
}

// GLOSA and the follower on the same seed and fixed-time plan: GLOSA stands for less time and
// stops no more often; both without an infraction.
TEST_F(V2iExamples, GlosaStandsLessThanTheFollowerOnTheSameSeed) {
  // Logging at debug level: GLOSA says when it advises.
  const auto debug = [](std::string& text) {
    text.replace(text.find("--log-level, info]"), 18, "--log-level, debug]");
  };
  const Outcome glosa = RunShipped("v2i_glosa_driving_school", debug);
  const Outcome follower = RunShipped("v2i_glosa_driving_school", [&](std::string& text) {
    debug(text);
    const std::string program = "command: [autodrive-example-glosa";
    text.replace(text.find(program), program.size(), "command: [autodrive-example-follower");
  });
  ASSERT_EQ(glosa.code, 0) << glosa.output;
  ASSERT_EQ(follower.code, 0) << follower.output;
  EXPECT_NE(glosa.agent_log.find("advising"), std::string::npos) << glosa.agent_log;
  EXPECT_EQ(follower.agent_log.find("advising"), std::string::npos);
  EXPECT_LT(glosa.run["stopped_time_s"].get<double>(), follower.run["stopped_time_s"].get<double>())
      << "GLOSA " << glosa.run.dump() << "\nfollower " << follower.run.dump();
  EXPECT_LE(glosa.run["stops"].get<int>(), follower.run["stops"].get<int>());
  for (const Outcome* r : {&glosa, &follower}) {
    EXPECT_EQ(r->run["red_light_violations"], 0);
    EXPECT_EQ(r->run["collisions"], 0);
  }
}

// The emergency vehicle asks each of the two signals on its way for pre-emption (MAP lane ids
// from the MAP), the SCM grants them, and it cancels what is still standing once through; the
// runner counts the requests from the SCM's answers, not from the agent.
TEST_F(V2iExamples, TheEmergencyVehicleAsksEachSignalOnItsWayAndCancelsOnceThrough) {
  const Outcome r = RunShipped("v2i_emergency_small_town");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.run["red_light_violations"], 0);
  EXPECT_GE(r.run["requests"].get<int>(), 2) << r.run.dump();
  const json& requests = r.report["metrics"]["v2i"]["requests"];
  ASSERT_TRUE(requests.is_array()) << r.report["metrics"]["v2i"].dump();
  ASSERT_GE(requests.size(), 2U);
  for (const json& q : requests) {
    EXPECT_EQ(q["type"], "preemption") << q.dump();
    // Served (its green came, by the lamps), then completed by the SCM or cancelled by the car.
    EXPECT_TRUE(q["to_green_s"].is_number()) << q.dump();
    EXPECT_TRUE(q["outcome"] == "completed" || q["outcome"] == "cancelled") << q.dump();
  }
  // What is still standing once through is cancelled by the car and confirmed by the SCM; what
  // the SCM completed first (the car took longer than the end it announced) is not cancelled
  // again. Which of the two a request meets depends on where the signals are in their cycle
  // when the car comes (the SCM's start-up, its cycle), not on the car's logic.
  const int completed = r.report["metrics"]["v2i"]["request_outcomes"]["completed"].get<int>();
  const int cancelled = r.report["metrics"]["v2i"]["request_outcomes"]["cancelled"].get<int>();
  EXPECT_EQ(completed + cancelled, static_cast<int>(requests.size()));
  EXPECT_NE(r.agent_log.find(fmt::format("cancels {}; answers:", cancelled)), std::string::npos)
      << r.agent_log;
  EXPECT_NE(r.agent_log.find(fmt::format("completed {}, cancelled {}", completed, cancelled)),
            std::string::npos)
      << r.agent_log;
}

// The bus asks for priority, not pre-emption, and the SCM serves it.
TEST_F(V2iExamples, TheBusAsksEachSignalOnItsWayForPriority) {
  const Outcome r = RunShipped("v2i_transit_small_town");
  ASSERT_EQ(r.code, 0) << r.output;
  const json& requests = r.report["metrics"]["v2i"]["requests"];
  ASSERT_TRUE(requests.is_array());
  ASSERT_GE(requests.size(), 2U) << requests.dump();
  for (const json& q : requests) {
    EXPECT_EQ(q["type"], "priority") << q.dump();
    EXPECT_TRUE(q["to_green_s"].is_number()) << q.dump();
  }
}

// The parking agent on its own localisation (SLAM maps the school standing at the first ips fix,
// then a particle filter on encoders, imu and LIDAR localises against that map): parked by the
// runner's judgement with no contact and no lane departure (the school is an open floor), its
// estimates traced each step and SLAM's map written in map_server's format as it stops.
TEST_F(V2iExamples, TheParkingAgentDrivesOnItsOwnLocalisationAndWritesSlamsMap) {
  const Outcome r = RunShipped("parking_school_pf");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.run["goals_reached"], 1) << r.output;
  EXPECT_EQ(r.run["collisions"], 0) << r.output;
  EXPECT_EQ(r.run["lane_departures"], 0) << r.output;
  EXPECT_NE(r.agent_log.find("occupied cells standing at its first fix"), std::string::npos)
      << r.agent_log;
  const fs::path run = dir_.path() / "parking_school_pf" / "run";
  EXPECT_GT(config::ReadFile(run / "localisation.csv").size(), 1000u);
  EXPECT_TRUE(fs::exists(run / "slam.pgm"));
  EXPECT_TRUE(fs::exists(run / "slam.yaml"));
  EXPECT_NE(r.agent_log.find("SLAM's map: "), std::string::npos) << r.agent_log;
}

// Behavioural cloning end to end on the real programs: a lap recorded, a model trained on it for
// an epoch, and the agent driving from the front camera in the shipped scenario (one lap, 40 s):
// every frame reaches the network and the car moves.
TEST_F(V2iExamples, TheCloningAgentDrivesFromItsFrontCamera) {
  const std::string lap = (dir_.path() / "lap").string();
  const std::string model = (dir_.path() / "model.pt").string();
  const auto run = [](const std::vector<std::string>& argv) {
    ChildProcess p(argv, {});
    std::string text;
    while (auto line = p.ReadLine(milliseconds(600'000))) text += *line + "\n";
    return std::pair{p.Wait(milliseconds(60'000)).value_or(-1), text};
  };
  const auto [record, record_text] = run(
      {Bin("autodrive-sim"), "record", "--city",
       (test::SourceDir() / "config/cities/driving_school.yaml").string(), "--route",
       "r2c0:N>E:0,r2c1:W>E:0,r2c3:W>E:0,r2c4:W>S:0,r3c4:N>S:0,r4c4:N>W:0,r4c3:E>W:0,r4c2:E>N:0,"
       "r3c2:S>N:0,r1c2:S>N:0,r0c2:S>W:0,r0c1:E>W:0,r0c0:E>S:0,r1c0:N>S:0",
       "--seed", "101", "--out", lap, "--quiet"});
  ASSERT_EQ(record, 0) << record_text;
  const auto [train, train_text] = run({Bin("autodrive-example-cloning-train"), "--data", lap,
                                        "--epochs", "1", "--out", model, "--threads", "1"});
  ASSERT_EQ(train, 0) << train_text;
  EXPECT_NE(train_text.find("epoch 1: training loss"), std::string::npos) << train_text;
  const Outcome r =
      RunShipped("cloning_driving_school",
                 [](std::string& text) {
                   text.replace(text.find("time_limit_s: 560"), 17, "time_limit_s: 40");
                   text.replace(text.find("laps: 5"), 7, "laps: 1");
                 },
                 {"AUTODRIVE_CLONING_MODEL=" + model});
  EXPECT_TRUE(r.code == 0 || r.code == 1) << r.output;
  EXPECT_EQ(r.report["end"]["reason"], "time_limit") << r.output;
  EXPECT_GT(r.run["distance_m"].get<double>(), 2.0) << r.run.dump();
  // 15 frames a second for 40 s, each through the network.
  const std::size_t at = r.agent_log.find(" frames through the network");
  ASSERT_NE(at, std::string::npos) << r.agent_log;
  const std::size_t from = r.agent_log.rfind(' ', at - 1) + 1;
  EXPECT_GE(std::stoi(r.agent_log.substr(from, at - from)), 590) << r.agent_log;
}

}  // namespace
}  // namespace autodrive
