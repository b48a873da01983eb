// docs/tutorials/wire-a-serial-light.md followed with the lamp emulator in place of the board:
// the tutorial's serial entry (its port the emulator's link in the test's folder) in a copy of
// the small town's light host makes signal_5 a physical head that follows the SCM, and goes
// offline when the board stops answering; the tutorial's udev rule is well formed.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include "tests/scm_processes.h"
#include "tests/tutorial_blocks.h"

namespace autodrive::test {
namespace {

using std::chrono::seconds;

constexpr char kTutorial[] = "wire-a-serial-light";
constexpr std::uint8_t kOk = 0, kOffline = 3, kPhysical = 2;

class TutorialSerialLight : public ScmProcesses {
 protected:
  static void Replace(std::string& text, const std::string& from, const std::string& to) {
    const auto at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
  }
  /// The emulator's `status` line ("status aspect=green lamps=0 0 1 ...").
  static std::string EmulatorStatus(ChildProcess& emulator) {
    emulator.Write("status\n");
    return emulator.ReadLine(std::chrono::seconds(10)).value_or("");
  }
};

TEST_F(TutorialSerialLight, TheTutorialsEntryMakesAPhysicalHeadThatFollowsTheScm) {
  // The emulator as the tutorial starts it, its link in the test's folder.
  const std::string link = (dir_ / "lamp5").string();
  std::string command = OneLine(TutorialBlock(kTutorial, "emulator"));
  Replace(command, "build/bin/", Bin(""));
  Replace(command, "/tmp/lamp5", link);
  std::vector<std::string> argv;
  std::istringstream words(command);
  for (std::string w; words >> w;) argv.push_back(w);
  ChildProcess emulator(argv);
  ASSERT_TRUE(emulator.ReadLine(seconds(10)).has_value()) << "the emulator's terminal";
  ASSERT_TRUE(std::filesystem::exists(link));

  // The shipped light host, its serial entry the tutorial's with the emulator's port.
  std::string entry = OneLine(TutorialBlock(kTutorial, "serial-entry"));
  Replace(entry, "/dev/autodrive/lamp5", link);
  std::string lights = config::ReadFile(Config("config/infra/small_town.yaml"));
  Replace(lights, "../maps/", Config("config/maps") + "/");
  Replace(lights, "serial: []", entry);
  StartInfra(Write("lights.yaml", lights));
  StartScm("small_town");

  // signal_5 is physical and ok, and the board shows what the SCM commands: green in its turn.
  // (Waiting for signal_4's first report too: on a loaded machine it may come after signal_5's.)
  EXPECT_TRUE(WaitDevices(
      [](const auto& seen) {
        const auto it = seen.find("signal_5");
        return it != seen.end() && it->second.backend == kPhysical && it->second.health == kOk &&
               seen.contains("signal_4");
      },
      seconds(60)))
      << "signal_5 never physical and ok, or signal_4 never reported";
  EXPECT_EQ(devices_seen_["signal_4"].backend, 1) << "the other heads stay simulated";
  std::string status;
  for (const auto end = SteadyClock::now() + seconds(180);
       status.find("aspect=green lamps=0 0 1") == std::string::npos && SteadyClock::now() < end;) {
    status = EmulatorStatus(emulator);
    std::this_thread::sleep_for(std::chrono::milliseconds(200));  // paces the queries
  }
  EXPECT_THAT(status, ::testing::HasSubstr("aspect=green lamps=0 0 1"));
  EXPECT_THAT(Scmctl({"show", "centre"}).text, ::testing::ContainsRegex("signal_5=[a-z]"));

  // A board that stops answering: the head goes offline, as the tutorial says.
  emulator.Write("mute\n");
  ASSERT_TRUE(emulator.ReadLine(seconds(10)).has_value());
  EXPECT_TRUE(WaitDevices([](const auto& seen) { return seen.at("signal_5").health == kOffline; },
                          seconds(30)));
}

TEST(TutorialSerialLightUdev, TheRuleIsWellFormedAndNamesThePortOfTheSerialEntry) {
  // No udevadm here to `verify` it: every KEY[{attr}] OP "value" pair is checked instead,
  // matches with ==, assignments with = or +=.
  const std::string rule = OneLine(TutorialBlock(kTutorial, "udev-rule"));
  const std::regex pair(R"re(^([A-Z]+)(\{[A-Za-z_]+\})?(==|!=|\+=|=)"([^"]*)"$)re");
  const std::set<std::string> matches{"SUBSYSTEM", "KERNEL", "ATTRS", "ATTR", "ENV"};
  const std::set<std::string> assignments{"SYMLINK", "GROUP", "MODE", "OWNER"};
  std::string symlink;
  std::size_t from = 0;
  int pairs = 0;
  for (;;) {
    const auto comma = rule.find(", ", from);
    const std::string p = rule.substr(from, comma == std::string::npos ? comma : comma - from);
    std::smatch m;
    ASSERT_TRUE(std::regex_match(p, m, pair)) << p;
    const bool is_match = m[3] == "==" || m[3] == "!=";
    EXPECT_TRUE(is_match ? matches.contains(m[1]) : assignments.contains(m[1])) << p;
    if (m[1] == "SYMLINK") symlink = m[4];
    ++pairs;
    if (comma == std::string::npos) break;
    from = comma + 2;
  }
  EXPECT_EQ(pairs, 7);
  EXPECT_THAT(OneLine(TutorialBlock(kTutorial, "serial-entry")),
              ::testing::HasSubstr("port: /dev/" + symlink + ","));
}

}  // namespace
}  // namespace autodrive::test
