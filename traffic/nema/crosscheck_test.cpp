// autodrive-scm-nema against SUMO 1.15: the export is accepted, the SCM's controller runs the
// Driving School's plans as SUMO's NEMA controller does, and an altered SUMO program is caught.
// libsumo runs one simulation per process, so each run is the program, in a child process.
#include "traffic/nema/crosscheck.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "traffic/nema/nema_test_support.h"

#include "common/test_support.h"
#include "scm/core/city.h"

namespace autodrive::traffic::nema {
namespace {

namespace fs = std::filesystem;

class TempDir : public test::TempDir {
 public:
  TempDir() : test::TempDir("traffic_nema_crosscheck_test") {}
};

using support::Output;
using support::RunNema;

std::string City() { return support::DrivingSchool(); }

nlohmann::json Report(const fs::path& dir) {
  std::ifstream in(dir / "report.json");
  return nlohmann::json::parse(in);
}

// The Driving School's actuated evening plan for 3 cycles with the call script `calls`: it must
// match SUMO; returns the report.
nlohmann::json EveningWithCalls(const TempDir& dir, const std::string& calls) {
  std::ofstream(dir.path() / "calls.txt") << calls;
  const Output r =
      RunNema({"crosscheck", City(), "driving_school_crossing", "evening", "--cycles", "3",
               "--calls", (dir.path() / "calls.txt").string(), "--out", dir.str()});
  EXPECT_EQ(r.code, 0) << r.text;
  nlohmann::json j = Report(dir.path());
  EXPECT_TRUE(j.at("match").get<bool>());
  return j;
}

TEST(NemaCrosscheck, DrivingSchoolDayPlanMatchesSumoNemaForTenCycles) {
  const TempDir dir;
  // Both start at time 0: our start-up (flash 3 s, all red 7 s) ends at 10 s, inside phase 1's
  // clearance, and stays red to phase 2's green at 18 s, on the cycle. (Before, it began phase 2
  // at 10 s and kept that lead for good: docs/controller-crosscheck.md.)
  const Output r = RunNema({"crosscheck", City(), "driving_school_crossing", "day", "--cycles",
                            "10", "--out", dir.str()});
  ASSERT_EQ(r.code, 0) << r.text;
  const nlohmann::json j = Report(dir.path());
  EXPECT_TRUE(j.at("match").get<bool>());
  EXPECT_EQ(j.at("sumo_version").get<std::string>().rfind("SUMO 1.15", 0), 0u)
      << j.at("sumo_version");
  EXPECT_EQ(j.at("cycle_s").get<double>(), 72.0);
  // Every green, yellow and red clearance of each phase in 10 cycles, within one step.
  int intervals = 0;
  for (const nlohmann::json& phase : j.at("phases")) {
    for (const nlohmann::json& i : phase.at("intervals")) {
      SCOPED_TRACE(i.dump());
      ++intervals;
      ASSERT_FALSE(i.at("ours").is_null());
      ASSERT_FALSE(i.at("sumo").is_null());
      EXPECT_LE(std::abs(i.at("begin_difference_s").get<double>()), 0.1 + 1e-9);
      EXPECT_LE(std::abs(i.at("end_difference_s").get<double>()), 0.1 + 1e-9);
    }
  }
  EXPECT_EQ(intervals, 10 * 4 * 3);
  // The cycle is SUMO's: 10 of 72 s in both.
  const auto& cycles = j.at("cycle_lengths");
  EXPECT_EQ(cycles.at("sumo_s").get<std::vector<double>>(), std::vector<double>(10, 72.0));
  EXPECT_EQ(cycles.at("ours_s").get<std::vector<double>>(), std::vector<double>(10, 72.0));
  // SUMO's greens read from its states agree with its SaveTLSSwitchTimes file: 3 links a phase.
  EXPECT_EQ(j.at("switch_times_check").at("links_checked").get<int>(), 10 * 4 * 3);
  EXPECT_TRUE(j.at("switch_times_check").at("disagreements").empty());
  EXPECT_EQ(j.at("link_states").at("steps_differing").get<int>(), 0);
  EXPECT_TRUE(fs::exists(dir.path() / "report.txt"));
  EXPECT_TRUE(fs::exists(dir.path() / "tls_switches.xml"));
}

TEST(NemaCrosscheck, SmallTownsThreePhaseTeeWithAnOffsetMatchesSumoNema) {
  const TempDir dir;
  const Output r =
      RunNema({"crosscheck", (test::SourceDir() / "config/cities/small_town.yaml").string(),
               "north_t", "day", "--cycles", "10", "--out", dir.str()});
  ASSERT_EQ(r.code, 0) << r.text;
  const nlohmann::json j = Report(dir.path());
  EXPECT_TRUE(j.at("match").get<bool>());
  EXPECT_EQ(j.at("cycle_s").get<double>(), 52.0);
  EXPECT_EQ(j.at("cycle_lengths").at("sumo_s").get<std::vector<double>>(),
            std::vector<double>(10, 52.0));
  EXPECT_LE(j.at("max_difference_s").get<double>(), 0.1 + 1e-9);
}

TEST(NemaCrosscheck, ActuatedEveningPlanFollowsTheSameCallsAsSumo) {
  const TempDir dir;
  // Calls held, a short one lost (non-locking), rests in green without conflicting calls.
  const nlohmann::json j = EveningWithCalls(
      dir, "# phase on_s off_s\n2 20 40\n3 30 31\n4 50 90\n1 100 101\n2 140 141\n3 160 161\n");
  int greens = 0;
  for (const nlohmann::json& phase : j.at("phases")) {
    for (const nlohmann::json& i : phase.at("intervals")) greens += i.at("kind") == "green";
  }
  // Phases 2, 4, 1 and 2 again (phase 3's first call, during phase 2's green, was not kept;
  // its second one ends phase 2's rest at 160 s).
  EXPECT_EQ(greens, 4);
}

TEST(NemaCrosscheck, AHeldCallMaxesOutMax1AfterTheConflictingCallAsInSumo) {
  // Phase 1 called throughout, phase 2 from 30 s: phase 1 maxes out 15 s (its max 1) after the
  // conflicting call (NTCIP phaseMaximum1), not after its green's start; then each maxes out
  // in turn, every green 15 s.
  const TempDir dir;
  const nlohmann::json j = EveningWithCalls(dir, "1 0 300\n2 30 300\n");
  const nlohmann::json& phase1 = j.at("phases").at(0);
  ASSERT_EQ(phase1.at("phase").get<int>(), 1);
  const nlohmann::json& first = phase1.at("intervals").at(0);
  ASSERT_EQ(first.at("kind").get<std::string>(), "yellow");
  EXPECT_NEAR(first.at("ours").at("begin_s").get<double>(), 45.0, 1e-9);
  EXPECT_NEAR(first.at("sumo").at("begin_s").get<double>(), 45.0, 0.1 + 1e-9);
  int greens = 0;
  for (const nlohmann::json& phase : j.at("phases")) {
    for (const nlohmann::json& i : phase.at("intervals")) {
      if (i.at("kind") != "green") continue;
      ++greens;
      EXPECT_NEAR(i.at("ours").at("end_s").get<double>() - i.at("ours").at("begin_s").get<double>(),
                  15.0, 1e-9);
    }
  }
  EXPECT_GE(greens, 10);
}

TEST(NemaCrosscheck, SeesSumoRunningALongerMaxGreen) {
  const TempDir dir;
  // Ours started 10 s early (its start-up done at SUMO's 0) so that the comparison starts with
  // the first cycle, where SUMO's longer phase 3 is the first difference.
  const Output r =
      RunNema({"crosscheck", City(), "driving_school_crossing", "day", "--cycles", "3",
               "--our-start", "-10", "--out", dir.str(), "--test-sumo-max-green", "3=10"});
  ASSERT_EQ(r.code, 1) << r.text;
  EXPECT_NE(r.text.find("verdict: DIFFERENT"), std::string::npos) << r.text;
  const nlohmann::json j = Report(dir.path());
  EXPECT_FALSE(j.at("match").get<bool>());
  const nlohmann::json& first = j.at("first_difference");
  EXPECT_EQ(first.at("phase").get<int>(), 3);
  EXPECT_EQ(first.at("kind").get<std::string>(), "green");
  EXPECT_NEAR(first.at("end_difference_s").get<double>(), 2.0, 1e-9);
  EXPECT_EQ(j.at("cycle_lengths").at("sumo_s").at(0).get<double>(), 74.0);
}

TEST(NemaCrosscheck, ExportIsAcceptedBySumo) {
  const TempDir dir;
  const fs::path file = dir.path() / "day.nema.add.xml";
  const Output r = RunNema({"export", City(), "driving_school_crossing", "day", "-o", file.string(),
                            "--check", (dir.path() / "net").string()});
  ASSERT_EQ(r.code, 0) << r.text;
  EXPECT_NE(r.text.find("SUMO accepts it"), std::string::npos) << r.text;
  std::ifstream in(file);
  const std::string xml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(xml.find("<tlLogic id=\"driving_school_crossing\" programID=\"NEMA\" type=\"NEMA\""),
            std::string::npos)
      << xml;

  // The check can fail: SUMO refuses a program whose ring does not add up to its cycle.
  std::string bad = xml;
  const std::string cycle = "key=\"total-cycle-length\" value=\"72\"";
  ASSERT_NE(bad.find(cycle), std::string::npos);
  bad.replace(bad.find(cycle), cycle.size(), "key=\"total-cycle-length\" value=\"70\"");
  const fs::path bad_file = dir.path() / "bad.nema.add.xml";
  std::ofstream(bad_file) << bad;
  const scm::City city = scm::LoadCity(City());
  const std::string message =
      test::ErrorMessage([&] { (void)CheckWithSumo(city, bad_file, dir.path() / "net2"); });
  EXPECT_NE(message.find("does not add to cycle length"), std::string::npos) << message;
}

TEST(NemaCrosscheck, BadInputExitsWithTwoAndSaysWhatIsWrong) {
  const TempDir dir;
  const Output flash = RunNema({"crosscheck", City(), "driving_school_crossing", "night",
                                "--cycles", "1", "--out", dir.str()});
  EXPECT_EQ(flash.code, 2) << flash.text;
  EXPECT_NE(flash.text.find("plan night (flash)"), std::string::npos) << flash.text;
  const Output plan =
      RunNema({"export", City(), "driving_school_crossing", "noon", "-o", dir.str() + "/x.xml"});
  EXPECT_EQ(plan.code, 2) << plan.text;
  EXPECT_NE(plan.text.find("no plan \"noon\""), std::string::npos) << plan.text;
  const Output cycles =
      RunNema({"crosscheck", City(), "driving_school_crossing", "day", "--out", dir.str()});
  EXPECT_EQ(cycles.code, 2) << cycles.text;
  EXPECT_NE(cycles.text.find("--cycles"), std::string::npos) << cycles.text;
  {
    std::ofstream calls(dir.path() / "calls.txt");
    calls << "9 1 2\n";
  }
  const Output calls =
      RunNema({"crosscheck", City(), "driving_school_crossing", "day", "--cycles", "1", "--calls",
               (dir.path() / "calls.txt").string(), "--out", dir.str()});
  EXPECT_EQ(calls.code, 2) << calls.text;
  EXPECT_NE(calls.text.find("calls.txt:1: the phase must be a NEMA phase number 1..8, got 9"),
            std::string::npos)
      << calls.text;
}

}  // namespace
}  // namespace autodrive::traffic::nema
