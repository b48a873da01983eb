#pragma once
/// @file
/// The SCM, its light hosts and scmctl as real processes over DDS, for the system tests: a
/// fixture that starts them on a DDS partition and in a temporary folder of the test's own,
/// and an independent SPaT checker that knows only the wire messages (not the SCM's code).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "autodrive_msgs/msg/DeviceStatus.h"
#include "autodrive_msgs/msg/Event.h"
#include "autodrive_msgs/msg/IntersectionState.h"
#include "autodrive_msgs/msg/SignalGroupState.h"
#include "autodrive_msgs/msg/Spat.h"

#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/process.h"
#include "common/test_support.h"
#include "common/time.h"
#include "tests/spat_checker.h"

namespace autodrive::test {

using SteadyClock = std::chrono::steady_clock;

inline std::string Bin(const std::string& name) {
  const char* dir = std::getenv("AUTODRIVE_BINARY_DIR");
  return std::string(dir ? dir : ".") + "/bin/" + name;
}

inline std::string Config(const std::string& rel) { return (SourceDir() / rel).string(); }

/// A TZ setting in which it is now about noon, so that the cities' schedules run their day
/// plans whatever time of day the test runs at. POSIX TZ "XXX<h>": local time is UTC - h hours.
inline std::string NoonTimeZone() {
  const std::time_t t = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&t, &utc);
  return "TZ=XXX" + std::to_string(utc.tm_hour - 12);
}

struct Output {
  int code = -1;
  std::string text;
};

/// Runs `argv` to the end through the shell, stderr folded into stdout: its exit code (-1 when
/// it did not end within 5 minutes of its last line) and output.
inline Output RunCaptured(const std::vector<std::string>& argv) {
  std::vector<std::string> sh{"/bin/sh", "-c", "exec \"$@\" 2>&1", "sh"};
  sh.insert(sh.end(), argv.begin(), argv.end());
  ChildProcess p(sh, {});
  Output out;
  while (auto line = p.ReadLine(std::chrono::milliseconds(300000))) out.text += *line + "\n";
  out.code = p.Wait(std::chrono::milliseconds(60000)).value_or(-1);
  return out;
}

inline bool AnyGreen(const msg::Spat& s) {
  for (const auto& x : dds::Elements(s.intersections)) {
    for (const auto& g : dds::Elements(x.signal_groups)) {
      if (IsGreen(g.event_state)) return true;
    }
  }
  return false;
}

inline const msg::IntersectionState* FindIntersection(const msg::Spat& s, std::string_view name) {
  for (const auto& x : dds::Elements(s.intersections)) {
    if (dds::View(x.name) == name) return &x;
  }
  return nullptr;
}

/// The last status each device reported.
struct DeviceSeen {
  std::uint8_t health = 255;
  std::uint8_t mode = 255;
  std::uint8_t backend = 0;  ///< DeviceStatus_Constants: 1 simulated, 2 physical
  std::int32_t displayed = -1;
  std::string city;
  std::uint64_t last_command_id = 0;
  Time stamp{};
};

