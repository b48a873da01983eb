// The intergreen collision oracle (issue 37, research §4.3 M8): the SCM's controllers drive
// SUMO's lights through the lamps on the Driving School's and the small town's networks, with
// slow clearing and fast entering vehicles that trust the signal. SUMO reports no junction
// collision with the cities' timings, and some at every intersection with every intergreen
// halved (the negative control). libsumo runs one simulation per process, so each run is the
// program, in a child process. The full hour is in docs/controller-crosscheck.md.
#include "traffic/nema/collision_oracle.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "traffic/nema/nema_test_support.h"

#include "common/test_support.h"

namespace autodrive::traffic::nema {
namespace {

namespace fs = std::filesystem;

class TempDir : public test::TempDir {
 public:
  TempDir() : test::TempDir("traffic_nema_collision_test") {}
};

using support::Output;
using support::RunNema;

// Simulated seconds of each run: at least 2 junction collisions at every intersection with the
// intergreens halved over seeds 1-8 in 900 s (seed 1: 9 to 28 in 1800 s), a few seconds of CPU.
// AUTODRIVE_SOAK multiplies it.
std::string RunSeconds() {
  const char* soak = std::getenv("AUTODRIVE_SOAK");
  const int factor = soak != nullptr ? std::max(1, std::atoi(soak)) : 1;
  return std::to_string(1800 * factor);
}

std::string CityFile(const std::string& name) {
  return (test::SourceDir() / ("config/cities/" + name + ".yaml")).string();
}

nlohmann::json Json(const fs::path& file) {
  std::ifstream in(file);
  return nlohmann::json::parse(in);
}

// Runs the oracle on `city` (every intersection in a run of its own) and returns the summary.
nlohmann::json Oracle(const std::string& city, const TempDir& dir, bool halve, int expect_code) {
  std::vector<std::string> args = {"collisions", CityFile(city), "--duration",
                                   RunSeconds(), "--out",        dir.str()};
  if (halve) args.emplace_back("--halve-intergreens");
  const Output r = RunNema(args);
  EXPECT_EQ(r.code, expect_code) << r.text;
  return Json(dir.path() / "summary.json");
}

void ExpectNoJunctionCollision(const nlohmann::json& summary, std::size_t runs) {
  ASSERT_EQ(summary.at("runs").size(), runs) << summary.dump(2);
  EXPECT_EQ(summary.at("junction_collisions").get<int>(), 0) << summary.dump(2);
  for (const nlohmann::json& run : summary.at("runs")) {
    SCOPED_TRACE(run.dump());
    EXPECT_TRUE(run.at("ran").get<bool>());
    EXPECT_EQ(run.at("junction_collisions").get<int>(), 0);
    EXPECT_EQ(run.at("monitor_violations").get<int>(), 0);
    // Saturated approaches: hundreds of vehicles through each box.
    EXPECT_GT(run.at("vehicles_departed").get<int>(), 300);
    // The report has what ran: both types, every intergreen the controller gave, seen.
    const nlohmann::json report = Json(fs::path(run.at("dir").get<std::string>()) / "report.json");
    EXPECT_EQ(report.at("vehicle_types").size(), 2u);
    EXPECT_EQ(report.at("step_s").get<double>(), 0.1);
    for (const nlohmann::json& g : report.at("intergreens")) {
      EXPECT_GE(g.at("observed_s").get<double>() + 1e-9, g.at("matrix_s").get<double>()) << g;
      EXPECT_GE(g.at("observed_s").get<double>(), 10.0 - 1e-9) << g;  // yellow 3 + red 7
    }
  }
}

// Every intersection's run reports junction collisions, inside its own junction, between
// vehicles of conflicting groups: one whose group's green had ended, one whose had begun.
void ExpectJunctionCollisionsEverywhere(const nlohmann::json& summary, std::size_t runs) {
  ASSERT_EQ(summary.at("runs").size(), runs) << summary.dump(2);
  for (const nlohmann::json& run : summary.at("runs")) {
    SCOPED_TRACE(run.dump());
    EXPECT_TRUE(run.at("ran").get<bool>());
    EXPECT_GT(run.at("intergreen_collisions").get<int>(), 0);
    EXPECT_EQ(run.at("monitor_violations").get<int>(), 0);
    const nlohmann::json report = Json(fs::path(run.at("dir").get<std::string>()) / "report.json");
    EXPECT_EQ(report.at("intergreen_factor").get<double>(), 0.5);
    for (const nlohmann::json& c : report.at("collisions")) {
      if (!c.at("conflicting_groups").get<bool>()) continue;
      EXPECT_TRUE(c.at("in_junction").get<bool>()) << c;
      EXPECT_EQ(c.at("junction").get<std::string>(), run.at("intersection").get<std::string>());
      const std::string signals = c.at("signals").get<std::string>();
      EXPECT_NE(signals.find("green ended"), std::string::npos) << signals;
      EXPECT_NE(signals.find("green since"), std::string::npos) << signals;
    }
  }
}

TEST(CollisionOracle, DrivingSchoolHasNoJunctionCollisionWithItsTimingsAndSomeWithThemHalved) {
  const TempDir safe;
  ExpectNoJunctionCollision(Oracle("driving_school", safe, false, 0), 1);
  const TempDir halved;
  ExpectJunctionCollisionsEverywhere(Oracle("driving_school", halved, true, 1), 1);
}

TEST(CollisionOracle, SmallTownHasNoJunctionCollisionWithItsTimingsAndSomeWithThemHalved) {
  const TempDir safe;
  ExpectNoJunctionCollision(Oracle("small_town", safe, false, 0), 2);
  const TempDir halved;
  ExpectJunctionCollisionsEverywhere(Oracle("small_town", halved, true, 1), 2);
}

TEST(CollisionOracle, AnActuatedScheduledPlanIsRefusedNamingIt) {
  const TempDir dir;
  const Output r = RunNema({"collisions", CityFile("driving_school"), "--intersection",
                            "driving_school_crossing", "--time-of-day", "19:30", "--duration", "60",
                            "--out", dir.str()});
  EXPECT_EQ(r.code, 2) << r.text;
  EXPECT_NE(r.text.find("runs plan evening (actuated)"), std::string::npos) << r.text;
  const Output bad = RunNema(
      {"collisions", CityFile("driving_school"), "--time-of-day", "25:00", "--out", dir.str()});
  EXPECT_EQ(bad.code, 2) << bad.text;
  EXPECT_NE(bad.text.find("HH:MM"), std::string::npos) << bad.text;
}

}  // namespace
}  // namespace autodrive::traffic::nema
