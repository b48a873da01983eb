// The scenario file's refusals (file, line and key), the composed city, and each metric on logs
// written by hand, against values worked out by hand.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <numbers>

#include "scenarios/compose.h"
#include "scenarios/metrics.h"
#include "scenarios/scenario.h"
#include "scenarios/sweep.h"

#include "common/config.h"
#include "common/error.h"
#include "common/test_support.h"
#include "maps/map_io.h"

namespace autodrive::scenarios {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string Refusal(const fs::path& file) {
  try {
    (void)LoadScenario(file);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(loaded)";
}

// A scenario file in `dir` whose city is the shipped Driving School, with `body` after it.
fs::path Write(const fs::path& dir, const std::string& body) {
  const fs::path file = dir / "s.yaml";
  config::WriteFile(
      file, fmt::format("name: s\ncity: {}\n{}",
                        (test::SourceDir() / "config/cities/driving_school.yaml").string(), body));
  return file;
}

const char* const kCar = R"(vehicles:
  - name: nigel_1
    spawn: {lane: "r2c0:N>E:0", along_m: 0.3}
    route: ["r2c0:N>E:0", "r2c1:W>E:0", "r2c3:W>E:0"]
    agent: {driver: []}
)";

TEST(ScenarioFile, RefusalsNameTheFileLineAndKey) {
  test::TempDir dir("scenario_file");
  EXPECT_EQ(Refusal(Write(dir.path(), kCar)), "(loaded)");
  const auto refused = [&](const std::string& body, const std::string& expected) {
    const fs::path file = Write(dir.path(), body);
    const std::string what = Refusal(file);
    EXPECT_NE(what.find(file.string() + ":"), std::string::npos) << what;
    EXPECT_NE(what.find(expected), std::string::npos) << what;
  };
  refused(std::string(kCar) + "speed: 3\n", ":8:1: speed: unknown key");
  refused(std::string(kCar) + "expect: {collisons: \"== 0\"}\n",
          "expect: collisons is not a run metric");
  refused(std::string(kCar) + "expect: {collisions: \"about 0\"}\n",
          "expect.collisions: \"about 0\" is not a comparison");
  refused(std::string(kCar) + "events: [{at_s: 3, action: mode, intersection: x}]\n",
          "events[0]: action mode needs mode");
  refused(std::string(kCar) +
              "events: [{at_s: 3, action: preempt, intersection: x, vehicle: nigel_9}]\n",
          "vehicle nigel_9 is not one of the scenario's cars");
  // Faults on a light head: the head, the lamp and the fault, and nothing of another action.
  refused(std::string(kCar) + "events: [{at_s: 3, action: lamp, lamp: red, fault: burnt_out}]\n",
          "events[0]: action lamp needs head");
  refused(std::string(kCar) + "events: [{at_s: 3, action: lamp, head: 2, lamp: red}]\n",
          "events[0]: action lamp needs fault");
  refused(std::string(kCar) + "events: [{at_s: 3, action: unplug, head: 2, intersection: x}]\n",
          "events[0]: action unplug takes no intersection");
  refused(std::string(kCar) + "events: [{at_s: 3, action: lamp, head: 2, lamp: blue}]\n",
          "events[0].lamp");
  refused(std::string(kCar) +
              "events: [{at_s: 3, action: mode, intersection: x, mode: flash, head: 2}]\n",
          "events[0]: action mode takes no head");
  refused(std::string(kCar) + "events: [{at_s: 3, action: link_cut}]\n",
          "events[0]: action link_cut needs host");
  refused(std::string(kCar) + "events: [{at_s: 3, action: link_cut, host: h, head: 2}]\n",
          "events[0]: action link_cut takes no head");
  refused(std::string(kCar) + "events: [{at_s: 3, action: unplug, head: 2, host: h}]\n",
          "events[0]: action unplug takes no host");
  // Obstacles placed and removed: by name, once each, removed after placed; their times are
  // the events'.
  const std::string box = "obstacles: [{name: box, x_m: 1, y_m: 2}]\n";
  refused(std::string(kCar) + box + "events: [{at_s: 3, action: place}]\n",
          "events[0]: action place needs obstacle");
  refused(std::string(kCar) + box + "events: [{at_s: 3, action: place, obstacle: bx}]\n",
          "events: obstacle bx is not one of the scenario's named obstacles (box)");
  refused(std::string(kCar) + box +
              "events: [{at_s: 3, action: place, obstacle: box}, {at_s: 4, action: place, "
              "obstacle: box}]\n",
          "obstacle box is placed twice");
  refused(std::string(kCar) + box +
              "events: [{at_s: 3, action: place, obstacle: box}, {at_s: 2, action: remove, "
              "obstacle: box}]\n",
          "obstacle box is removed at 2 s, not after it is placed at 3 s");
  refused(std::string(kCar) + "obstacles: [{name: box, x_m: 1, y_m: 2, from_s: 3}]\n",
          "obstacles[0]: from_s and until_s are set by place and remove events");
  refused(
      std::string(kCar) + "obstacles: [{name: box, x_m: 1, y_m: 2}, {name: box, x_m: 2, y_m: 2}]\n",
      "obstacles: box is listed twice");
  refused(std::string(kCar) + box + "events: [{at_s: 3, action: remove, obstacle: box, head: 2}]\n",
          "events[0]: action remove takes no head");
  // A demand surge: where, how fast and how many; nothing of another action.
  refused(std::string(kCar) + "events: [{at_s: 3, action: surge, from: a, per_hour: 600}]\n",
          "events[0]: action surge needs count");
  refused(std::string(kCar) +
              "events: [{at_s: 3, action: surge, from: a, per_hour: 600, count: 5, vehicle: "
              "nigel_1}]\n",
          "events[0]: action surge takes no vehicle");
  refused(std::string(kCar) + "events: [{at_s: 3, action: place, obstacle: box, to: a}]\n",
          "events[0]: action place takes no to");
  // A trigger: a car of the scenario; none for what the simulator or SUMO apply.
  refused(std::string(kCar) +
              "events: [{action: mode, intersection: x, mode: flash, when: "
              "{vehicle: nigel_7, x_m: 1, y_m: 2}}]\n",
          "events: vehicle nigel_7 is not one of the scenario's cars");
  refused(std::string(kCar) + box +
              "events: [{action: place, obstacle: box, when: {vehicle: nigel_1, x_m: 1, y_m: "
              "2}}]\n",
          "events[0]: action place takes no when");
  refused(std::string(kCar) +
              "events: [{action: mode, intersection: x, mode: flash, when: "
              "{vehicle: nigel_1, x_m: 1}}]\n",
          "events[0].when.y_m: missing required key");
  // A camera lost and back: once each, back after lost.
  refused(std::string(kCar) + "events: [{at_s: 3, action: camera_lost}]\n",
          "events[0]: action camera_lost needs camera");
  refused(std::string(kCar) +
              "events: [{at_s: 3, action: camera_lost, camera: o}, {at_s: 5, action: "
              "camera_lost, camera: o}]\n",
          "events: camera o is lost twice");
  refused(std::string(kCar) +
              "events: [{at_s: 3, action: camera_lost, camera: o}, {at_s: 2, action: "
              "camera_back, camera: o}]\n",
          "events: camera o comes back at 2 s, not after it is lost at 3 s");
  refused(std::string(kCar) + "events: [{at_s: 3, action: camera_back, camera: o}]\n",
          "events: camera o comes back but is never lost");
  refused("vehicles:\n  - {name: car_1, spawn: {lane: a}}\n",
          "vehicles[0]: name: \"car_1\" is not nigel_<n>");
  refused(std::string(kCar) + "  - name: nigel_1\n    spawn: {lane: a}\n",
          "nigel_1 is listed twice");
  refused(std::string(kCar) + "vehicles: []\n", "duplicate key");
  config::WriteFile(dir.path() / "s.yaml", std::string("name: s\ncity: nowhere.yaml\n") + kCar);
  EXPECT_NE(Refusal(dir.path() / "s.yaml").find(":2:"), std::string::npos)
      << Refusal(dir.path() / "s.yaml");
}

TEST(ScenarioFile, Expectations) {
  EXPECT_TRUE(ParseExpectation("== 0").Holds(0));
  EXPECT_FALSE(ParseExpectation("== 0").Holds(1));
  EXPECT_TRUE(ParseExpectation(">= 0.95").Holds(1.0));
  EXPECT_FALSE(ParseExpectation("<3").Holds(3));
  EXPECT_TRUE(ParseExpectation(" != 2 ").Holds(3));
  EXPECT_FALSE(ParseExpectation("<= 1").Holds(std::nan("")));
  EXPECT_THROW((void)ParseExpectation("= 1"), InputError);
  EXPECT_THROW((void)ParseExpectation(">= x"), InputError);
  EXPECT_THROW((void)ParseExpectation(">= 1 m"), InputError);
}

std::string ComposeRefusal(const std::string& body) {
  test::TempDir dir("scenario_compose");
  const fs::path file = Write(dir.path(), body);
  const Scenario s = LoadScenario(file);
  const maps::Map map =
      maps::LoadMapOrLayout((test::SourceDir() / "config/maps/driving_school.yaml").string());
  try {
    (void)ComposeCity(s, file, map, dir.path() / "city.yaml", dir.path() / "run",
                      dir.path() / "logs", dir.path());
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(composed)";
}

TEST(ComposedCity, RoutesAndEventsAreCheckedAgainstTheMapAndCity) {
  EXPECT_EQ(ComposeRefusal(kCar), "(composed)");
  // A route whose lanes do not follow each other, a lane the map has not, an intersection it
  // has not, a plan the city has not: each named at its line.
  std::string wrong = kCar;
  wrong.replace(wrong.find("\"r2c1:W>E:0\", "), 14, "");
  EXPECT_NE(ComposeRefusal(wrong).find(":6:"), std::string::npos) << ComposeRefusal(wrong);
  EXPECT_NE(ComposeRefusal(wrong).find("lane r2c3:W>E:0 does not follow r2c0:N>E:0"),
            std::string::npos);
  std::string unknown = kCar;
  unknown.replace(unknown.find("r2c3:W>E:0"), 10, "r9c9:W>E:0");
  EXPECT_NE(ComposeRefusal(unknown).find("vehicles[0].route[2]: map driving_school has no lane"),
            std::string::npos)
      << ComposeRefusal(unknown);
  EXPECT_NE(ComposeRefusal(std::string(kCar) +
                           "events: [{at_s: 3, action: mode, intersection: x, mode: flash}]\n")
                .find("events[0].intersection: map driving_school has no intersection \"x\""),
            std::string::npos);
  EXPECT_NE(
      ComposeRefusal(std::string(kCar) + "events: [{at_s: 3, action: link_cut, host: lights}]\n")
          .find("events[0].host: the city's light host is \"driving_school_lights\""),
      std::string::npos)
      << ComposeRefusal(std::string(kCar) +
                        "events: [{at_s: 3, action: link_cut, host: lights}]\n");
  EXPECT_NE(ComposeRefusal(std::string(kCar) + "events: [{at_s: 3, action: unplug, head: 9}]\n")
                .find("events[0].head: map driving_school has no signal head 9"),
            std::string::npos)
      << ComposeRefusal(std::string(kCar) + "events: [{at_s: 3, action: unplug, head: 9}]\n");
  EXPECT_NE(ComposeRefusal(std::string(kCar) + "events: [{at_s: 3, action: plan, intersection: "
                                               "driving_school_crossing, plan: rush}]\n")
                .find("has no plan \"rush\""),
            std::string::npos);
  const std::string surge = std::string(kCar) +
                            "events: [{at_s: 3, action: surge, from: r9c9:W>E:0, per_hour: 600, "
                            "count: 5}]\n";
  EXPECT_NE(
      ComposeRefusal(surge).find("events[0].from: map driving_school has no lane \"r9c9:W>E:0\""),
      std::string::npos)
      << ComposeRefusal(surge);
  const std::string tram = std::string(kCar) +
                           "events: [{at_s: 3, action: surge, from: r2c0:N>E:0, per_hour: 600, "
                           "count: 5, type: tram}]\n";
  EXPECT_NE(ComposeRefusal(tram).find("events[0].type: SUMO type \"tram\" is not one of"),
            std::string::npos)
      << ComposeRefusal(tram);
  const std::string camera =
      std::string(kCar) + "events: [{at_s: 3, action: camera_lost, camera: top}]\n";
  EXPECT_NE(ComposeRefusal(camera).find("events[0].camera:"), std::string::npos)
      << ComposeRefusal(camera);
  EXPECT_NE(ComposeRefusal(camera).find("has no overhead camera \"top\" (it has: overhead)"),
            std::string::npos)
      << ComposeRefusal(camera);
  EXPECT_EQ(ComposeRefusal(std::string(kCar) + "eye: true\n"
                                               "events: [{at_s: 3, action: camera_lost, camera: "
                                               "overhead}, {at_s: 5, action: camera_back, camera: "
                                               "overhead}]\n"),
            "(composed)");
  // Laps of a route that does not close (r2c0 does not follow r2c3) are refused; the figure of
  // eight closes.
  std::string open_laps = kCar;
  open_laps.replace(open_laps.find("    agent:"), 0, "    laps: 2\n");
  EXPECT_NE(ComposeRefusal(open_laps).find("does not follow r2c3:W>E:0 (neither a successor nor "
                                           "the end of a movement from it): laps need a closed "
                                           "route"),
            std::string::npos)
      << ComposeRefusal(open_laps);
  EXPECT_EQ(ComposeRefusal(R"(vehicles:
  - name: nigel_1
    spawn: {lane: "r2c0:N>E:0", along_m: 0.3}
    route: ["r2c0:N>E:0", "r2c1:W>E:0", "r2c3:W>E:0", "r2c4:W>S:0", "r3c4:N>S:0", "r4c4:N>W:0",
            "r4c3:E>W:0", "r4c2:E>N:0", "r3c2:S>N:0", "r1c2:S>N:0", "r0c2:S>W:0", "r0c1:E>W:0",
            "r0c0:E>S:0", "r1c0:N>S:0"]
    laps: 3
    agent: {driver: []}
)"),
            "(composed)");
  // Obstacle events name no intersection: they compose.
  EXPECT_EQ(
      ComposeRefusal(std::string(kCar) + "obstacles: [{name: box, x_m: 3.5, y_m: 2.35}]\n"
                                         "events: [{at_s: 3, action: place, obstacle: box}]\n"),
      "(composed)");
}

TEST(ComposedCity, EveryShippedScenarioLoadsAndComposes) {
  int scenarios = 0;
  for (const auto& e : fs::directory_iterator(test::SourceDir() / "config/scenarios")) {
    if (e.path().extension() != ".yaml") continue;
    SCOPED_TRACE(e.path().string());
    const YAML::Node node = YAML::LoadFile(e.path().string());
    if (node["scenario"]) {  // a sweep names its scenario (its variants are optional)
      EXPECT_NO_THROW((void)LoadSweep(e.path()));
      continue;
    }
    const Scenario s = LoadScenario(e.path());
    const YAML::Node city = YAML::LoadFile(s.city);
    const maps::Map map = maps::LoadMapOrLayout(
        (fs::path(s.city).parent_path() / city["map"].as<std::string>()).string());
    test::TempDir dir("scenario_shipped");
    EXPECT_NO_THROW((void)ComposeCity(s, e.path(), map, dir.path() / "city.yaml",
                                      dir.path() / "run", dir.path() / "logs", dir.path()));
    ++scenarios;
  }
  EXPECT_GE(scenarios, 14);
}

TEST(ComposedCity, TheEyeInTheLoopAndACameraLost) {
  test::TempDir dir("scenario_eye");
  const fs::path file = Write(dir.path(), std::string(kCar) +
                                              "eye: true\n"
                                              "events: [{at_s: 3, action: camera_lost, camera: "
                                              "overhead}, {at_s: 5.5, action: camera_back, "
                                              "camera: overhead}]\n");
  const maps::Map map =
      maps::LoadMapOrLayout((test::SourceDir() / "config/maps/driving_school.yaml").string());
  const ComposedCity c = ComposeCity(LoadScenario(file), file, map, dir.path() / "city.yaml",
                                     dir.path() / "run", dir.path() / "logs", dir.path());
  const YAML::Node city = YAML::Load(c.yaml);
  // The Eye runs, in the first stage with the lights (its fleet reaches the SCM's stage).
  EXPECT_EQ(city["launch"]["eye"]["mode"].as<std::string>(), "on");
  const YAML::Node stages = city["sim"]["service"]["stages"];
  ASSERT_EQ(stages.size(), 2U);
  EXPECT_EQ(stages[0][0].as<std::string>(), "lights");
  EXPECT_EQ(stages[0][1].as<std::string>(), "eye");
  EXPECT_EQ(stages[1][0].as<std::string>(), "scm");
  EXPECT_EQ(city["sim"]["cameras"][0]["lost_from_s"].as<double>(), 3.0);
  EXPECT_EQ(city["sim"]["cameras"][0]["lost_until_s"].as<double>(), 5.5);
}

TEST(ComposedCity, RunsInLockstepWithTheScenariosCarsAndAgents) {
  test::TempDir dir("scenario_city");
  const fs::path file =
      Write(dir.path(), std::string("seed: 7\ntime_limit_s: 30\ntraffic: {vehicles: 5}\n") + kCar);
  const Scenario s = LoadScenario(file);
  const maps::Map map =
      maps::LoadMapOrLayout((test::SourceDir() / "config/maps/driving_school.yaml").string());
  const ComposedCity c = ComposeCity(s, file, map, dir.path() / "city.yaml", dir.path() / "run",
                                     dir.path() / "logs", dir.path());
  const YAML::Node city = YAML::Load(c.yaml);
  EXPECT_EQ(city["sim"]["seed"].as<int>(), 7);
  EXPECT_EQ(city["traffic"]["vehicles"].as<int>(), 5);
  EXPECT_EQ(city["sim"]["vehicles"].size(), 1U);
  EXPECT_EQ(city["sim"]["service"]["mode"].as<std::string>(), "lockstep");
  EXPECT_EQ(city["sim"]["service"]["duration_s"].as<double>(), 30.0);
  EXPECT_EQ(city["sim"]["service"]["stages"][1][0].as<std::string>(), "scm");
  EXPECT_EQ(c.controllers, (std::vector<std::string>{"scenario", "traffic", "agent_nigel_1"}));
  EXPECT_EQ(city["launch"]["eye"]["mode"].as<std::string>(), "off");
  EXPECT_EQ(city["launch"]["agents"][0]["command"][4].as<std::string>(), "nigel_1");
  EXPECT_TRUE(fs::path(city["map"].as<std::string>()).is_absolute());
  // SUMO writes its trip statistics into the run's logs, those of cars still driving included.
  const YAML::Node args = city["traffic"]["sumo"]["args"];
  ASSERT_EQ(args.size(), 4U);
  EXPECT_EQ(args[0].as<std::string>(), "--tripinfo-output");
  EXPECT_EQ(args[1].as<std::string>(), (dir.path() / "logs" / kTripinfoFile).string());
  EXPECT_EQ(args[3].as<std::string>(), "true");
}

// ---- Metrics on logs written by hand ----

// A straight road along x at y = 0 with one signalised stop line at x = 2 (head 3) and a wall
// box at x in [4, 4.2]; one car (Nigel's body: 0.318 m long, centre 0.07077 m ahead of the rear
// axle, so its tail is 0.08823 m behind the axle and its front 0.22977 m ahead).
RunWorld Road() {
  RunWorld w;
  RunWorld::Car car;
  car.name = "nigel_1";
  car.route = {{0, 0}, {5, 0}};
  car.goal_tolerance_m = 0.1;
  w.cars.push_back(car);
  w.statics.push_back({"wall", "0", Rectangle({4.1, 0}, 0, 0.2, 1.0)});
  w.stop_lines.push_back({"east", "x", "signal", {3}, {2, 0.15}, {2, -0.15}, {1, 0}});
  w.stop_lines.push_back({"east_stop", "y", "stop", {}, {3, 0.15}, {3, -0.15}, {1, 0}});
  w.lanes.push_back({"east", 0.3, {{0, 0}, {5, 0}}});
  w.groups.push_back({1, 3, {3}});
  w.end_s = 30;
  return w;
}

// Ground truth of a car at constant speed v along y = `y` from x0, every 10 ms for `seconds`;
// it stops dead at x_stop (when given) for `stop_s`, then goes on.
void WriteDrive(const fs::path& logs, double v, double seconds, double y = 0.0, double x_stop = 1e9,
                double stop_s = 0.0) {
  std::ofstream f(logs / "ground_truth.csv");
  f << "t_s,vehicle,x_m,y_m,yaw_rad,vx_mps,vy_mps,yaw_rate_radps\n";
  double x = 0, stopped = 0;
  for (int i = 0; i * 0.01 <= seconds + 1e-9; ++i) {
    const double t = i * 0.01;
    double speed = v;
    if (x >= x_stop && stopped < stop_s) {
      speed = 0;
      stopped += 0.01;
    }
    f << fmt::format("{:.6f},nigel_1,{:.6f},{:.6f},0,{:.6f},0,0\n", t, x, y, speed);
    x += speed * 0.01;
  }
}

void WriteLamps(const fs::path& logs, const std::string& rows) {
  config::WriteFile(logs / "lamps.csv", "t_s,head,state\n" + rows);
}

// A goal pose (a parking bay): reached once the car stands within its distance and heading
// tolerances, not while it drives through; route completion 1 or 0; the final pose's errors.
TEST(Metrics, AGoalPoseIsReachedStandingThereWithinBothTolerances) {
  test::TempDir dir("metrics_goal_pose");
  WriteLamps(dir.path(), "0.000000,3,3\n");
  // 0.1 m/s from x = 0, standing at x = 1.0 from t = 10 s for 5 s, then on to 20 s (x 1.5).
  WriteDrive(dir.path(), 0.1, 20, 0.0, 1.0, 5.0);
  RunWorld w = Road();
  w.stop_lines.clear();
  w.statics.clear();
  w.cars[0].route.clear();
  w.cars[0].goal_pose = Eigen::Vector3d(1.02, 0.0, 0.0);
  w.cars[0].goal_tolerance_m = 0.05;
  w.cars[0].goal_tolerance_rad = 0.0873;
  const json m = ComputeMetrics(w, dir.path());
  EXPECT_EQ(m["run"]["goals_reached"], 1);
  EXPECT_EQ(m["run"]["route_completion"], 1.0);
  json v = m["vehicles"]["nigel_1"];
  EXPECT_EQ(v["goal_reached"], true);
  EXPECT_NEAR(v["time_to_goal_s"].get<double>(), 10.0, 0.02) << "when it stood there, not 9.7 s";
  EXPECT_EQ(v["route_completion"], 1.0);
  EXPECT_NEAR(v["final_position_error_m"].get<double>(), 0.48, 0.01) << "it drove on after";
  // The same stand with the goal facing north: not reached.
  w.cars[0].goal_pose = Eigen::Vector3d(1.02, 0.0, std::numbers::pi / 2);
  v = ComputeMetrics(w, dir.path())["vehicles"]["nigel_1"];
  EXPECT_EQ(v["goal_reached"], false);
  EXPECT_EQ(v["route_completion"], 0.0);
  EXPECT_NEAR(v["final_heading_error_deg"].get<double>(), 90.0, 1e-6);
  // It survives world.json.
  const RunWorld back = RunWorld::FromJson(w.ToJson());
  ASSERT_TRUE(back.cars[0].goal_pose);
  EXPECT_EQ(*back.cars[0].goal_pose, *w.cars[0].goal_pose);
  EXPECT_EQ(back.cars[0].goal_tolerance_rad, 0.0873);
}

// Laps of a closed route (a 1 m square, anticlockwise from the origin, 3 laps): each lap's time
// from when its end was passed; the route's end point, passed every lap, is the goal only at the
// last.
TEST(Metrics, LapsOfAClosedRouteAreTimedAndItsEndIsTheGoalOnlyAtTheLast) {
  test::TempDir dir("metrics_laps");
  WriteLamps(dir.path(), "0.000000,3,3\n");
  const std::vector<Eigen::Vector2d> corners{{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0, 0}};
  RunWorld w;
  RunWorld::Car car;
  car.name = "nigel_1";
  for (int lap = 0; lap < 3; ++lap)
    car.route.insert(car.route.end(), corners.begin(), corners.end());
  car.goal_tolerance_m = 0.1;
  car.lap_ends_m = {4, 8, 12};
  w.cars.push_back(car);
  w.end_s = 80;
  // 0.2 m/s round the square from (0.1, 0): 20 s a lap; `laps` laps, then standing.
  const auto drive = [&](double laps, double seconds) {
    std::ofstream f(dir.path() / "ground_truth.csv");
    f << "t_s,vehicle,x_m,y_m,yaw_rad,vx_mps,vy_mps,yaw_rate_radps\n";
    for (int i = 0; i * 0.01 <= seconds + 1e-9; ++i) {
      const double t = i * 0.01;
      const double s = std::min(0.1 + 0.2 * t, 0.1 + 4 * laps);
      const double along = std::fmod(s, 4.0);
      const int side = std::min(static_cast<int>(along), 3);
      const Eigen::Vector2d a = corners[static_cast<std::size_t>(side)];
      const Eigen::Vector2d b = corners[static_cast<std::size_t>(side) + 1];
      const Eigen::Vector2d p = a + (along - side) * (b - a);
      const double speed = s < 0.1 + 4 * laps ? 0.2 : 0.0;
      f << fmt::format("{:.6f},nigel_1,{:.6f},{:.6f},{:.6f},{:.6f},0,0\n", t, p.x(), p.y(),
                       std::atan2(b.y() - a.y(), b.x() - a.x()), speed);
    }
  };
  drive(2.5, 60);  // two and a half laps
  json v = ComputeMetrics(w, dir.path())["vehicles"]["nigel_1"];
  EXPECT_EQ(v["goal_reached"], false) << "it passed the route's end point twice, not its goal";
  EXPECT_EQ(v["laps_completed"], 2);
  ASSERT_EQ(v["lap_times_s"].size(), 2u);
  // Lap 1 ends at 3.9 m driven (it started 0.1 m in), lap 2 at 7.9 m.
  EXPECT_NEAR(v["lap_times_s"][0].get<double>(), 19.5, 0.02);
  EXPECT_NEAR(v["lap_times_s"][1].get<double>(), 20.0, 0.02);
  EXPECT_NEAR(v["route_completion"].get<double>(), 10.1 / 12, 0.01);
  drive(3 - 0.25 / 4, 80);  // to the goal: the front 0.23 m ahead of the rear axle
  v = ComputeMetrics(w, dir.path())["vehicles"]["nigel_1"];
  EXPECT_EQ(v["goal_reached"], true);
  EXPECT_EQ(v["laps_completed"], 3);
  EXPECT_EQ(v["route_completion"], 1.0);
  const RunWorld back = RunWorld::FromJson(w.ToJson());
  EXPECT_EQ(back.cars[0].lap_ends_m, w.cars[0].lap_ends_m);
}

TEST(Metrics, RedLightWhenTheTailCrossesTheLineOnRed) {
  test::TempDir dir("metrics_red");
  // 0.1 m/s: the tail (x - 0.08823) crosses x = 2 at t = 20.8823 s, the first sample at or
  // after it 20.89 s. Red until 25 s: one violation at 20.89 s.
  WriteDrive(dir.path(), 0.1, 30);
  WriteLamps(dir.path(), "0.000000,3,1\n25.000000,3,3\n");
  json m = ComputeMetrics(Road(), dir.path());
  const auto& red = m["vehicles"]["nigel_1"]["red_light_violations"];
  ASSERT_EQ(red.size(), 1U) << red;
  EXPECT_NEAR(red[0]["t_s"].get<double>(), 20.89, 1e-6);
  EXPECT_EQ(red[0]["head"], 3);
  EXPECT_EQ(m["run"]["red_light_violations"], 1);
  // Green from 20.5 s: the front crossed on red (at 17.70 s), the tail on green: none.
  WriteLamps(dir.path(), "0.000000,3,1\n20.500000,3,3\n");
  m = ComputeMetrics(Road(), dir.path());
  EXPECT_EQ(m["run"]["red_light_violations"], 0);
  // Yellow (2) is not red.
  WriteLamps(dir.path(), "0.000000,3,2\n");
  EXPECT_EQ(ComputeMetrics(Road(), dir.path())["run"]["red_light_violations"], 0);
}

TEST(Metrics, AFlashingRedOrDarkSignalIsJudgedAsAStopSign) {
  test::TempDir dir("metrics_flash");
  // Head 3 flashes red (red and dark every 0.5 s) from 0 to 40 s. At 0.1 m/s without
  // stopping, the front crosses x = 2 when x = 1.77023 (t = 17.7023 s, sample 17.71 s) and the
  // tail at 20.89 s (in a lit half): no red-light violation, one stop-sign violation.
  std::string flash;
  for (int k = 0; k < 80; ++k) flash += fmt::format("{:.6f},3,{}\n", 0.5 * k, k % 2 == 0 ? 1 : 0);
  WriteLamps(dir.path(), flash);
  WriteDrive(dir.path(), 0.1, 30);
  json m = ComputeMetrics(Road(), dir.path());
  EXPECT_EQ(m["run"]["red_light_violations"], 0);
  const json& stops = m["vehicles"]["nigel_1"]["stop_sign_violations"];
  ASSERT_EQ(stops.size(), 2U) << stops;  // the flashing red at x = 2, the stop sign at x = 3
  EXPECT_NEAR(stops[0]["t_s"].get<double>(), 17.71, 1e-6);
  EXPECT_EQ(stops[0]["control"], "flashing_red");
  EXPECT_EQ(stops[0]["head"], 3);
  // A full stop 0.2 m before the line (front at 1.8: x = 1.57), 2 s: none there.
  WriteDrive(dir.path(), 0.1, 40, 0.0, 1.57, 2.0);
  m = ComputeMetrics(Road(), dir.path());
  EXPECT_EQ(m["run"]["red_light_violations"], 0);
  ASSERT_EQ(m["vehicles"]["nigel_1"]["stop_sign_violations"].size(), 1U);
  EXPECT_FALSE(m["vehicles"]["nigel_1"]["stop_sign_violations"][0].contains("control"));
  // A dark head (the intersection switched off) is an all-way stop too.
  WriteLamps(dir.path(), "0.000000,3,0\n");
  WriteDrive(dir.path(), 0.1, 30);
  m = ComputeMetrics(Road(), dir.path());
  ASSERT_EQ(m["vehicles"]["nigel_1"]["stop_sign_violations"].size(), 2U);
  EXPECT_EQ(m["vehicles"]["nigel_1"]["stop_sign_violations"][0]["control"], "dark");
  // A steady red, as before: the red light, no stop-sign rule at the signal.
  WriteLamps(dir.path(), "0.000000,3,1\n");
  m = ComputeMetrics(Road(), dir.path());
  EXPECT_EQ(m["run"]["red_light_violations"], 1);
  EXPECT_EQ(m["vehicles"]["nigel_1"]["stop_sign_violations"].size(), 1U);
}

// A sign's pole (an octagon of 1 cm radius, as MakeWorld stands it) on the car's path is a
// collision like a wall's; the same pole 2 cm beside its body is not.
TEST(Metrics, APoleIsCollidedWith) {
  test::TempDir dir("metrics_pole");
  WriteLamps(dir.path(), "0.000000,3,3\n");
  const auto pole = [](double y) {
    Points octagon;
    for (int k = 0; k < 8; ++k) {
      const double a = std::numbers::pi / 8 + k * std::numbers::pi / 4;
      octagon.push_back(Eigen::Vector2d(3.5, y) +
                        0.0108 * Eigen::Vector2d(std::cos(a), std::sin(a)));
    }
    return octagon;
  };
  RunWorld on_path = Road();
  on_path.statics = {{"pole", "sign_2", pole(0.05)}};
  WriteDrive(dir.path(), 0.2, 25);
  const json m = ComputeMetrics(on_path, dir.path());
  const auto& c = m["vehicles"]["nigel_1"]["collisions"];
  ASSERT_EQ(c.size(), 1U) << c;
  EXPECT_EQ(c[0]["kind"], "pole");
  EXPECT_EQ(c[0]["with"], "pole:sign_2");
  RunWorld beside = Road();
  beside.statics = {{"pole", "sign_2", pole(0.0875 + 0.0108 + 0.02)}};
  EXPECT_EQ(ComputeMetrics(beside, dir.path())["run"]["collisions"], 0);
}

TEST(Metrics, CollisionAtFirstContactWithItsSpeed) {
  test::TempDir dir("metrics_collision");
  WriteLamps(dir.path(), "0.000000,3,3\n");
  // The front (x + 0.22977) reaches the wall's face at x = 4 when x = 3.77023: at 0.2 m/s,
  // t = 18.85115 s; within 5 mm (contact) from x = 3.76523, t = 18.82615 s: the first sample
  // at or after it is 18.83 s. The ground truth drives through (as if nothing stopped it):
  // one contact all the same.
  WriteDrive(dir.path(), 0.2, 25);
  json m = ComputeMetrics(Road(), dir.path());
  const auto& c = m["vehicles"]["nigel_1"]["collisions"];
  ASSERT_EQ(c.size(), 1U) << c;
  EXPECT_NEAR(c[0]["t_s"].get<double>(), 18.83, 1e-6);
  EXPECT_EQ(c[0]["kind"], "wall");
  EXPECT_NEAR(c[0]["speed_mps"].get<double>(), 0.2, 1e-6);
  EXPECT_EQ(m["run"]["collisions"], 1);
  // The wall (0.65) and the stop sign at x = 3 it rolled through on the way (0.8).
  EXPECT_NEAR(m["vehicles"]["nigel_1"]["penalty"].get<double>(), 0.65 * 0.8, 1e-6);
  // 0.1 m/s for 30 s: 3 m, front at 3.22977: no contact.
  WriteDrive(dir.path(), 0.1, 30);
  EXPECT_EQ(ComputeMetrics(Road(), dir.path())["run"]["collisions"], 0);
}

TEST(Metrics, AnObstaclePlacedOrRemovedCountsOnlyWhileItStands) {
  test::TempDir dir("metrics_timed_obstacle");
  WriteLamps(dir.path(), "0.000000,3,3\n");
  // The wall's box as an obstacle placed at 18.9 s: the first contact (18.83 s, as above) is
  // before it stands; the car still overlaps it at 18.9 s (driving through): one contact then.
  RunWorld w = Road();
  w.statics[0].kind = "obstacle";
  w.statics[0].from_s = 18.9;
  WriteDrive(dir.path(), 0.2, 25);
  json m = ComputeMetrics(w, dir.path());
  ASSERT_EQ(m["vehicles"]["nigel_1"]["collisions"].size(), 1U);
  EXPECT_NEAR(m["vehicles"]["nigel_1"]["collisions"][0]["t_s"].get<double>(), 18.9, 1e-6);
  // Removed at 18.8 s, before the car came near it: none.
  w.statics[0].from_s = 0;
  w.statics[0].until_s = 18.8;
  EXPECT_EQ(ComputeMetrics(w, dir.path())["run"]["collisions"], 0);
  // Removed at 18.84 s: the contact at 18.83 s counts.
  w.statics[0].until_s = 18.84;
  EXPECT_EQ(ComputeMetrics(w, dir.path())["run"]["collisions"], 1);
  // world.json keeps the times.
  const RunWorld back = RunWorld::FromJson(w.ToJson());
  EXPECT_EQ(back.statics[0].from_s, 0.0);
  EXPECT_EQ(back.statics[0].until_s, 18.84);
  EXPECT_FALSE(RunWorld::FromJson(Road().ToJson()).statics[0].until_s.has_value());
}

TEST(Metrics, StopSignNeedsAFullStopWithinTheZone) {
  test::TempDir dir("metrics_stop");
  WriteLamps(dir.path(), "0.000000,3,3\n");
  // Rolling through x = 3 (the front at 3 when x = 2.77023): a violation at the first sample
  // after, t = 27.71 s at 0.1 m/s, its slowest speed 0.1.
  WriteDrive(dir.path(), 0.1, 30);
  json m = ComputeMetrics(Road(), dir.path());
  ASSERT_EQ(m["vehicles"]["nigel_1"]["stop_sign_violations"].size(), 1U);
  EXPECT_NEAR(m["vehicles"]["nigel_1"]["stop_sign_violations"][0]["t_s"].get<double>(), 27.71,
              1e-6);
  // A full stop with the front 0.23 m before the line (x = 2.54): none.
  WriteDrive(dir.path(), 0.1, 40, 0.0, 2.54, 2.0);
  m = ComputeMetrics(Road(), dir.path());
  EXPECT_EQ(m["run"]["stop_sign_violations"], 0);
  EXPECT_EQ(m["run"]["stops"], 1);
  EXPECT_NEAR(m["run"]["stopped_time_s"].get<double>(), 2.0, 0.011);
  // A full stop 0.5 m before it (outside the 0.3 m zone): a violation.
  WriteDrive(dir.path(), 0.1, 40, 0.0, 2.27, 2.0);
  EXPECT_EQ(ComputeMetrics(Road(), dir.path())["run"]["stop_sign_violations"], 1);
}

TEST(Metrics, LaneDepartureAndRouteCompletion) {
  test::TempDir dir("metrics_lane");
  WriteLamps(dir.path(), "0.000000,3,3\n");
  // 0.2 m off the lane's centre (half width 0.15): one departure from the start, 0.05 m out.
  WriteDrive(dir.path(), 0.1, 10, 0.2);
  json m = ComputeMetrics(Road(), dir.path());
  ASSERT_EQ(m["vehicles"]["nigel_1"]["lane_departures"].size(), 1U);
  EXPECT_NEAR(m["vehicles"]["nigel_1"]["lane_departures"][0]["max_offset_m"].get<double>(), 0.05,
              1e-6);
  EXPECT_NEAR(m["vehicles"]["nigel_1"]["off_lane_fraction"].get<double>(), 1.0, 1e-6);
  // On the lane for 10 s at 0.1 m/s: 1 m of the 5 m route, no goal.
  WriteDrive(dir.path(), 0.1, 10, 0.0);
  m = ComputeMetrics(Road(), dir.path());
  EXPECT_EQ(m["run"]["lane_departures"], 0);
  EXPECT_NEAR(m["run"]["route_completion"].get<double>(), 0.2, 1e-6);
  EXPECT_EQ(m["run"]["goals_reached"], 0);
  EXPECT_NEAR(m["run"]["distance_m"].get<double>(), 1.0, 1e-6);
  // Time loss against the top speed 0.26 m/s: 10 s x (1 - 0.1 / 0.26) = 6.1538 s.
  EXPECT_NEAR(m["run"]["time_loss_s"].get<double>(), 10 * (1 - 0.1 / 0.26), 0.01);
  // Driving the wrong way along the lane is off it.
  RunWorld back = Road();
  back.lanes[0].centreline = {{5, 0}, {0, 0}};
  EXPECT_EQ(ComputeMetrics(back, dir.path())["run"]["lane_departures"], 1);
  // On an open floor (the Parking School's tiles) there is no lane to depart: 0.2 m off the
  // lane's centre is no departure where the floor is open, one where it ends before the car does.
  WriteDrive(dir.path(), 0.1, 10, 0.2);
  RunWorld floor = Road();
  floor.open_floors.push_back({{0, -0.5}, {5, 0.5}});
  EXPECT_EQ(ComputeMetrics(floor, dir.path())["run"]["lane_departures"], 0);
  // Written and read back with the world.
  EXPECT_EQ(
      ComputeMetrics(RunWorld::FromJson(floor.ToJson()), dir.path())["run"]["lane_departures"], 0);
  floor.open_floors[0].max.x() = 0.5;
  EXPECT_EQ(ComputeMetrics(floor, dir.path())["run"]["lane_departures"], 1);
}

TEST(Metrics, ALogEditedByHandIsRefusedNamingItsFileAndLine) {
  test::TempDir dir("metrics_bad_log");
  WriteLamps(dir.path(), "0.000000,3,3\n");
  config::WriteFile(dir.path() / "ground_truth.csv",
                    "t_s,vehicle,x_m,y_m,yaw_rad,vx_mps,vy_mps,yaw_rate_radps\n"
                    "0.000000,nigel_1,0,0,0,0,0,0\n0.010000,nigel_1,zero,0,0,0,0,0\n");
  try {
    (void)ComputeMetrics(Road(), dir.path());
    ADD_FAILURE() << "a bad number was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("ground_truth.csv:3: \"zero\" is not a number"),
              std::string::npos)
        << e.what();
  }
}

