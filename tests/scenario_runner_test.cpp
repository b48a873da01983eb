// autodrive-scenario as a user runs it, with real processes: drivers that run a red light,
// collide, leave their lane and roll through a stop sign each fail their expectation with the
// violation named, the clean drive passes, and an independent recomputation (Python, standard
// library) agrees with every report; the same seed gives the same report.json byte for byte
// (its `invocation` aside) and another seed another one; a sweep killed halfway resumes without
// running its finished runs again; nothing is left running after any of it.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <fstream>
#include <functional>
#include <set>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/config.h"
#include "common/process.h"
#include "common/test_support.h"

namespace autodrive {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using std::chrono::milliseconds;
using std::chrono::seconds;

std::string Bin(const std::string& name) {
  const char* dir = std::getenv("AUTODRIVE_BINARY_DIR");
  return std::string(dir ? dir : ".") + "/bin/" + name;
}

std::string Shipped(const std::string& name) {
  return (test::SourceDir() / "config/scenarios" / (name + ".yaml")).string();
}

// Every process whose environment holds `tag` (all of a run's: the runner, the launcher and the
// city's programs inherit it).
std::set<int> Tagged(const std::string& tag) {
  std::set<int> pids;
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream in(e.path() / "environ", std::ios::binary);
    const std::string env((std::istreambuf_iterator<char>(in)), {});
    if (env.find(tag) != std::string::npos && std::stoi(name) != getpid())
      pids.insert(std::stoi(name));
  }
  return pids;
}

// Waits (generously) until no process carries `tag`; true when none does.
bool NoneLeft(const std::string& tag) {
  const auto end = std::chrono::steady_clock::now() + seconds(90);
  while (std::chrono::steady_clock::now() < end) {
    std::set<int> left = Tagged(tag);
    // Zombies wait for a parent that is gone to be reaped by init: not running.
    std::erase_if(left, [](int pid) {
      std::ifstream stat(fmt::format("/proc/{}/stat", pid));
      std::string s;
      std::getline(stat, s);
      const auto close = s.rfind(')');
      return close == std::string::npos || s.substr(close + 2, 1) == "Z";
    });
    if (left.empty()) return true;
    std::this_thread::sleep_for(milliseconds(200));
  }
  return false;
}

json ReadJson(const fs::path& file) { return json::parse(config::ReadFile(file)); }

