// scmctl atspm end to end: a real SCM (in process, on its own DDS partition and database) whose
// high-resolution log holds hand-built records (UDOT's golden PCD cycle and fixed-time services
// of the Driving School), read by the real scmctl program through the operator command `hires`
// and measured. Also `scmctl hires`, whose paging `atspm` shares: the same lines in pages of 2.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/config.h"
#include "common/process.h"
#include "common/test_support.h"
#include "scm/atspm/event_log.h"
#include "scm/config_loader.h"
#include "scm/daemon.h"
#include "scm/store/store.h"

namespace autodrive::scm {
namespace {

using nlohmann::json;
using ::testing::HasSubstr;

struct Output {
  int code = -1;
  std::string text;
};

class ScmctlAtspm : public ::testing::Test {
 protected:
  ScmctlAtspm()
      : partition_(fmt::format("scmctl_atspm_{}", ::getpid())),
        dir_(std::filesystem::temp_directory_path() / partition_) {
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  ~ScmctlAtspm() override { std::filesystem::remove_all(dir_); }

  /// The Driving School with its map path made absolute, not waiting for lights (none here).
  std::filesystem::path City() const {
    std::string text = config::ReadFile(test::SourceDir() / "config/cities/driving_school.yaml");
    const std::string map =
        (test::SourceDir() / "config/maps/driving_school.yaml").lexically_normal().string();
    text.replace(text.find("map: ../maps/driving_school.yaml"), 32, "map: " + map);
    text += "\ndevices: {wait_for_lights: false}\n";
    const auto path = dir_ / "city.yaml";
    std::ofstream(path) << text;
    return path;
  }

  /// scmctl with `args` on the test's partition, stderr folded into stdout: its exit code and
  /// output.
  Output Scmctl(const std::vector<std::string>& args) const {
    const char* bin = std::getenv("AUTODRIVE_BINARY_DIR");
    std::vector<std::string> argv{"/bin/sh",
                                  "-c",
                                  "exec \"$@\" 2>&1",
                                  "sh",
                                  std::string(bin != nullptr ? bin : ".") + "/bin/scmctl",
                                  "--partition",
                                  partition_,
                                  "--timeout",
                                  "60"};
    argv.insert(argv.end(), args.begin(), args.end());
    ChildProcess p(argv, {});
    Output out;
    while (auto line = p.ReadLine(std::chrono::minutes(5))) out.text += *line + "\n";
    out.code = p.Wait(std::chrono::minutes(1)).value_or(-1);
    return out;
  }

  std::string partition_;
  std::filesystem::path dir_;
};

/// Seconds since the epoch, as scmctl's --since and --until take them.
std::string Arg(Time t) { return fmt::format("{:.3f}", ToSeconds(t)); }

TEST_F(ScmctlAtspm, TheGoldenCycleAndTheSplitsThroughARealScm) {
  const std::filesystem::path city = City();
  const IntersectionId id = LoadCity(city).intersections.front().id;
  // Two hours ago, on a whole second: well inside the log's retention, before anything the
  // SCM logs itself now.
  const Time t0 = TimeFromSeconds(std::floor(ToSeconds(SystemNow())) - 7200.0);
  const auto at = [&](double s) { return t0 + FromSeconds(s); };
  std::vector<HiresRecord> seeded;
  const auto add = [&](double s, int code, int param) {
    seeded.push_back(
        {id, at(s), static_cast<std::uint16_t>(code), static_cast<std::uint16_t>(param)});
  };
  // UDOT's golden cycle on phase 2 (red 0 s, green 300 s, yellow 600 s, end 900 s) with
  // channel 2 (group 2, north) on at +5 s and +10 s.
  add(0, atspm::code::kPhaseEndYellow, 2);
  add(5, atspm::code::kDetectorOn, 2);
  add(5.5, atspm::code::kDetectorOff, 2);
  add(10, atspm::code::kDetectorOn, 2);
  add(10.5, atspm::code::kDetectorOff, 2);
  add(300, atspm::code::kPhaseBeginGreen, 2);
  add(600, atspm::code::kPhaseBeginYellow, 2);
  add(900, atspm::code::kPhaseEndYellow, 2);
  // Phase 1 served as the day plan does, 8 s green, 3 s yellow, 7 s red clearance, force off.
  for (const double g : {1000.0, 1072.0, 1144.0}) {
    for (const int c : {0, 1, 2, 3}) add(g, c, 1);
    for (const int c : {6, 7, 8}) add(g + 8, c, 1);
    for (const int c : {9, 10}) add(g + 11, c, 1);
    for (const int c : {11, 12}) add(g + 18, c, 1);
  }
  Store((dir_ / "scm.db").string()).AppendHires(seeded);

  ScmOptions options;
  options.config_path = city;
  options.db_path = (dir_ / "scm.db").string();
  options.config_root = test::SourceDir();
  dds::Participant participant(dds::ParticipantOptions{{}, partition_, {}});
  WallClock clock;
  Scm scm(options, clock, participant);
  std::thread loop([&] { scm.Run(); });

  // The golden cycle: 2 arrivals on red, 585 s of delay; the channel's phase from the city file.
  Output r = Scmctl({"atspm", "driving_school_crossing", "--measure", "pcd", "--since", Arg(at(0)),
                     "--until", Arg(at(900)), "--city", city.string(), "--json"});
  ASSERT_EQ(r.code, 0) << r.text;
  json out = json::parse(r.text);
  EXPECT_EQ(out["measure"], "pcd");
  EXPECT_EQ(out["intersection"], "driving_school_crossing");
  const json* phase2 = nullptr;
  for (const json& p : out["phases"]) {
    if (p["phase"] == 2) phase2 = &p;
  }
  ASSERT_NE(phase2, nullptr) << r.text;
  EXPECT_EQ((*phase2)["total"]["on_red"], 2);
  EXPECT_EQ((*phase2)["total"]["on_green"], 0);
  EXPECT_DOUBLE_EQ((*phase2)["total"]["delay_s"].get<double>(), 585.0);
  // The same with the channel given on the command line, as a table.
  r = Scmctl({"atspm", "driving_school_crossing", "--measure", "arrivals", "--since", Arg(at(0)),
              "--until", Arg(at(900)), "--phase-of-channel", "2:2"});
  ASSERT_EQ(r.code, 0) << r.text;
  EXPECT_THAT(r.text, HasSubstr("phase 2: 1 cycles, 2 arrivals: on green 0.0 %, yellow 0.0 %, red "
                                "100.0 %; green time 33.3 %, platoon ratio 0.00; delay 585.0 s"));

  // Split monitor: 18 s services of phase 1, forced off.
  r = Scmctl({"--json", "atspm", "driving_school_crossing", "--measure", "split-monitor", "--since",
              Arg(at(950)), "--until", Arg(at(1200))});
  ASSERT_EQ(r.code, 0) << r.text;
  out = json::parse(r.text);
  ASSERT_EQ(out["phases"].size(), 1u) << r.text;
  ASSERT_EQ(out["phases"][0]["cycles"].size(), 3u);
  for (const json& c : out["phases"][0]["cycles"]) {
    EXPECT_DOUBLE_EQ(c["split_s"].get<double>(), 18.0);
    EXPECT_DOUBLE_EQ(c["green_s"].get<double>(), 8.0);
    EXPECT_DOUBLE_EQ(c["yellow_s"].get<double>(), 3.0);
    EXPECT_DOUBLE_EQ(c["red_clearance_s"].get<double>(), 7.0);
    EXPECT_EQ(c["termination"], "force_off");
  }
  r = Scmctl({"atspm", "driving_school_crossing", "--measure", "phase-termination", "--since",
              Arg(at(950)), "--until", Arg(at(1200))});
  ASSERT_EQ(r.code, 0) << r.text;
  EXPECT_THAT(r.text, ::testing::ContainsRegex("\n +1 +0 +0 +3 +0 +0 +0 +0.0 +0.0 +100.0\n"));

  // What scmctl refuses: a detector measure without a channel map, an unknown intersection.
  r = Scmctl(
      {"atspm", "driving_school_crossing", "--measure", "split-failure", "--since", Arg(at(0))});
  EXPECT_EQ(r.code, 2) << r.text;
  EXPECT_THAT(r.text, HasSubstr("--measure split-failure reads vehicle detectors"));
  r = Scmctl({"atspm", "nowhere", "--measure", "split-monitor", "--since", Arg(at(0))});
  EXPECT_EQ(r.code, 2) << r.text;
  EXPECT_THAT(r.text, HasSubstr("unknown intersection \"nowhere\""));

  // hires reads the same records, in pages of 2 as in one.
  r = Scmctl({"hires", "driving_school_crossing", "--since", Arg(at(0)), "--until", Arg(at(1000)),
              "--csv"});
  ASSERT_EQ(r.code, 0) << r.text;
  EXPECT_EQ(std::ranges::count(r.text, '\n'), 1 + 8) << "the header and the golden cycle's 8\n"
                                                     << r.text;
  EXPECT_THAT(r.text, ::testing::StartsWith("SignalIdentifier,Timestamp,EventCode,EventParam\n"));
  EXPECT_THAT(r.text, HasSubstr(",82,2\ndriving_school_crossing,"));
  const Output paged = Scmctl({"hires", "driving_school_crossing", "--since", Arg(at(0)), "--until",
                               Arg(at(1000)), "--csv", "--page", "2"});
  EXPECT_EQ(paged.text, r.text);
  // Over the served cycles, whose milliseconds hold 2 to 4 records each, in pages of 1 to 3 as
  // in one (a page that ends inside a millisecond read on from a later page once printed some
  // of its records twice).
  r = Scmctl({"hires", "driving_school_crossing", "--since", Arg(at(950)), "--until", Arg(at(1200)),
              "--csv"});
  ASSERT_EQ(r.code, 0) << r.text;
  EXPECT_EQ(std::ranges::count(r.text, '\n'), 1 + 3 * 11) << r.text;
  for (const char* page : {"1", "2", "3"}) {
    const Output p = Scmctl({"hires", "driving_school_crossing", "--since", Arg(at(950)), "--until",
                             Arg(at(1200)), "--csv", "--page", page});
    EXPECT_EQ(p.text, r.text) << "pages of " << page;
  }

  scm.Stop();
  loop.join();
}

}  // namespace
}  // namespace autodrive::scm
