// The launch plan of a city file: what `autodrive-city up` would start, in which order, and
// the errors that stop it before anything starts.
#include "city/launcher/launch_config.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <map>

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

// Issue 36: a city spread over the lab's hosts, each starting its share with `up --host`.
TEST_F(Plan, LaunchHostsGiveEachHostItsShareInStartOrderWithItsOwnLauncherFiles) {
  const auto file = City(Lights() +
                         "  hosts:\n"
                         "    server: [driver, scm, sim, traffic, eye]\n"
                         "    track: [lights]\n");
  const LaunchPlan whole = PlanCity(file, dir_ / "bin");
  EXPECT_EQ(whole.hosts.size(), 2u);
  EXPECT_EQ(whole.status_file, whole.run_dir / "status.json");
  EXPECT_EQ(whole.pid_file, whole.run_dir / "launcher.pid");
  LaunchPlan server = whole;
  SelectHost(server, "server");
  EXPECT_EQ(Names(server), (std::vector<std::string>{"scm", "sim", "traffic", "eye", "driver"}))
      << "the city's start order, not the list's";
  EXPECT_EQ(server.host, "server");
  EXPECT_EQ(server.status_file, whole.run_dir / "status-server.json");
  EXPECT_EQ(server.pid_file, whole.run_dir / "launcher-server.pid");
  LaunchPlan track = whole;
  SelectHost(track, "track");
  EXPECT_EQ(Names(track), (std::vector<std::string>{"lights"}));
  LaunchPlan all = whole;
  SelectHost(all, "");
  EXPECT_EQ(Names(all), Names(whole)) << "no --host: the whole city on this machine";
  try {
    SelectHost(track, "garage");
    ADD_FAILURE() << "an unknown host was taken";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr("--host garage: launch.hosts has no such host (it has "
                                    "server, track)"));
  }
}

TEST_F(Plan, LaunchHostsMustNameEveryProcessOnceAndNothingElse) {
  const auto refused = [&](const std::string& hosts, const std::string& why) {
    try {
      (void)PlanCity(City(Lights() + "  hosts:\n" + hosts), dir_ / "bin");
      ADD_FAILURE() << "taken: " << hosts;
    } catch (const ConfigError& e) {
      EXPECT_THAT(e.what(), HasSubstr(why)) << hosts;
    }
  };
  refused("    a: [lights, scm, sim, traffic, eye]\n",
          "launch.hosts: no host runs driver (name each process of the city once)");
  refused("    a: [lights, scm, sim, traffic, eye, driver]\n    b: [scm]\n",
          "launch.hosts: scm is on two hosts, a and b");
  refused("    a: [lights, scm, sim, traffic, eye, driver, dashboard]\n",
          "launch.hosts.a: dashboard is not one of the processes this city starts (lights, scm, "
          "sim, traffic, eye, driver;");
  refused("    a: [lights, scm, sim, traffic, eye, drvier]\n",
          "launch.hosts.a: drvier is not one of the processes");
  refused("    \"a b\": [lights, scm, sim, traffic, eye, driver]\n",
          "launch.hosts: host name \"a b\" (letters, digits, '_' and '-' only)");
  try {
    LaunchPlan plan = PlanCity(City(Lights()), dir_ / "bin");
    SelectHost(plan, "track");
    ADD_FAILURE() << "--host taken without launch.hosts";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr("--host track: the city file has no launch.hosts"));
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

TEST_F(Plan, ALockstepCityStartsItsControllersWithTheirNamesAndWaitsForNone) {
  const auto city = [&](const std::string& service) {
    std::string text = config::ReadFile(City(Lights() + "  eye: {mode: off}\n"));
    text.replace(text.find("\nsim:\n"), 6, "\nsim:\n  service: " + service + "\n");
    std::ofstream(dir_ / "city.yaml") << text;
    return dir_ / "city.yaml";
  };
  const LaunchPlan plan =
      PlanCity(city("{mode: lockstep, stages: [[lights], [scm]], controllers: [traffic, driver]}"),
               dir_ / "bin");
  EXPECT_EQ(Names(plan), (std::vector<std::string>{"lights", "scm", "sim", "traffic", "driver"}));
  for (const ProcessPlan& p : plan.processes) {
    EXPECT_EQ(p.ready.kind, Readiness::Kind::kNone) << p.name;
    EXPECT_EQ(p.restart, Restart::kNever) << p.name;
    const bool controller = p.name != "sim";
    EXPECT_EQ(
        p.argv.size() >= 2 && p.argv[p.argv.size() - 2] == "--lockstep" && p.argv.back() == p.name,
        controller)
        << p.name;
  }
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] {
                (void)PlanCity(city("{mode: lockstep, stages: [[lights], [scm]], controllers: "
                                    "[driver, planner]}"),
                               dir_ / "bin");
              }),
              HasSubstr("sim.service: the simulator would wait in lockstep for planner, which "
                        "the launcher does not start"));
}