std::vector<std::string> ReadLines(const fs::path& file) {
  std::vector<std::string> lines;
  std::ifstream in(file);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

struct Outcome {
  int code = -1;
  std::string output;
  json report;
};

class ScenarioRunner : public ::testing::Test {
 protected:
  ScenarioRunner() : tag_(fmt::format("AUTODRIVE_TEST_TAG={}", dir_.str())) {}

  Outcome RunScenario(const std::string& file, const std::string& out,
                      const std::vector<std::string>& extra = {}) {
    std::vector<std::string> argv{Bin("autodrive-scenario"), "run", file, "--out", out, "--quiet"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    ChildProcess p(argv, {tag_});
    Outcome r;
    while (auto line = p.ReadLine(milliseconds(600'000))) r.output += *line + "\n";
    r.code = p.Wait(milliseconds(60'000)).value_or(-1);
    if (fs::exists(fs::path(out) / "report.json"))
      r.report = ReadJson(fs::path(out) / "report.json");
    return r;
  }

  // The shipped scenario `name` written into the test's folder (its city found from there),
  // its time limit replaced by `limit` (which may carry further keys), `edit` applied.
  fs::path Shortened(const std::string& name, const std::string& limit,
                     const std::function<void(std::string&)>& edit = {}) {
    std::string text = config::ReadFile(Shipped(name));
    text.replace(text.find("city: ../cities/"), 16,
                 "city: " + (test::SourceDir() / "config/cities/").string());
    const auto at = text.find("time_limit_s: ");
    text.replace(at, text.find('\n', at) - at, limit);
    if (edit) edit(text);
    const fs::path file = dir_.path() / (name + ".yaml");
    config::WriteFile(file, text);
    return file;
  }

  test::TempDir dir_{"scenario_runner"};
  std::string tag_;
};

TEST_F(ScenarioRunner, FaultsOnPurposeFailNamingTheViolationAndTheCleanDrivePasses) {
  struct Case {
    std::string scenario;
    int code;
    std::string metric;  // the run metric the fault shows in, and its value
    int value;
  };
  const std::vector<Case> cases{
      {"crossing_clean", 0, "infractions", 0},
      {"crossing_red_light", 1, "red_light_violations", 1},
      {"obstacle_collision", 1, "collisions", 1},
      {"lane_departure", 1, "lane_departures", 1},
      {"stop_sign_roll", 1, "stop_sign_violations", 1},
  };
  std::vector<std::string> outs;
  for (const Case& c : cases) {
    const std::string out = (dir_.path() / c.scenario).string();
    const Outcome r = RunScenario(Shipped(c.scenario), out);
    SCOPED_TRACE(c.scenario + ":\n" + r.output);
    EXPECT_EQ(r.code, c.code);
    ASSERT_TRUE(r.report.is_object());
    EXPECT_EQ(r.report["metrics"]["run"][c.metric], c.value);
    EXPECT_EQ(r.report["passed"], c.code == 0);
    if (c.code == 1) {
      EXPECT_NE(r.output.find("failed: " + c.metric + " == 0 (got 1)"), std::string::npos);
    }
    // The other faults are absent: one violation, of its kind.
    EXPECT_EQ(r.report["metrics"]["run"]["infractions"], c.value);
    outs.push_back(out);
  }
  // The fault's time and the car's speed, from the logged ground truth by hand: the red light
  // at the first step the car's tail (0.08823 m behind its rear axle) is past the stop line at
  // x 2.0 (west approach, head 3 red since the start-up's all-red).
  {
    const json report = ReadJson(fs::path(outs[1]) / "report.json");
    ASSERT_EQ(report["metrics"]["vehicles"]["nigel_1"]["red_light_violations"].size(), 1U);
    const json red = report["metrics"]["vehicles"]["nigel_1"]["red_light_violations"][0];
    std::ifstream truth(fs::path(outs[1]) / "logs/ground_truth.csv");
    std::string line;
    std::getline(truth, line);
    double crossed = -1;
    while (std::getline(truth, line)) {
      double t = 0, x = 0;
      ASSERT_EQ(std::sscanf(line.c_str(), "%lf,nigel_1,%lf", &t, &x), 2) << line;
      if (x - 0.08823 >= 2.0) {
        crossed = t;
        break;
      }
    }
    EXPECT_NEAR(red["t_s"].get<double>(), crossed, 1e-6);
    EXPECT_EQ(red["head"], 3);
  }
  // An independent recomputation from the raw logs agrees with every report.
  std::vector<std::string> argv{"/usr/bin/python3",
                                (test::SourceDir() / "tests/scenario_recompute.py").string()};
  argv.insert(argv.end(), outs.begin(), outs.end());
  ChildProcess check(argv);
  std::string said;
  while (auto line = check.ReadLine(milliseconds(300'000))) said += *line + "\n";
  EXPECT_EQ(check.Wait(milliseconds(60'000)), std::optional<int>(0)) << said;
  EXPECT_EQ(said.find("DISAGREES"), std::string::npos) << said;
  EXPECT_TRUE(NoneLeft(tag_));
}

TEST_F(ScenarioRunner, SameSeedSameReportAnotherSeedAnother) {
  // The small town's crossing with SUMO and four cars, with the paper's noise (which the seed
  // draws), 20 simulated seconds.
  const fs::path file = Shortened("small_town_crossing", "time_limit_s: 20\nnoise: paper");
  const auto stable = [](json report) {
    report.erase("invocation");
    return report.dump(2);
  };
  const Outcome a = RunScenario(file.string(), (dir_.path() / "a").string());
  const Outcome b = RunScenario(file.string(), (dir_.path() / "b").string());
  const Outcome c = RunScenario(file.string(), (dir_.path() / "c").string(), {"--seed", "2"});
  ASSERT_TRUE(a.report.is_object()) << a.output;
  ASSERT_TRUE(b.report.is_object()) << b.output;
  ASSERT_TRUE(c.report.is_object()) << c.output;
  EXPECT_EQ(a.report["end"]["reason"], "time_limit");
  // SUMO's own statistics of its 10 cars (not of its stand-ins for the lab's four).
  EXPECT_EQ(a.report["metrics"]["run"]["background_trips"], 10) << a.report["metrics"].dump();
  EXPECT_EQ(a.report["metrics"]["background"]["per_car"].size(), 10U);
  EXPECT_EQ(stable(a.report), stable(b.report));
  // The raw logs too, the SCM's events included (its supervision judges the launcher, which
  // reports on the wall clock, on the wall clock: a run faster than real time raises nothing).
  for (const char* log : {"ground_truth.csv", "lamps.csv", "spat.jsonl", "events.jsonl"}) {
    EXPECT_EQ(config::ReadFile(dir_.path() / "a/logs" / log),
              config::ReadFile(dir_.path() / "b/logs" / log))
        << log;
  }
  EXPECT_EQ(config::ReadFile(dir_.path() / "a/logs/events.jsonl").find("launcher_lost"),
            std::string::npos);
  // Another seed: other noise, other cars' paths, other metrics (not only the seed field).
  EXPECT_NE(a.report["metrics"].dump(), c.report["metrics"].dump());
  EXPECT_TRUE(NoneLeft(tag_));
}

TEST_F(ScenarioRunner, AnAgentThatEndsBeforeTheRunFailsItNamingTheAgent) {
  // An agent that exits at once never answers the simulator, which would wait for it for good.
  const fs::path file = dir_.path() / "dead_agent.yaml";
  config::WriteFile(
      file, fmt::format(R"(name: dead_agent
city: {}
time_limit_s: 20
vehicles:
  - name: nigel_1
    spawn: {{lane: "r2c0:N>E:0", along_m: 0.3}}
    agent: {{command: ["true"]}}
)",
                        (test::SourceDir() / "config/cities/driving_school.yaml").string()));
  const Outcome r = RunScenario(file.string(), (dir_.path() / "dead").string());
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("the city's process agent_nigel_1 exited with code 0"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.report["end"]["reason"], "failed");
  EXPECT_TRUE(NoneLeft(tag_));
}

TEST_F(ScenarioRunner, ALampBurntOutMidRunIsReportedByItsHostAndTheCrossingFailsIntoFlash) {
  // The shipped lamp_fault scenario cut to 25 s: its fault comes at 20 s, and then an unplugged
  // head (a second event, added here) at 22 s.
  const fs::path file = Shortened("lamp_fault", "time_limit_s: 25", [](std::string& text) {
    text.replace(text.find("expect:"), 7, "  - {at_s: 22, action: unplug, head: 4}\nexpect:");
  });
  const Outcome r = RunScenario(file.string(), (dir_.path() / "fault").string());
  ASSERT_EQ(r.code, 0) << r.output;
  const fs::path logs = dir_.path() / "fault" / "logs";
  // The light host carried both out (its events), the SCM saw the faults (its own).
  std::string infra, scm;
  for (const std::string& line : ReadLines(logs / "events.jsonl")) {
    const json e = json::parse(line);
    if (e["code"] == "sim_fault") infra += e["message"].get<std::string>() + "\n";
    if (e["source"] == "scm" && e["active"] == true &&
        (e["code"] == "device_fault" || e["code"] == "device_offline" ||
         e["code"] == "device_lost")) {
      scm += e["device"].get<std::string>() + " ";
    }
  }
  EXPECT_NE(infra.find("signal_2: red lamp burnt out"), std::string::npos) << infra;
  EXPECT_NE(infra.find("signal_4: unplugged"), std::string::npos) << infra;
  EXPECT_NE(scm.find("signal_2"), std::string::npos) << scm;
  // Before the fault the crossing runs its plan; from a step after it, SPaT says failure flash
  // (J2735 IntersectionStatusObject bit 2) to the end.
  bool flash_before = false, flash_after = true;
  int after = 0;
  for (const std::string& line : ReadLines(logs / "spat.jsonl")) {
    const json s = json::parse(line);
    const double t = s["t_s"].get<double>();
    const bool flash = (s["status"].get<int>() & 4) != 0;
    if (t > 3.0 && t < 20.0) flash_before = flash_before || flash;
    if (t >= 20.2) {
      flash_after = flash_after && flash;
      ++after;
    }
  }
  EXPECT_FALSE(flash_before);
  EXPECT_TRUE(flash_after);
  EXPECT_GT(after, 40);  // 10 Hz for the run's last 4.8 s
  EXPECT_TRUE(NoneLeft(tag_));
}

TEST_F(ScenarioRunner, ALinkCutBetweenTheScmAndItsLightHostMakesBothSidesFailSafe) {
  // The shipped link_cut scenario cut to 22 s: the link goes at 15 s and comes back at 25 s.
  const fs::path file = Shortened("link_cut", "time_limit_s: 22");
  const Outcome r = RunScenario(file.string(), (dir_.path() / "cut").string());
  ASSERT_EQ(r.code, 0) << r.output;
  const fs::path logs = dir_.path() / "cut" / "logs";
  // The SCM loses all four heads (it no longer hears them) and flashes the crossing.
  std::set<std::string> lost;
  double failsafe_at = -1;
  for (const std::string& line : ReadLines(logs / "events.jsonl")) {
    const json e = json::parse(line);
    if (e["source"] != "scm" || e["active"] != true) continue;
    if (e["code"] == "device_lost") lost.insert(e["device"].get<std::string>());
    if (e["code"] == "failsafe_flash" && failsafe_at < 0) failsafe_at = e["t_s"].get<double>();
  }
  EXPECT_EQ(lost.size(), 4U);
  EXPECT_GT(failsafe_at, 15.0);
  // The heads, no longer hearing the SCM, flash red on their own: head 2 shows red and dark in
  // turn between the heartbeat's time-out and the end (the lamps still light for the cars).
  int red = 0, dark = 0;
  for (const std::string& line : ReadLines(logs / "lamps.csv")) {
    double t = 0;
    int head = 0, state = 0;
    if (std::sscanf(line.c_str(), "%lf,%d,%d", &t, &head, &state) != 3) continue;
    if (head != 2 || t < 16.5) continue;
    red += state == 1 ? 1 : 0;
    dark += state == 0 ? 1 : 0;
  }
  EXPECT_GE(red, 2);
  EXPECT_GE(dark, 2);
  EXPECT_TRUE(NoneLeft(tag_));
}

TEST_F(ScenarioRunner, AnObstaclePlacedMidRunStopsTheCarUntilItIsRemoved) {
  // The shipped obstacle_mid_run: a box at x in [3.45, 3.55] on the car's lane from 5 s to
  // 45 s. The example driver stops short of it (its LIDAR sees it), stands until it is gone,
  // then reaches its goal past where it stood.
  const fs::path file = Shortened("obstacle_mid_run", "time_limit_s: 70");
  const Outcome r = RunScenario(file.string(), (dir_.path() / "mid").string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.report["metrics"]["run"]["collisions"], 0);
  EXPECT_EQ(r.report["metrics"]["run"]["goals_reached"], 1);
  // Nigel's front is 0.22977 m ahead of its rear axle.
  constexpr double kFront = 0.22977, kFace = 3.45;
  double stood_from = -1, moved_again = -1, last_x = 0;
  for (const std::string& line : ReadLines(dir_.path() / "mid" / "logs" / "ground_truth.csv")) {
    double t = 0, x = 0, y = 0, yaw = 0, vx = 0;
    char car[32];
    if (std::sscanf(line.c_str(), "%lf,%31[^,],%lf,%lf,%lf,%lf", &t, car, &x, &y, &yaw, &vx) != 6) {
      continue;
    }
    last_x = x;
    if (x + kFront > 2.9 && x + kFront < kFace && std::abs(vx) < 1e-3 && stood_from < 0) {
      stood_from = t;
    }
    if (stood_from >= 0 && moved_again < 0 && std::abs(vx) > 0.05) moved_again = t;
  }
  EXPECT_GT(stood_from, 5.0) << "it stood short of the box while the box stood";
  EXPECT_LT(stood_from, 45.0);
  EXPECT_GE(moved_again, 45.0) << "and went on only once it was removed";
  EXPECT_GT(last_x, kFace) << "past where the box stood";
  // The box's times are in the world the metrics read.
  const json world = ReadJson(dir_.path() / "mid" / "logs" / "world.json");
  bool found = false;
  for (const json& st : world["statics"]) {
    if (st["name"] != "box") continue;
    found = true;
    EXPECT_EQ(st["from_s"], 5.0);
    EXPECT_EQ(st["until_s"], 45.0);
  }
  EXPECT_TRUE(found);

  // A driver that ignores its LIDAR runs into it while it stands: the physics stops the car,
  // the metrics count the obstacle.
  const fs::path blind = Shortened("obstacle_mid_run", "time_limit_s: 40", [](std::string& text) {
    const std::string clean = "agent: {driver: []}";
    text.replace(text.find(clean), clean.size(), "agent: {driver: [--ignore-obstacles]}");
  });
  const Outcome b = RunScenario(blind.string(), (dir_.path() / "blind").string());
  ASSERT_EQ(b.code, 1) << b.output;
  const json& c = b.report["metrics"]["vehicles"]["nigel_1"]["collisions"];
  ASSERT_EQ(c.size(), 1U) << c;
  EXPECT_EQ(c[0]["kind"], "obstacle");
  EXPECT_GT(c[0]["t_s"].get<double>(), 5.0);
  double furthest = 0;
  for (const std::string& line : ReadLines(dir_.path() / "blind" / "logs" / "ground_truth.csv")) {
    double t = 0, x = 0;
    char car[32];
    if (std::sscanf(line.c_str(), "%lf,%31[^,],%lf", &t, car, &x) == 3) {
      furthest = std::max(furthest, x);
    }
  }
  EXPECT_LT(furthest + kFront, kFace + 0.01) << "the box held the car";

  // A box placed onto the car (0.6 s in, where it then is) cannot be: the run fails with the
  // simulator's reason, and nothing is left running.
  const fs::path onto = Shortened("obstacle_mid_run", "time_limit_s: 3", [](std::string& text) {
    const std::string box = "{name: box, x_m: 3.5, y_m: 2.35,";
    text.replace(text.find(box), box.size(), "{name: box, x_m: 0.46, y_m: 2.63,");
    const std::string place = "{at_s: 5, action: place";
    text.replace(text.find(place), place.size(), "{at_s: 0.6, action: place");
  });
  const Outcome o = RunScenario(onto.string(), (dir_.path() / "onto").string());
  EXPECT_EQ(o.code, 2) << o.output;
  EXPECT_NE(o.output.find("would stand where vehicle 0's body is"), std::string::npos) << o.output;
  EXPECT_TRUE(NoneLeft(tag_));
}

TEST_F(ScenarioRunner, ADemandSurgeSendsItsCarsFromItsTimeAtItsRate) {
  // The shipped demand_surge cut to 30 s: 10 cars at 1200 an hour (one every 3 s) entering
  // at the centre's north approach from 10 s on, beside 4 background cars. SUMO's own trip
  // statistics (its tripinfo file, read here with a plain search) show when each departed.
  const fs::path file = Shortened("demand_surge", "time_limit_s: 30");
  const Outcome r = RunScenario(file.string(), (dir_.path() / "surge").string());
  ASSERT_EQ(r.code, 1) << r.output;  // 30 s let too few in for its ">= 12"
  EXPECT_NE(r.output.find("failed: background_trips >= 12"), std::string::npos) << r.output;
  const std::string trips = config::ReadFile(dir_.path() / "surge" / "logs" / "sumo_tripinfo.xml");
  std::vector<double> departs;
  int background = 0;
  for (std::size_t at = trips.find("<tripinfo "); at != std::string::npos;
       at = trips.find("<tripinfo ", at + 1)) {
    const std::string id = trips.substr(trips.find("id=\"", at) + 4, 12);
    const double depart = std::stod(trips.substr(trips.find("depart=\"", at) + 8));
    if (id.rfind("flow0_", 0) == 0) {
      departs.push_back(depart);
    } else if (id.rfind("bg_", 0) == 0) {
      ++background;
    }
  }
  EXPECT_EQ(background, 4);
  ASSERT_GE(departs.size(), 2U) << trips;
  EXPECT_LE(departs.size(), 10U);
  std::sort(departs.begin(), departs.end());
  EXPECT_NEAR(departs[0], 10.0, 0.051) << "the first at the event's time";
  // The k-th is due at 10 + 3k s; SUMO holds one back while there is no room to insert it,
  // then sends it as soon as there is (so two may come closer than 3 s), never before.
  for (std::size_t k = 0; k < departs.size(); ++k) {
    EXPECT_GE(departs[k], 10.0 + 3.0 * static_cast<double>(k) - 0.051) << k;
  }
  EXPECT_EQ(r.report["metrics"]["run"]["background_trips"], 4 + static_cast<int>(departs.size()));
  EXPECT_TRUE(NoneLeft(tag_));
}

TEST_F(ScenarioRunner, ACameraLostIsReportedByTheEyeInTheLoopAndItsReturnToo) {
  // The shipped camera_lost: the Eye in lockstep on the overhead camera (30 Hz), which sends
  // nothing from 10 s to 18 s. Its last frame before is at 9.967 s (frame 299), so the Eye
  // reports it lost 2 s of simulated time later, at the step of 11.98 s, and back at 18 s;
  // the same in two runs.
  const fs::path file = Shortened("camera_lost", "time_limit_s: 22");
  const Outcome r = RunScenario(file.string(), (dir_.path() / "lost").string());
  ASSERT_EQ(r.code, 0) << r.output;
  std::vector<json> eye;
  for (const std::string& line : ReadLines(dir_.path() / "lost" / "logs" / "events.jsonl")) {
    const json e = json::parse(line);
    if (e["source"] == "eye") eye.push_back(e);
  }
  const auto find = [&](const std::string& code, bool active) -> const json* {
    for (const json& e : eye) {
      if (e["code"] == code && e["active"] == active) return &e;
    }
    return nullptr;
  };
  ASSERT_NE(find("camera_registered", false), nullptr) << json(eye).dump(1);
  ASSERT_NE(find("vehicle_found", false), nullptr);
  const json* lost = find("camera_lost", true);
  const json* back = find("camera_lost", false);
  ASSERT_NE(lost, nullptr) << json(eye).dump(1);
  ASSERT_NE(back, nullptr) << json(eye).dump(1);
  EXPECT_NEAR((*lost)["t_s"].get<double>(), 11.98, 1e-6);
  EXPECT_EQ((*lost)["device"], "overhead");
  EXPECT_NEAR((*back)["t_s"].get<double>(), 18.0, 1e-6);
  // The car's track ended 0.5 s after the last frame (at the step of 10.48 s), not when the
  // frames came back.
  const json* car_lost = find("vehicle_lost", true);
  ASSERT_NE(car_lost, nullptr) << json(eye).dump(1);
  EXPECT_NEAR((*car_lost)["t_s"].get<double>(), 10.48, 1e-6);
  // The car was tracked again after the camera came back.
  bool found_again = false;
  for (const json& e : eye) {
    found_again = found_again || (e["code"] == "vehicle_found" && e["t_s"].get<double>() >= 18.0);
  }
  EXPECT_TRUE(found_again);
  const Outcome again = RunScenario(file.string(), (dir_.path() / "again").string());
  ASSERT_EQ(again.code, 0) << again.output;
  EXPECT_EQ(config::ReadFile(dir_.path() / "lost" / "logs" / "events.jsonl"),
            config::ReadFile(dir_.path() / "again" / "logs" / "events.jsonl"));
  EXPECT_TRUE(NoneLeft(tag_));
}

TEST_F(ScenarioRunner, ATriggeredEventHappensAtTheStepTheCarComesWithinReach) {
  // crossing_clean's car drives east along y = 2.35 towards the crossing. The crossing is put
  // into flash when the car's front (0.22977 m ahead of its rear axle) comes within 0.05 m of
  // (1.3, 2.35): at the first step whose ground truth says so. A trigger it never reaches
  // never fires.
  const fs::path file = Shortened("crossing_clean", "time_limit_s: 12", [](std::string& text) {
    text +=
        "events:\n"
        "  - {action: mode, intersection: driving_school_crossing, mode: flash,\n"
        "     when: {vehicle: nigel_1, x_m: 1.3, y_m: 2.35, within_m: 0.05}}\n"
        "  - {at_s: 1, action: mode, intersection: driving_school_crossing, mode: auto,\n"
        "     when: {vehicle: nigel_1, x_m: 4.5, y_m: 4.5, within_m: 0.05}}\n";
  });
  const Outcome r = RunScenario(file.string(), (dir_.path() / "trigger").string());
  ASSERT_NE(r.code, 2) << r.output;
  const fs::path logs = dir_.path() / "trigger" / "logs";
  double expected = -1;
  for (const std::string& line : ReadLines(logs / "ground_truth.csv")) {
    double t = 0, x = 0, y = 0, yaw = 0;
    char car[32];
    if (std::sscanf(line.c_str(), "%lf,%31[^,],%lf,%lf,%lf", &t, car, &x, &y, &yaw) != 5) continue;
    const double fx = x + 0.22977 * std::cos(yaw) - 1.3, fy = y + 0.22977 * std::sin(yaw) - 2.35;
    if (std::hypot(fx, fy) <= 0.05) {
      expected = t;
      break;
    }
  }
  ASSERT_GT(expected, 0.0) << "the car came within reach";
  const std::vector<std::string> applied = ReadLines(logs / "scenario_events.jsonl");
  ASSERT_EQ(applied.size(), 1U) << "the unreached trigger never fired";
  const json e = json::parse(applied[0]);
  EXPECT_EQ(e["mode"], "flash");
  EXPECT_NEAR(e["t_s"].get<double>(), expected, 1e-6);
  EXPECT_EQ(e["trigger"]["vehicle"], "nigel_1");
  EXPECT_LE(e["trigger"]["distance_m"].get<double>(), 0.05);
  EXPECT_TRUE(NoneLeft(tag_));
}

TEST_F(ScenarioRunner, CtrlCTakesTheCityDown) {
  const std::string out = (dir_.path() / "interrupted").string();
  ChildProcess p({Bin("autodrive-scenario"), "run", Shipped("crossing_clean"), "--out", out},
                 {tag_});
  // Once the city runs (the launcher's log says so), Ctrl-C.
  const auto end = std::chrono::steady_clock::now() + seconds(120);
  while (std::chrono::steady_clock::now() < end) {
    std::ifstream log(fs::path(out) / "launcher.log");
    const std::string text((std::istreambuf_iterator<char>(log)), {});
    if (text.find("is up.") != std::string::npos) break;
    std::this_thread::sleep_for(milliseconds(100));
  }
  ASSERT_EQ(::kill(p.pid(), SIGINT), 0);
  EXPECT_EQ(p.Wait(milliseconds(120'000)), std::optional<int>(130));
  const json report = ReadJson(fs::path(out) / "report.json");
  EXPECT_EQ(report["end"]["reason"], "interrupted");
  EXPECT_TRUE(NoneLeft(tag_));
}

TEST_F(ScenarioRunner, ASweepKilledHalfwayResumesWithoutRunningItsFinishedRunsAgain) {
  // 20 runs: the clean crossing for 6 simulated seconds, 10 seeds, two variants.
  const fs::path sweep = dir_.path() / "sweep.yaml";
  config::WriteFile(sweep, fmt::format(R"(name: twenty
scenario: {}
seed_range: {{first: 1, count: 10}}
parallel: 2
variants:
  - {{name: cruise, set: {{time_limit_s: 6}}}}
  - {{name: slow, agent_args: [--throttle, "0.4"], set: {{time_limit_s: 6}}}}
)",
                                       Shipped("crossing_clean")));
  const fs::path out = dir_.path() / "sweep";
  const auto reports = [&] {
    std::map<std::string, std::string> done;
    if (!fs::exists(out / "runs")) return done;
    for (const auto& e : fs::directory_iterator(out / "runs")) {
      // A run stopped with the sweep says it was interrupted: not done.
      const fs::path report = e.path() / "report.json";
      if (fs::exists(report) &&
          json::parse(config::ReadFile(report))["end"]["reason"] != "interrupted") {
        done[e.path().filename().string()] = config::ReadFile(report);
      }
    }
    return done;
  };
  std::map<std::string, std::string> before;
  {
    ChildProcess first({Bin("autodrive-scenario"), "sweep", sweep.string(), "--out", out.string()},
                       {tag_});
    const auto end = std::chrono::steady_clock::now() + seconds(600);
    while (reports().size() < 6 && std::chrono::steady_clock::now() < end) {
      std::this_thread::sleep_for(milliseconds(200));
    }
    ASSERT_GE(reports().size(), 6U);
    // Killed outright: its runs and their cities go with it.
    ASSERT_EQ(::kill(first.pid(), SIGKILL), 0);
    (void)first.Wait(milliseconds(10'000));
  }
  EXPECT_TRUE(NoneLeft(tag_)) << "a sweep killed with SIGKILL left processes";
  before = reports();
  ASSERT_LT(before.size(), 20U);
  ChildProcess resume(
      {Bin("autodrive-scenario"), "sweep", sweep.string(), "--out", out.string(), "--resume"},
      {tag_});
  std::string said;
  while (auto line = resume.ReadLine(milliseconds(900'000))) said += *line + "\n";
  EXPECT_EQ(resume.Wait(milliseconds(60'000)), std::optional<int>(0)) << said;
  EXPECT_NE(said.find(fmt::format("20 of 20 runs done ({} before)", before.size())),
            std::string::npos)
      << said;
  const auto after = reports();
  EXPECT_EQ(after.size(), 20U);
  for (const auto& [id, text] : before) {
    EXPECT_EQ(after.at(id), text) << id << " was run again";
  }
  const json summary = ReadJson(out / "summary.json");
  EXPECT_EQ(summary["runs_done"], 20);
  EXPECT_EQ(summary["variants"][0]["stats"]["collisions"]["n"], 10);
  EXPECT_TRUE(NoneLeft(tag_));
}

}  // namespace
}  // namespace autodrive