// SUMO's tripinfo file as SUMO 1.x writes it (attributes trimmed to those read, and two more).
constexpr const char* kTripinfo = R"(<?xml version="1.0" encoding="UTF-8"?>
<!-- generated on a day by Eclipse SUMO sumo Version 1.18.0 -->
<tripinfos xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
    <tripinfo id="nigel_1" depart="0.00" arrival="-1.00" duration="59.95" routeLength="13.81" waitingTime="49.50" waitingCount="8" timeLoss="55.95"/>
    <tripinfo id="bg_0" depart="0.05" arrival="31.20" duration="31.15" routeLength="60.47" waitingTime="10.00" waitingCount="2" timeLoss="12.50"/>
    <tripinfo id="bg_1" depart="0.05" arrival="-1.00" duration="59.90" routeLength="89.68" waitingTime="30.00" waitingCount="3" timeLoss="34.50"/>
</tripinfos>
)";

TEST(Metrics, SumoTripStatisticsOfTheBackgroundCarsLeaveTheLabsCarsOut) {
  test::TempDir dir("metrics_tripinfo");
  const fs::path file = dir.path() / kTripinfoFile;
  EXPECT_TRUE(SumoTripStatistics(file, {"nigel_1"}).is_null());  // no SUMO in the run
  config::WriteFile(file, kTripinfo);
  const json t = SumoTripStatistics(file, {"nigel_1"});
  EXPECT_EQ(t["trips"], 2);
  EXPECT_EQ(t["arrived"], 1);  // bg_1 still drove at the end (arrival -1)
  EXPECT_EQ(t["waiting_count"], 5);
  EXPECT_DOUBLE_EQ(t["waiting_time_s"]["mean"].get<double>(), 20.0);
  EXPECT_DOUBLE_EQ(t["waiting_time_s"]["max"].get<double>(), 30.0);
  EXPECT_DOUBLE_EQ(t["time_loss_s"]["mean"].get<double>(), 23.5);
  EXPECT_DOUBLE_EQ(t["time_loss_s"]["max"].get<double>(), 34.5);
  EXPECT_FALSE(t["per_car"].contains("nigel_1"));
  EXPECT_EQ(t["per_car"]["bg_1"]["arrived"], false);
  // The run's metrics carry them beside the lab's own.
  WriteLamps(dir.path(), "0.000000,3,3\n");
  WriteDrive(dir.path(), 0.2, 1.0);
  const json m = ComputeMetrics(Road(), dir.path());
  EXPECT_EQ(m["run"]["background_trips"], 2);
  EXPECT_DOUBLE_EQ(m["run"]["background_time_loss_mean_s"].get<double>(), 23.5);
  // Edited by hand: kTripinfo with `from` replaced by `to`, refused with what it says.
  const auto refusal = [&](const std::string& from, const std::string& to) {
    std::string text = kTripinfo;
    text.replace(text.find(from), from.size(), to);
    config::WriteFile(file, text);
    try {
      (void)SumoTripStatistics(file, {});
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("(read)");
  };
  // A bad number names the trip, its line and the attribute; a trip twice (an id reused)
  // would count twice.
  EXPECT_THAT(refusal("timeLoss=\"34.50\"", "timeLoss=\"lots\""),
              testing::HasSubstr(":6: trip \"bg_1\": timeLoss is \"lots\", not a number"));
  EXPECT_THAT(refusal("id=\"bg_1\"", "id=\"bg_0\""),
              testing::HasSubstr(":6: trip \"bg_0\" is there twice"));
  // SUMO killed before it closed the file: no statistics, said so.
  config::WriteFile(file, std::string(kTripinfo).substr(
                              0, std::string(kTripinfo).find("    <tripinfo id=\"bg_1\"")));
  EXPECT_TRUE(SumoTripStatistics(file, {}).contains("unfinished"));
  config::WriteFile(file, "<trips/>\n");
  EXPECT_THROW((void)SumoTripStatistics(file, {}), InputError);
}

TEST(Metrics, PolygonDistance) {
  const Points a = Rectangle({0, 0}, 0, 1, 1);
  EXPECT_NEAR(PolygonDistance(a, Rectangle({2, 0}, 0, 1, 1)), 1.0, 1e-12);
  EXPECT_EQ(PolygonDistance(a, Rectangle({0.5, 0.5}, 0.3, 1, 1)), 0.0);
  EXPECT_EQ(PolygonDistance(a, Rectangle({0, 0}, 0, 0.2, 0.2)), 0.0);  // inside
  EXPECT_NEAR(
      PolygonDistance(a, Rectangle({0, 2}, std::numbers::pi / 4, std::sqrt(2.0), std::sqrt(2.0))),
      0.5, 1e-12);
}

}  // namespace
}  // namespace autodrive::scenarios