// A city of districts (docs/districts.md): a light host and an SCM per district, each on the
// district's domain, the rest on the launcher's; each district's light file hosts exactly its
// district's heads.
TEST_F(Plan, ACityOfDistrictsStartsALightHostAndAnScmPerDistrictOnItsDomain) {
  // The small town's lights split by district: north_t's heads 1-3, centre's 4-7.
  const auto write_lights = [&](const std::string& name, const std::string& heads) {
    std::string text = config::ReadFile(test::SourceDir() / "config/infra/small_town.yaml");
    text.replace(text.find("map: ../maps/"), 13,
                 "map: " + (test::SourceDir() / "config/maps").string() + "/");
    text.replace(text.find("heads: [1, 2, 3, 4, 5, 6, 7]"), 28, "heads: " + heads);
    text.replace(text.find("name: small_town_lights"), 23, "name: " + name);
    const auto file = dir_ / (name + ".yaml");
    std::ofstream(file) << text;
    return file.string();
  };
  const std::string up = write_lights("uptown_lights", "[1, 2, 3]");
  const std::string down = write_lights("downtown_lights", "[4, 5, 6, 7]");
  const auto city = [&](const std::string& launch) {
    const auto f = City(launch);
    std::string text = config::ReadFile(f);
    text.insert(text.find("\nfleet:") + 1,
                "districts:\n"
                "  - {name: uptown, domain: 11, intersections: [north_t]}\n"
                "  - {name: downtown, domain: 12, intersections: [centre]}\n");
    std::ofstream(f) << text;
    return f;
  };
  const std::string both =
      "launch:\n  lights:\n    districts: {uptown: " + up + ", downtown: " + down + "}\n";
  const LaunchPlan plan = PlanCity(city(both), dir_ / "bin");
  EXPECT_EQ(Names(plan),
            (std::vector<std::string>{"lights_uptown", "lights_downtown", "scm_uptown",
                                      "scm_downtown", "sim", "traffic", "eye", "driver"}));
  EXPECT_EQ(plan.districts,
            (std::map<std::string, std::uint32_t>{{"uptown", 11}, {"downtown", 12}}));
  const auto process = [&](const std::string& name) -> const ProcessPlan& {
    return *std::ranges::find(plan.processes, name, &ProcessPlan::name);
  };
  const ProcessPlan& lights_up = process("lights_uptown");
  EXPECT_EQ(lights_up.program, "lights");
  EXPECT_EQ(lights_up.argv, (std::vector<std::string>{(dir_ / "bin" / "autodrive-infra").string(),
                                                      "--config", up, "--domain", "11"}));
  EXPECT_EQ(lights_up.ready.sender, "infra/uptown_lights");
  EXPECT_EQ(lights_up.ready.domain, 11u);
  EXPECT_EQ(process("lights_downtown").ready.domain, 12u);
  const ProcessPlan& scm_down = process("scm_downtown");
  EXPECT_EQ(scm_down.program, "scm");
  EXPECT_EQ(scm_down.restart, Restart::kAlways);
  EXPECT_EQ(scm_down.argv,
            (std::vector<std::string>{(dir_ / "bin" / "autodrive-scm").string(), "--config",
                                      (dir_ / "city.yaml").string(), "--district", "downtown",
                                      "--db", (plan.run_dir / "scm_downtown.db").string()}));
  EXPECT_EQ(scm_down.ready.sender, "scm");
  EXPECT_EQ(scm_down.ready.domain, 12u);
  EXPECT_EQ(process("sim").ready.domain, std::nullopt) << "on the launcher's own domain";

  // Each district's share on a host of its own (`up --host uptown`).
  LaunchPlan uptown = PlanCity(
      city(both + "  hosts:\n    uptown: [lights_uptown, scm_uptown]\n"
                  "    downtown: [lights_downtown, scm_downtown]\n    server: [sim, traffic, eye, "
                  "driver]\n"),
      dir_ / "bin");
  SelectHost(uptown, "uptown");
  EXPECT_EQ(Names(uptown), (std::vector<std::string>{"lights_uptown", "scm_uptown"}));
  EXPECT_EQ(uptown.districts.size(), 2u) << "its table goes to every district's SCM";

  // Refused: a district's file that hosts another's head, or is missing; one file for all;
  // a district that is none; lockstep.
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] {
                (void)PlanCity(
                    city("launch:\n  lights:\n    districts: {uptown: " +
                         write_lights("all", "[1, 2, 3, 4]") + ", downtown: " + down + "}\n"),
                    dir_ / "bin");
              }),
              HasSubstr("launch.lights (district uptown): the light host's file " +
                        (dir_ / "all.yaml").string() +
                        " does not match the city (district uptown's heads): it hosts signal_4 "
                        "(centre, E approach), which is district downtown's"));
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] {
                (void)PlanCity(city("launch:\n  lights:\n    districts: {uptown: " + up + "}\n"),
                               dir_ / "bin");
              }),
              HasSubstr("small_town_downtown.yaml of district downtown does not exist (set "
                        "launch.lights.districts.downtown"));
  EXPECT_THAT(
      test::ErrorMessage<ConfigError>([&] { (void)PlanCity(city(Lights()), dir_ / "bin"); }),
      HasSubstr("launch.lights.config: a city of districts has a light host per district"));
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] {
                (void)PlanCity(city("launch:\n  lights:\n    districts: {midtown: " + up + "}\n"),
                               dir_ / "bin");
              }),
              HasSubstr("launch.lights.districts: midtown is not a district (the city has "
                        "uptown, downtown)"));
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] {
                (void)PlanCity(City("launch:\n  lights:\n    districts: {uptown: " + up + "}\n"),
                               dir_ / "bin");
              }),
              HasSubstr("launch.lights.districts: the city has no districts"));
  {
    std::string text = config::ReadFile(city(both));
    text.replace(text.find("\nsim:\n"), 6,
                 "\nsim:\n  service: {mode: lockstep, controllers: [driver]}\n");
    std::ofstream(dir_ / "city.yaml") << text;
    EXPECT_THAT(
        test::ErrorMessage<ConfigError>([&] { (void)PlanCity(dir_ / "city.yaml", dir_ / "bin"); }),
        HasSubstr("sim.service.mode: lockstep is not for a city of districts"));
  }
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

