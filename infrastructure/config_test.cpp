#include "infrastructure/config.h"

#include <gtest/gtest.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <fstream>

#include "common/test_support.h"

namespace autodrive::infrastructure {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

std::vector<fs::path> ShippedConfigs() {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(test::SourceDir() / "config" / "infra")) {
    if (e.path().extension() == ".yaml") out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

// A scratch directory for config files, removed at the end of the test.
class TempDir {
 public:
  TempDir()
      : path_(fs::temp_directory_path() /
              ("autodrive_infra_config_" + std::to_string(::getpid()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name())) {
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  // Writes `text` to `name` in the directory and returns its path.
  fs::path Write(const std::string& name, const std::string& text) const {
    const fs::path p = path_ / name;
    std::ofstream(p) << text;
    return p;
  }

 private:
  fs::path path_;
};

std::string DrivingSchoolMap() {
  return (test::SourceDir() / "config" / "maps" / "driving_school.yaml").string();
}

std::string LoadError(const std::string& yaml) {
  return test::ErrorMessage<ConfigError>(
      [&] { (void)config::LoadString<InfraConfig>(yaml, "infra.yaml"); });
}

TEST(InfraConfig, TheShippedConfigsLoadAndResolveAgainstTheirMaps) {
  std::map<std::string, std::size_t> heads;
  for (const auto& path : ShippedConfigs()) {
    SCOPED_TRACE(path.string());
    const InfraConfig config = LoadInfraConfig(path);
    const HostPlan plan = PlanHost(config, path);
    heads[path.stem().string()] = plan.heads.size();
    // The city is an SCM city of the project: config/cities/<city>.yaml, whose name it is.
    const fs::path city = test::SourceDir() / "config" / "cities" / (config.city + ".yaml");
    ASSERT_TRUE(fs::exists(city)) << city;
    EXPECT_EQ(YAML::LoadFile(city.string())["name"].as<std::string>(), config.city);
    for (const auto& h : plan.heads) EXPECT_EQ(h.backend, BackendType::kSimulated);
    EXPECT_TRUE(config.monitor.enabled);
  }
  EXPECT_EQ(heads, (std::map<std::string, std::size_t>{{"driving_school", 4}, {"small_town", 7}}));
}

TEST(InfraConfig, RoundTripsThroughYaml) {
  for (const auto& path : ShippedConfigs()) {
    const InfraConfig config = LoadInfraConfig(path);
    EXPECT_EQ(config::LoadString<InfraConfig>(config::SaveString(config)), config);
  }
  InfraConfig full;
  full.name = "lab_2";
  full.city = "parking_school";
  full.map = "/maps/x.yaml";
  full.scm_heartbeat_timeout_s = 2500ms;
  full.status_period_s = 50ms;
  full.flash_period_s = 800ms;
  full.heads = {2, 3};
  full.default_backend = BackendType::kSerial;
  full.serial = {{2, "/dev/ttyACM0", 115200}, {3, "/dev/ttyACM1", 9600}};
  full.monitor = {false, 500ms};
  EXPECT_EQ(config::LoadString<InfraConfig>(config::SaveString(full)), full);
}

TEST(InfraConfig, OptionalKeysKeepTheirDefaults) {
  const auto c = config::LoadString<InfraConfig>("name: a\ncity: c\nmap: m.yaml\n");
  EXPECT_EQ(c.scm_heartbeat_timeout_s, 1s);
  EXPECT_EQ(c.status_period_s, 100ms);
  EXPECT_EQ(c.flash_period_s, 1s);
  EXPECT_TRUE(c.heads.empty());
  EXPECT_EQ(c.default_backend, BackendType::kSimulated);
  EXPECT_TRUE(c.serial.empty());
  EXPECT_TRUE(c.monitor.enabled);
  EXPECT_EQ(c.monitor.conflict_persistence_s, 300ms);
}

TEST(InfraConfigErrors, NameFileLineColumnKeyAndValue) {
  EXPECT_EQ(LoadError("name: a\ncity: c\nmap: m.yaml\nscm_heartbeat_timeout: 1\n"),
            "infra.yaml:4:1: scm_heartbeat_timeout: unknown key (did you mean "
            "scm_heartbeat_timeout_s? allowed keys: name, city, map, scm_heartbeat_timeout_s, "
            "status_period_s, flash_period_s, heads, default_backend, serial, monitor)");
  EXPECT_EQ(LoadError("map: m.yaml\n"), "infra.yaml:1:1: name: missing required key");
  EXPECT_EQ(LoadError("name: a\nmap: m.yaml\n"), "infra.yaml:1:1: city: missing required key");
  EXPECT_EQ(LoadError("name: a\ncity: small-town\nmap: m.yaml\n"),
            "infra.yaml:2:7: city: invalid value (got small-town; expected a non-empty city "
            "name of letters, digits and '_')");
  EXPECT_EQ(LoadError("name: a b\ncity: c\nmap: m.yaml\n"),
            "infra.yaml:1:7: name: invalid value (got a b; expected a non-empty "
            "name of letters, digits and '_')");
  EXPECT_EQ(LoadError("name: a\ncity: c\nmap: m.yaml\nscm_heartbeat_timeout_s: 0.01\n"),
            "infra.yaml:4:26: scm_heartbeat_timeout_s: out of range (got 0.01; expected a value "
            "in [0.1, 60.0])");
  EXPECT_EQ(LoadError("name: a\ncity: c\nmap: m.yaml\ndefault_backend: usb\n"),
            "infra.yaml:4:18: default_backend: not an allowed value (got \"usb\"; expected one "
            "of \"simulated\", \"serial\")");
  EXPECT_EQ(LoadError("name: a\ncity: c\nmap: m.yaml\nheads: [1, 2, 1]\n"),
            "infra.yaml:4:8: heads: invalid value (got a sequence; expected a list of distinct "
            "head ids)");
  EXPECT_EQ(LoadError("name: a\ncity: c\nmap: m.yaml\nheads: [0]\n"),
            "infra.yaml:4:9: heads[0]: out of range (got 0; expected a value in [1, 1000000])");
  EXPECT_EQ(
      LoadError(
          "name: a\ncity: c\nmap: m.yaml\nserial:\n  - {head: 1, port: /dev/x, baud: 12345}\n"),
      "infra.yaml:5:35: serial[0].baud: invalid value (got 12345; expected a baud rate of "
      "9600, 19200, 38400, 57600, 115200, 230400, 460800 or 921600)");
  EXPECT_EQ(LoadError("name: a\ncity: c\nmap: m.yaml\nserial:\n  - {head: 1, port: /dev/x}\n"
                      "  - {head: 2, port: /dev/x}\n"),
            "infra.yaml:5:3: serial: invalid value (got a sequence; expected entries with "
            "distinct heads and distinct ports)");
  EXPECT_EQ(
      LoadError(
          "name: a\ncity: c\nmap: m.yaml\nheads: [1]\nserial:\n  - {head: 2, port: /dev/x}\n"),
      "infra.yaml:1:1: <root>: serial[0].head: head 2 is not one of the hosted heads "
      "(heads)");
  EXPECT_EQ(LoadError("name: a\ncity: c\nmap: m.yaml\nmonitor: {conflict_persistence_s: 5}\n"),
            "infra.yaml:4:35: monitor.conflict_persistence_s: out of range (got 5; expected a "
            "value in [0.05, 2.0])");
}

TEST(InfraConfigErrors, HeadsMustBeSignalHeadsOfTheMap) {
  TempDir dir;
  const auto path = dir.Write(
      "infra.yaml", "name: a\ncity: c\nmap: " + DrivingSchoolMap() + "\nheads: [1,\n        9]\n");
  const InfraConfig config = LoadInfraConfig(path);
  EXPECT_EQ(test::ErrorMessage<ConfigError>([&] { (void)PlanHost(config, path); }),
            path.string() +
                ":5:9: heads[1]: no signal head 9 in map driving_school (it has 1, 2, "
                "3, 4)");
}

TEST(InfraConfigErrors, SerialHeadsMustBeSignalHeadsOfTheMap) {
  TempDir dir;
  const auto path = dir.Write("infra.yaml", "name: a\ncity: c\nmap: " + DrivingSchoolMap() +
                                                "\nserial:\n  - {head: 12, port: /dev/x}\n");
  const InfraConfig config = LoadInfraConfig(path);
  EXPECT_EQ(test::ErrorMessage<ConfigError>([&] { (void)PlanHost(config, path); }),
            path.string() +
                ":5:12: serial[0].head: no signal head 12 in map driving_school (it "
                "has 1, 2, 3, 4)");
}

TEST(InfraConfigErrors, ASerialDefaultNeedsAPortForEveryHead) {
  TempDir dir;
  const auto path =
      dir.Write("infra.yaml", "name: a\ncity: c\nmap: " + DrivingSchoolMap() +
                                  "\ndefault_backend: serial\nserial:\n  - {head: 1, port: /a}\n");
  const InfraConfig config = LoadInfraConfig(path);
  EXPECT_EQ(test::ErrorMessage<ConfigError>([&] { (void)PlanHost(config, path); }),
            path.string() +
                ":4:18: default_backend: head 2 would use the serial backend but has "
                "no entry in serial (add {head: 2, port: ...})");
}

TEST(InfraConfigErrors, AMissingMapNamesTheResolvedPath) {
  TempDir dir;
  const auto path = dir.Write("infra.yaml", "name: a\ncity: c\nmap: ../nowhere/map.yaml\n");
  const InfraConfig config = LoadInfraConfig(path);
  const std::string resolved = (path.parent_path() / "../nowhere/map.yaml").string();
  EXPECT_EQ(test::ErrorMessage<ConfigError>([&] { (void)PlanHost(config, path); }),
            path.string() + ":3:6: map: cannot load the map " + resolved + " (" + resolved +
                ": cannot read file (No such file or directory))");
}

TEST(HostPlan, ResolvesBackendsAndIntersections) {
  TempDir dir;
  const auto path =
      dir.Write("infra.yaml",
                "name: a\ncity: c\nmap: " + DrivingSchoolMap() +
                    "\nheads: [4, 2]\nserial:\n  - {head: 4, port: /dev/ttyACM3, baud: 9600}\n");
  const HostPlan plan = PlanHost(LoadInfraConfig(path), path);
  ASSERT_EQ(plan.heads.size(), 2u);
  EXPECT_EQ(plan.heads[0].id, SignalHeadId(2)) << "in id order";
  EXPECT_EQ(plan.heads[0].backend, BackendType::kSimulated);
  EXPECT_EQ(plan.heads[1].id, SignalHeadId(4));
  EXPECT_EQ(plan.heads[1].backend, BackendType::kSerial);
  EXPECT_EQ(plan.heads[1].serial->port, "/dev/ttyACM3");
  EXPECT_EQ(plan.heads[1].intersection, plan.map.intersections[0].id);
}

}  // namespace
}  // namespace autodrive::infrastructure