class ScmProcesses : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    partition_ = fmt::format("scm_{}_{}", ::getpid(), info->name());
    dir_ = std::filesystem::temp_directory_path() / partition_;
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    participant_ = std::make_unique<dds::Participant>(dds::ParticipantOptions{{}, partition_, {}});
    spat_ = std::make_unique<dds::Reader<msg::Spat>>(*participant_, dds::topics::Spat().name,
                                                     dds::Qos::Stream(256));
    events_ = std::make_unique<dds::Reader<msg::Event>>(*participant_, dds::topics::Events());
    devices_ = std::make_unique<dds::Reader<msg::DeviceStatus>>(
        *participant_, dds::topics::Devices().name, dds::Qos::LatchedState(256));
  }
  void TearDown() override {
    scm_.reset();
    infras_.clear();
    std::filesystem::remove_all(dir_);
  }

  /// Starts a light host from a shipped config (`config/infra/<name>.yaml`) or a path.
  ChildProcess& StartInfra(const std::string& name = "driving_school",
                           std::vector<std::string> extra = {}) {
    const std::string config =
        name.find('/') == std::string::npos ? Config("config/infra/" + name + ".yaml") : name;
    std::vector<std::string> argv{
        Bin("autodrive-infra"), "--config", config, "--partition", partition_,
        "--log-level",          "warn"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    infras_.push_back(std::make_unique<ChildProcess>(argv));
    return *infras_.back();
  }
  /// Starts the SCM on a shipped city (`config/cities/<name>.yaml`) or a path.
  void StartScm(const std::string& name = "driving_school", std::vector<std::string> extra = {},
                std::vector<std::string> env = {}) {
    const std::string config =
        name.find('/') == std::string::npos ? Config("config/cities/" + name + ".yaml") : name;
    std::vector<std::string> argv{
        Bin("autodrive-scm"),       "--config",    config, "--partition", partition_, "--db",
        (dir_ / "scm.db").string(), "--log-level", "warn"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    env.push_back(NoonTimeZone());
    scm_ = std::make_unique<ChildProcess>(argv, env);
  }
  /// A shipped city file with its map named by absolute path, so that a copy in the test's
  /// folder still finds it (the path stays under the SCM's configuration root).
  std::string CityText(const std::string& city) const {
    std::string text = config::ReadFile(Config("config/cities/" + city + ".yaml"));
    const std::string rel = "../maps/" + city + ".yaml";
    text.replace(text.find(rel), rel.size(), Config("config/maps/" + city + ".yaml"));
    return text;
  }
  /// The DDS domains of the two districts of `SmallTownInDistricts`, this test's own (tests run
  /// two at a time, each in its own partition; the pid keeps their domains apart as well).
  static std::uint32_t Uptown() { return 100 + static_cast<std::uint32_t>(::getpid() % 60); }
  static std::uint32_t Downtown() { return Uptown() + 60; }
  /// The small town's city text in two districts (docs/districts.md): uptown (north_t) on
  /// domain `Uptown()`, downtown (centre) on `Downtown()`; `extra` is added after them.
  std::string SmallTownInDistricts(const std::string& extra = "") const {
    std::string text = CityText("small_town");
    text.insert(text.find("\nfleet:") + 1,
                fmt::format("districts:\n"
                            "  - {{name: uptown, domain: {}, intersections: [north_t]}}\n"
                            "  - {{name: downtown, domain: {}, intersections: [centre]}}\n",
                            Uptown(), Downtown()) +
                    extra);
    return text;
  }
  /// The small town's light host split by `SmallTownInDistricts`' districts, written into the
  /// test's folder as up.yaml (north_t's heads 1-3, host uptown_lights) and down.yaml (centre's
  /// 4-7, downtown_lights); returns their paths.
  std::pair<std::string, std::string> SmallTownDistrictLights() const {
    std::string lights = config::ReadFile(Config("config/infra/small_town.yaml"));
    const std::string map = "../maps/small_town.yaml";
    lights.replace(lights.find(map), map.size(), Config("config/maps/small_town.yaml"));
    const std::string heads = "heads: [1, 2, 3, 4, 5, 6, 7]";
    const std::string name = "name: small_town_lights";
    std::string up = lights, down = lights;
    up.replace(up.find(heads), heads.size(), "heads: [1, 2, 3]");
    up.replace(up.find(name), name.size(), "name: uptown_lights");
    down.replace(down.find(heads), heads.size(), "heads: [4, 5, 6, 7]");
    down.replace(down.find(name), name.size(), "name: downtown_lights");
    return {Write("up.yaml", up), Write("down.yaml", down)};
  }
  /// Writes `text` to `name` in the test's folder; returns its path.
  std::string Write(const std::string& name, const std::string& text) const {
    const auto path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
  }
  /// Runs scmctl; with `as_operator`, as that operator (state-changing commands need one).
  Output Scmctl(std::vector<std::string> args, const std::string& as_operator = "") const {
    std::vector<std::string> argv{Bin("scmctl"), "--partition", partition_, "--timeout", "10"};
    if (!as_operator.empty()) {
      argv.push_back("--operator");
      argv.push_back(as_operator);
    }
    argv.insert(argv.end(), args.begin(), args.end());
    ChildProcess p(argv);
    Output out;
    while (auto line = p.ReadLine(std::chrono::seconds(30))) out.text += *line + "\n";
    out.code = p.Wait(std::chrono::seconds(30)).value_or(-1);
    return out;
  }
  /// As the lab's operator (the shipped cities allow "lab").
  Output Lab(std::vector<std::string> args) const { return Scmctl(std::move(args), "lab"); }

  /// Waits up to `timeout` for a SPaT that `pred` likes; every SPaT taken goes to `checker_`.
  template <typename P>
  std::optional<dds::Message<msg::Spat>> WaitSpat(P pred, SteadyClock::duration timeout) {
    const auto end = SteadyClock::now() + timeout;
    while (SteadyClock::now() < end) {
      spat_->WaitForData(std::chrono::milliseconds(50));
      auto all = spat_->TakeAll();
      for (std::size_t i = 0; i < all.size(); ++i) {
        checker_.Add(*all[i]);
        if (pred(*all[i])) {
          for (std::size_t j = i + 1; j < all.size(); ++j) checker_.Add(*all[j]);
          return std::move(all[i]);
        }
      }
    }
    return std::nullopt;
  }
  /// Takes the SPaT that arrived into the checker; returns how many.
  std::size_t DrainSpat() {
    std::size_t n = 0;
    for (auto& m : spat_->TakeAll()) {
      checker_.Add(*m);
      ++n;
    }
    return n;
  }
  /// Waits up to `timeout` for an event with `code` (and `device_id` when given).
  bool WaitEvent(const std::string& code, SteadyClock::duration timeout,
                 const std::string& device_id = "") {
    const auto end = SteadyClock::now() + timeout;
    for (;;) {
      for (auto& e : events_->TakeAll()) {
        events_seen_.emplace_back(std::string(dds::View(e->code)),
                                  std::string(dds::View(e->device_id)));
      }
      for (const auto& [c, d] : events_seen_) {
        if (c == code && (device_id.empty() || d == device_id)) return true;
      }
      if (SteadyClock::now() >= end) return false;
      events_->WaitForData(std::chrono::milliseconds(50));
    }
  }
  /// Takes the device statuses that arrived into `devices_seen_`.
  void CollectDevices() {
    for (auto& m : devices_->TakeAll()) {
      devices_seen_[std::string(dds::View(m->device_id))] =
          DeviceSeen{m->health,
                     m->mode,
                     m->backend,
                     m->displayed_state,
                     std::string(dds::View(m->city)),
                     m->last_command_id,
                     dds::FromMsg(m->header.stamp)};
    }
  }
  /// Waits up to `timeout` until `pred(devices_seen_)` holds.
  template <typename P>
  bool WaitDevices(P pred, SteadyClock::duration timeout) {
    const auto end = SteadyClock::now() + timeout;
    for (;;) {
      CollectDevices();
      if (pred(devices_seen_)) return true;
      if (SteadyClock::now() >= end) return false;
      devices_->WaitForData(std::chrono::milliseconds(50));
    }
  }
  /// Runs `scmctl status` until its text has `needle`, up to `timeout`.
  bool WaitStatus(const std::string& needle, SteadyClock::duration timeout) {
    const auto end = SteadyClock::now() + timeout;
    for (;;) {
      if (Scmctl({"status"}).text.find(needle) != std::string::npos) return true;
      if (SteadyClock::now() >= end) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));  // paces the retries
    }
  }

  std::string partition_;
  std::filesystem::path dir_;
  std::unique_ptr<dds::Participant> participant_;
  std::unique_ptr<dds::Reader<msg::Spat>> spat_;
  std::unique_ptr<dds::Reader<msg::Event>> events_;
  std::unique_ptr<dds::Reader<msg::DeviceStatus>> devices_;
  std::vector<std::pair<std::string, std::string>> events_seen_;
  std::map<std::string, DeviceSeen> devices_seen_;
  SpatChecker checker_;
  std::vector<std::unique_ptr<ChildProcess>> infras_;
  std::unique_ptr<ChildProcess> scm_;
};

}  // namespace autodrive::test
