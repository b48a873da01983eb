// docs/tutorials/add-an-intersection.md followed on a copy of the small town in the test's own
// folder (its ~/lab): the map made signalised at west_t, the city's new intersection and the
// light host's heads from the tutorial's blocks; the shipped heads keep their ids, a light host
// that misses the new heads is refused naming them, and the edited city comes up with every
// intersection out of start-up.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/scm_processes.h"
#include "tests/tutorial_blocks.h"

namespace autodrive::test {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr char kTutorial[] = "add-an-intersection";

class TutorialIntersection : public ScmProcesses {
 protected:
  std::string Block(const std::string& name) const { return TutorialBlock(kTutorial, name); }
  /// Runs a tutorial's shell block from the source folder with HOME in the test's folder, its
  /// `build/bin/` the programs under test.
  Output Shell(std::string script) const {
    const std::string bin = Bin("");
    for (auto at = script.find("build/bin/"); at != std::string::npos;
         at = script.find("build/bin/", at + bin.size())) {
      script.replace(at, 10, bin);
    }
    return RunCaptured({"env", "HOME=" + dir_.string(), "XDG_STATE_HOME=" + State(), "/bin/sh",
                        "-c", "cd '" + SourceDir().string() + "' && " + script});
  }
  std::string Lab(const std::string& rel) const { return (dir_ / "lab" / rel).string(); }
  std::string State() const { return (dir_ / "state").string(); }
  /// The cell of a map row as the tutorial quotes it ("  - [CELL, straight, ..."): CELL.
  static std::string Cell(const std::string& row) {
    const auto open = row.find('[');
    return row.substr(open + 1, row.find(',', open) - open - 1);
  }
  static void Replace(std::string& text, const std::string& from, const std::string& to) {
    const auto at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
  }
  /// The "signal heads by approach" line under `intersection` in `autodrive-map info`'s text.
  static std::string HeadsOf(const std::string& info, const std::string& intersection) {
    const auto at = info.find("    " + intersection + " ");
    if (at == std::string::npos) return "";
    const auto line = info.find('\n', at) + 1;
    const auto end = info.find('\n', line);
    const std::string next = info.substr(line, end - line);
    return next.find("signal heads by approach") == std::string::npos ? "" : next;
  }
};

TEST_F(TutorialIntersection, TheStepsKeepTheShippedHeadsRefuseAnUnhostedHeadAndBringTheCityUp) {
  // Copy the shipped files.
  Output r = Shell(Block("copy"));
  ASSERT_EQ(r.code, 0) << r.text;
  const std::string map_path = Lab("maps/small_town.yaml");
  const std::string city_path = Lab("cities/small_town.yaml");
  const std::string lights_path = Lab("infra/small_town.yaml");
  const Output shipped_info = RunCaptured({Bin("autodrive-map"), "info", map_path});
  ASSERT_EQ(shipped_info.code, 0) << shipped_info.text;

  // 1. The map: west_t signalised, its heads 8, 9, 10; the shipped heads keep their ids.
  std::string map = config::ReadFile(map_path);
  Replace(map, Cell(Block("map-from")), Cell(Block("map-to")));
  Write("lab/maps/small_town.yaml", map);
  const Output info = RunCaptured({Bin("autodrive-map"), "info", map_path});
  ASSERT_EQ(info.code, 0) << info.text;
  EXPECT_TRUE(ShowsQuoted(HeadsOf(info.text, "west_t"), Block("map-info"))) << info.text;
  for (const std::string x : {"north_t", "centre"}) {
    EXPECT_NE(HeadsOf(shipped_info.text, x), "") << shipped_info.text;
    EXPECT_EQ(HeadsOf(info.text, x), HeadsOf(shipped_info.text, x)) << x;
  }

  // 2. The city: west_t beside centre and north_t; only the signals run in this test.
  std::string city = config::ReadFile(city_path);
  Replace(city, "\nfleet:", "\n" + Block("city-west-t") + "fleet:");
  Write("lab/cities/small_town.yaml", city + Block("launch-signals-only"));
  r = RunCaptured({Bin("scmctl"), "config", "validate", city_path});
  EXPECT_EQ(r.code, 0) << r.text;

  // 3. Before the light host hosts the new heads, `check` refuses the city naming them.
  r = Shell(Block("check"));
  EXPECT_NE(r.code, 0) << r.text;
  EXPECT_TRUE(ShowsQuoted(r.text, Block("check-refused"))) << r.text;
  std::string lights = config::ReadFile(lights_path);
  Replace(lights, OneLine(Block("lights-from")), OneLine(Block("lights-to")));
  Write("lab/infra/small_town.yaml", lights);
  r = Shell(Block("check"));
  EXPECT_EQ(r.code, 0) << r.text;

  // 5. Run it: every intersection, west_t too, out of start-up (about 10 s; generous deadline).
  ChildOptions options;
  options.output_file = dir_ / "launcher.log";
  options.extra_env = {"XDG_STATE_HOME=" + State(), NoonTimeZone()};
  ChildProcess up = ChildProcess::Start({Bin("autodrive-city"), "up", city_path, "--partition",
                                         partition_, "--dashboard", "127.0.0.1:0"},
                                        options);
  const std::set<std::string> running{"green", "yellow", "red_clearance"};
  nlohmann::json seen;
  bool all_running = false;
  for (const auto end = SteadyClock::now() + seconds(180);
       !all_running && SteadyClock::now() < end && !up.Wait(milliseconds(0));) {
    const Output x = Scmctl({"--json", "intersections"});
    seen = nlohmann::json::parse(x.text, nullptr, false);
    if (!seen.is_object() || !seen.contains("values")) continue;
    const auto& values = seen["values"];
    all_running = values.size() == 3;
    for (const std::string name : {"centre", "north_t", "west_t"}) {
      all_running =
          all_running && values.contains(name) && running.contains(values[name].value("stage", ""));
    }
    if (!all_running) std::this_thread::sleep_for(milliseconds(500));  // paces the polls
  }
  EXPECT_TRUE(all_running) << seen.dump() << "\n" << config::ReadFile(dir_ / "launcher.log");
  const Output down =
      RunCaptured({"env", "XDG_STATE_HOME=" + State(), Bin("autodrive-city"), "down", city_path});
  EXPECT_EQ(down.code, 0) << down.text;
  EXPECT_EQ(up.Wait(milliseconds(60000)), std::optional<int>(0))
      << config::ReadFile(dir_ / "launcher.log");
}

TEST(TutorialBlocks, AMissingMarkIsAnErrorNamingTheFileAndTheMark) {
  EXPECT_THAT(ErrorMessage([] { (void)TutorialBlock(kTutorial, "no-such-block"); }),
              ::testing::EndsWith("add-an-intersection.md: no block marked <!-- test: "
                                  "no-such-block -->\n"));
  EXPECT_TRUE(ShowsQuoted("a: b\nc  d: e", "a…c d…"));
  EXPECT_FALSE(ShowsQuoted("c d: e a: b", "a…c d"));
}

}  // namespace
}  // namespace autodrive::test