// A lab's first change: west_t made signalised (docs/tutorials/add-an-intersection.md). The
// shipped lights file hosts heads 1..7, which keep their ids; west_t's new heads (8..10) are
// hosted by no one, and the city is refused naming them, as is a lights file that misses one of
// the shipped heads.
TEST_F(Plan, ALightsFileThatDoesNotHostEveryHeadIsRefusedNamingTheHeads) {
  std::string map = config::ReadFile(test::SourceDir() / "config/maps/small_town.yaml");
  const std::string stop = "t@90 control=stop name=west_t";
  ASSERT_NE(map.find(stop), std::string::npos);
  map.replace(map.find(stop), stop.size(), "t@90 control=signal name=west_t");
  std::filesystem::create_directories(dir_ / "maps");
  std::ofstream(dir_ / "maps" / "small_town.yaml") << map;
  const std::string west_t =
      "  - name: west_t\n"
      "    timing: {min_green_s: 5.0, max_green_s: 15.0, yellow_s: 3.0, red_clearance_s: 7.0}\n"
      "    groups:\n"
      "      - {id: 1, name: east, approaches: [east]}\n"
      "      - {id: 2, name: north, approaches: [north]}\n"
      "      - {id: 3, name: south, approaches: [south]}\n"
      "    plans:\n"
      "      - name: day\n"
      "        type: fixed\n"
      "        phases: [{groups: [1], green_s: 8.0}, {groups: [2], green_s: 8.0}, "
      "{groups: [3], green_s: 8.0}]\n"
      "    schedule: [{at: \"00:00\", plan: day}]\n";
  const auto write_lights = [&](const std::string& heads) {
    std::string text = config::ReadFile(test::SourceDir() / "config/infra/small_town.yaml");
    text.replace(text.find("map: ../maps/"), 13, "map: " + (dir_ / "maps").string() + "/");
    text.replace(text.find("heads: [1, 2, 3, 4, 5, 6, 7]"), 28, "heads: " + heads);
    std::ofstream(dir_ / "lights.yaml") << text;
    return "launch:\n  lights: {config: " + (dir_ / "lights.yaml").string() + "}\n";
  };
  const auto city = [&](const std::string& lights) {
    const auto file = City(lights);
    std::string text = config::ReadFile(file);
    text.replace(text.find("map: "), text.find('\n', text.find("map: ")) - text.find("map: "),
                 "map: " + (dir_ / "maps" / "small_town.yaml").string());
    text.insert(text.find("\nfleet:") + 1, west_t);
    std::ofstream(file) << text;
    return file;
  };
  EXPECT_EQ(
      test::ErrorMessage<ConfigError>(
          [&] { (void)PlanCity(city(write_lights("[1, 2, 3, 4, 5, 6, 7]")), dir_ / "bin"); }),
      (dir_ / "city.yaml").string() + ": launch.lights: the light host's file " +
          (dir_ / "lights.yaml").string() +
          " does not match the city: it does not host signal_8 (west_t, E approach), signal_9 "
          "(west_t, N approach), signal_10 (west_t, S approach) (add them to its heads). Head ids "
          "are the map's heads= (autodrive-map info lists them); set launch.lights.mode: off "
          "when the lights run on other hosts");
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] {
                (void)PlanCity(city(write_lights("[1, 2, 3, 4, 6, 7, 8, 9, 10]")), dir_ / "bin");
              }),
              HasSubstr("it does not host signal_5 (centre, N approach) (add it to its heads)"));
  const LaunchPlan plan =
      PlanCity(city(write_lights("[1, 2, 3, 4, 5, 6, 7, 8, 9, 10]")), dir_ / "bin");
  EXPECT_EQ(Names(plan).front(), "lights");
}

}  // namespace
}  // namespace autodrive::launcher
