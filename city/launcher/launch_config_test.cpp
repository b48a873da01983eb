// The launch plan of a city file: what `autodrive-city up` would start, in which order, and
// the errors that stop it before anything starts.
#include "city/launcher/launch_config.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>

#include "common/config.h"
#include "common/test_support.h"

namespace autodrive::launcher {
namespace {

using ::testing::HasSubstr;

class Plan : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = std::filesystem::temp_directory_path() /
           ("launch_config_" + std::to_string(::getpid()) + "_" + info->name());
    std::filesystem::create_directories(dir_ / "bin");
    // Stand-ins for the programs: the plan checks only that they are there.
    for (const char* p : {"autodrive-infra", "autodrive-scm", "autodrive-sim", "autodrive-traffic",
                          "autodrive-eye", "autodrive-example-driver"}) {
      std::ofstream(dir_ / "bin" / p) << "";
    }
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // The shipped small town with `extra` appended, written into the test's folder.
  std::filesystem::path City(const std::string& extra) {
    std::string text = config::ReadFile(test::SourceDir() / "config/cities/small_town.yaml");
    const auto replace = [&](const std::string& from, const std::string& to) {
      for (auto at = text.find(from); at != std::string::npos; at = text.find(from, at + 1)) {
        text.replace(at, from.size(), to);
      }
    };
    replace("../maps/", (test::SourceDir() / "config/maps").string() + "/");
    replace("../cameras/", (test::SourceDir() / "config/cameras").string() + "/");
    const auto file = dir_ / "city.yaml";
    std::ofstream(file) << text << "\n" << extra;
    return file;
  }

  std::vector<std::string> Names(const LaunchPlan& plan) {
    std::vector<std::string> out;
    for (const ProcessPlan& p : plan.processes) out.push_back(p.name);
    return out;
  }

  std::string Lights() const {
    return "launch:\n  lights: {config: " +
           (test::SourceDir() / "config/infra/small_town.yaml").string() + "}\n";
  }

  std::filesystem::path dir_;
};

TEST_F(Plan, TheSmallTownStartsLightsScmSimTrafficEyeAndDriverInThatOrder) {
  const LaunchPlan plan = PlanCity(City(Lights()), dir_ / "bin");
  EXPECT_EQ(plan.city_name, "small_town");
  EXPECT_EQ(Names(plan),
            (std::vector<std::string>{"lights", "scm", "sim", "traffic", "eye", "driver"}));
  EXPECT_EQ(plan.processes[0].restart, Restart::kAlways);
  EXPECT_EQ(plan.processes[1].restart, Restart::kAlways);
  EXPECT_EQ(plan.processes[1].ready.kind, Readiness::Kind::kHeartbeat);
  EXPECT_EQ(plan.processes[2].ready.kind, Readiness::Kind::kClock);
  EXPECT_EQ(plan.processes[3].restart, Restart::kOnFailure);
  for (const ProcessPlan& p : plan.processes) {
    EXPECT_EQ(p.log, plan.run_dir / "logs" / (p.name + ".log"));
    EXPECT_TRUE(p.city_program);
  }
}

TEST_F(Plan, AMixedCityLeavesOutWhatIsOff) {
  const LaunchPlan plan =
      PlanCity(City(Lights() + "  sim: {mode: off}\n  eye: {mode: off}\n  traffic: {mode: off}\n"
                               "  run_dir: run\n"),
               dir_ / "bin");
  EXPECT_EQ(Names(plan), (std::vector<std::string>{"lights", "scm"}));
  EXPECT_EQ(plan.run_dir, dir_ / "run");
}

TEST_F(Plan, AgentsComeAfterTheCitysProgramsWithTheirPathsFilledIn) {
  const LaunchPlan plan = PlanCity(
      City(Lights() + "  run_dir: run\n  agents:\n"
                      "    - {name: planner, command: [python3, p.py, '{city}', '{run}/x'], "
                      "restart: always, env: [A=1]}\n"),
      dir_ / "bin");
  const ProcessPlan& a = plan.processes.back();
  EXPECT_EQ(a.name, "planner");
  EXPECT_EQ(a.argv, (std::vector<std::string>{"python3", "p.py", (dir_ / "city.yaml").string(),
                                              (dir_ / "run" / "x").string()}));
  EXPECT_EQ(a.restart, Restart::kAlways);
  EXPECT_EQ(a.env, (std::vector<std::string>{"A=1"}));
  EXPECT_FALSE(a.city_program);
}

TEST_F(Plan, BadFilesAreRefusedWithOneErrorNamingWhere) {
  // A misspelt key in another program's section: refused here, before anything starts.
  {
    const auto f = City(Lights());
    std::string text = config::ReadFile(f);
    text.replace(text.find("\ntraffic:"), 9, "\ntraffic:\n  vehicle: 3");
    std::ofstream(f) << text;
    EXPECT_THAT(test::ErrorMessage<ConfigError>([&] { (void)PlanCity(f, dir_ / "bin"); }),
                HasSubstr("traffic.vehicle"));
  }
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] {
                (void)PlanCity(City(Lights() + "  sim: {mode: sometimes}\n"), dir_ / "bin");
              }),
              HasSubstr("launch.sim.mode"));
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] {
                (void)PlanCity(City(Lights() + "  agents:\n    - {name: scm, command: [x]}\n"),
                               dir_ / "bin");
              }),
              HasSubstr("\"scm\" is taken"));
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] {
                (void)PlanCity(City("launch:\n  lights: {config: /nonexistent/infra.yaml}\n"),
                               dir_ / "bin");
              }),
              HasSubstr("does not exist"));
  EXPECT_THAT(test::ErrorMessage<InputError>([&] {
                std::filesystem::remove(dir_ / "bin" / "autodrive-eye");
                (void)PlanCity(City(Lights()), dir_ / "bin");
              }),
              HasSubstr("autodrive-eye is not there"));
}

}  // namespace
}  // namespace autodrive::launcher
