// docs/tutorials/change-a-signal-plan.md followed on a copy of the small town in the test's own
// folder (its ~/lab), with the tutorial's own commands and edits: the edited city validates; each
// edit that breaks a rule is refused with the message the tutorial quotes; applied to a real SCM
// (and its light host) on a partition of the test's own, the new plan runs, by hand and on SPaT.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <chrono>
#include <fstream>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/scm_processes.h"
#include "tests/tutorial_blocks.h"

namespace autodrive::test {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr char kTutorial[] = "change-a-signal-plan";

class TutorialSignalPlan : public ScmProcesses {
 protected:
  void SetUp() override {
    ScmProcesses::SetUp();
    // The tutorial's `scmctl` on the PATH, on the test's partition.
    std::filesystem::create_directories(dir_ / "bin");
    Write("bin/scmctl",
          "#!/bin/sh\nexec '" + Bin("scmctl") + "' --partition " + partition_ + " \"$@\"\n");
    ASSERT_EQ(::chmod((dir_ / "bin" / "scmctl").c_str(), 0755), 0);
  }
  std::string Block(const std::string& name) const { return TutorialBlock(kTutorial, name); }
  /// Runs a tutorial's shell block in `folder` (from the source folder when empty), HOME in the
  /// test's folder, with the time of day at noon.
  Output Shell(const std::string& script, const std::string& folder = "") const {
    const char* path = std::getenv("PATH");
    return RunCaptured(
        {"env", "HOME=" + dir_.string(),
         "PATH=" + (dir_ / "bin").string() + ":" + Bin("") + ":" + (path ? path : "/usr/bin:/bin"),
         NoonTimeZone(), "/bin/sh", "-c",
         "cd '" + (folder.empty() ? SourceDir().string() : folder) + "' && " + script});
  }
  std::string Cities() const { return (dir_ / "lab" / "cities").string(); }
  /// `scmctl --json intersections`' value for `name` (null until the SCM answers).
  nlohmann::json Intersection(const std::string& name) const {
    const auto j = nlohmann::json::parse(Scmctl({"--json", "intersections"}).text, nullptr, false);
    if (!j.is_object() || !j.contains("values") || !j["values"].contains(name)) return {};
    return j["values"][name];
  }
  /// Waits up to `timeout` for a green of `name` that began under a second ago (`scmctl --json
  /// show`): the most of it left for steps that must happen before it ends, on a loaded machine.
  bool WaitFreshGreen(const std::string& name, SteadyClock::duration timeout) const {
    for (const auto end = SteadyClock::now() + timeout; SteadyClock::now() < end;) {
      const auto j = nlohmann::json::parse(Scmctl({"--json", "show", name}).text, nullptr, false);
      if (j.is_object() && j.contains("values") && j["values"].is_object()) {
        for (const auto& [key, g] : j["values"].items()) {
          if (key.starts_with("group ") && g.is_object() && g.value("aspect", "") == "green" &&
              g.value("since_s", 99.0) < 1.0) {
            return true;
          }
        }
      }
      std::this_thread::sleep_for(milliseconds(100));  // paces the polls
    }
    return false;
  }
  /// Waits up to `timeout` until `pred(Intersection(name))`; returns the last value seen.
  template <typename P>
  nlohmann::json WaitIntersection(const std::string& name, P pred, SteadyClock::duration timeout) {
    nlohmann::json x;
    for (const auto end = SteadyClock::now() + timeout; SteadyClock::now() < end;) {
      x = Intersection(name);
      if (!x.is_null() && pred(x)) return x;
      std::this_thread::sleep_for(milliseconds(200));  // paces the polls
    }
    return x;
  }
};

TEST_F(TutorialSignalPlan, TheEditedCityValidatesBrokenRulesAreRefusedAndTheNewPlanRuns) {
  Output r = Shell(Block("copy"));
  ASSERT_EQ(r.code, 0) << r.text;
  const std::string city_path = Cities() + "/small_town.yaml";
  const std::string shipped = config::ReadFile(city_path);

  // 1. The edits; 2. the edited city validates locally.
  const std::string edited =
      ApplyDiff(ApplyDiff(shipped, Block("edit-plans")), Block("edit-schedule"));
  Write("lab/cities/small_town.yaml", edited);
  r = Shell(Block("validate"));
  EXPECT_EQ(r.code, 0) << r.text;
  EXPECT_TRUE(ShowsQuoted(r.text, Block("validate-ok"))) << r.text;
  // Each broken rule is refused with the tutorial's message, exit status 2.
  for (const std::string rule : {"min-green", "yellow", "red-clearance"}) {
    Write("lab/cities/small_town.yaml", ApplyDiff(edited, Block(rule)));
    r = Shell(Block("validate"));
    EXPECT_EQ(r.code, 2) << rule << ": " << r.text;
    EXPECT_TRUE(ShowsQuoted(r.text, Block(rule + "-refused"))) << rule << ": " << r.text;
  }
  Write("lab/cities/small_town.yaml", edited);

  // 3. The city runs the shipped plans (a copy beside the edited one), its lights the shipped.
  const std::string running = Write("lab/cities/running.yaml", shipped);
  StartInfra("small_town");
  scm_ = std::make_unique<ChildProcess>(
      std::vector<std::string>{Bin("autodrive-scm"), "--config", running, "--partition", partition_,
                               "--db", (dir_ / "scm.db").string(), "--log-level", "warn"},
      std::vector<std::string>{NoonTimeZone()});
  const auto green = [](const nlohmann::json& x) { return x.value("stage", "") == "green"; };
  nlohmann::json centre = WaitIntersection("centre", green, seconds(120));
  ASSERT_TRUE(green(centre)) << centre.dump();
  EXPECT_EQ(centre.value("plan", ""), "day");
  r = Lab({"plan", "centre", "school_run"});
  EXPECT_EQ(r.code, 2) << "the running city has no such plan yet: " << r.text;
  r = Shell(Block("validate-scm"), Cities());
  EXPECT_EQ(r.code, 0) << r.text;
  r = Shell(Block("apply"), Cities());
  EXPECT_EQ(r.code, 0) << r.text;
  EXPECT_TRUE(ShowsQuoted(r.text, Block("apply-ok"))) << r.text;
  EXPECT_THAT(Scmctl({"status"}).text, ::testing::HasSubstr("config: " + city_path));

  // 4. By hand: pending until the next safe point (the end of this green, 8 s), then run; SPaT
  // says so. From a green just begun, so that the block's two commands run within it.
  ASSERT_TRUE(WaitFreshGreen("centre", seconds(120))) << Scmctl({"show", "centre"}).text;
  r = Shell(Block("plan-by-hand"), Cities());
  EXPECT_EQ(r.code, 0) << r.text;
  EXPECT_TRUE(ShowsQuoted(r.text, Block("plan-pending"))) << r.text;
  centre = WaitIntersection(
      "centre",
      [](const nlohmann::json& x) {
        return x.value("plan", "") == "school_run" && x.value("plan_by", "") == "operator";
      },
      seconds(120));
  EXPECT_EQ(centre.value("plan", ""), "school_run") << centre.dump();
  EXPECT_TRUE(WaitSpat(
      [](const msg::Spat& s) {
        const auto* x = FindIntersection(s, "centre");
        return x && dds::View(x->plan) == "school_run";
      },
      seconds(30)));
  r = Lab({"plan", "centre", "auto"});
  EXPECT_EQ(r.code, 0) << r.text;
  centre = WaitIntersection(
      "centre",
      [](const nlohmann::json& x) {
        // Back to the schedule at once, back to its plan at the next safe point.
        return x.value("plan_by", "") == "schedule" && x.value("plan", "") == "day";
      },
      seconds(120));
  EXPECT_EQ(centre.value("plan", ""), "day") << centre.dump();
}

}  // namespace
}  // namespace autodrive::test
