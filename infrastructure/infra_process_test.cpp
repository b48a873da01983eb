// `autodrive-infra` as a process: the test plays the SCM over DDS on a partition of its own
// (heartbeat, commands) and watches what the device host publishes (lamp states, DeviceStatus,
// events, its heartbeat). One head is physical, through an `autodrive-lamp-emulator` process.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <thread>

#include "common/aspect.h"
#include "common/dds/conversions.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/process.h"
#include "common/test_support.h"

namespace autodrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using SteadyClock = std::chrono::steady_clock;

constexpr std::uint8_t kOk = 0, kDegraded = 1, kFault = 2;
constexpr std::uint8_t kNormal = 0, kFlash = 1;
constexpr std::uint8_t kSimulated = 1, kPhysical = 2;

struct Status {
  std::uint8_t health = 255;
  std::uint8_t mode = 255;
  std::uint8_t backend = 0;
  std::int32_t displayed = -1;
  std::string detail;
  Time stamp{};
  std::string city;
  std::string host;
  std::uint64_t last_command_id = 0;
};

struct EventSeen {
  std::uint8_t severity = 0;
  std::string source;
  std::string code;
  std::string message;
  std::string device_id;
  bool active = false;
  std::uint32_t intersection_id = 0;
};

class InfraProcessTest : public ::testing::Test {
 protected:
  InfraProcessTest()
      : partition_("infra_process_" + std::to_string(::getpid()) + "_" +
                   ::testing::UnitTest::GetInstance()->current_test_info()->name()),
        dir_(fs::temp_directory_path() / partition_),
        participant_(Join(partition_)),
        heartbeat_writer_(participant_, dds::topics::Heartbeat()),
        heartbeats_(participant_, dds::topics::InfraHeartbeat()),
        statuses_(participant_, dds::topics::Devices().name, dds::Qos::LatchedState(256)),
        events_(participant_, dds::topics::Events()),
        device_commands_(participant_, dds::topics::DeviceCommands()) {
    fs::create_directories(dir_);
    for (std::uint32_t h = 1; h <= 7; ++h) {  // the small town has 7 heads, the school 4
      commands_.emplace(h, std::make_unique<dds::Writer<msg::Int32>>(
                               participant_, dds::topics::SignalCommand(SignalHeadId(h))));
      states_.emplace(h, std::make_unique<dds::Reader<msg::Int32>>(
                             participant_, dds::topics::SignalState(SignalHeadId(h))));
    }
  }

  ~InfraProcessTest() override {
    beating_ = false;
    if (scm_thread_.joinable()) scm_thread_.join();
    clock_running_ = false;
    if (clock_thread_.joinable()) clock_thread_.join();
    fs::remove_all(dir_);
  }

  static dds::Participant Join(const std::string& partition) {
    dds::ParticipantOptions o;
    o.partition = partition;
    return dds::Participant(o);
  }

  // Starts the lamp emulator for head 4, then autodrive-infra, and waits for its heartbeat.
  void StartInfra(const std::vector<std::string>& extra_args = {}) {
    emulator_ = std::make_unique<ChildProcess>(
        std::vector<std::string>{ExecutableDir() + "/autodrive-lamp-emulator"});
    const auto port = emulator_->ReadLine(10s);
    ASSERT_TRUE(port.has_value());
    const fs::path config = dir_ / "infra.yaml";
    std::ofstream(config) << "name: proc_test\n"
                          << "city: driving_school\n"
                          << "map: "
                          << (test::SourceDir() / "config/maps/driving_school.yaml").string()
                          << "\nscm_heartbeat_timeout_s: 1.0\n"
                          << "status_period_s: 0.1\n"
                          << "serial:\n  - {head: 4, port: " << *port << "}\n";
    std::vector<std::string> argv{ExecutableDir() + "/autodrive-infra",
                                  "--config",
                                  config.string(),
                                  "--partition",
                                  partition_,
                                  "--log-level",
                                  "warn"};
    argv.insert(argv.end(), extra_args.begin(), extra_args.end());
    infra_ = std::make_unique<ChildProcess>(argv);
    ASSERT_TRUE(Pump([&] { return infra_beats_ > 0; }, 30s)) << "no heartbeat from infra/proc_test";
  }

  // Starts autodrive-infra with the shipped small town config (north_t's signal_1..3 and
  // centre's signal_4..7, simulated) and waits for its heartbeat.
  void StartSmallTown() {
    city_ = "small_town";
    infra_sender_ = "infra/small_town_lights";
    infra_ = std::make_unique<ChildProcess>(
        std::vector<std::string>{ExecutableDir() + "/autodrive-infra", "--config",
                                 (test::SourceDir() / "config/infra/small_town.yaml").string(),
                                 "--partition", partition_, "--log-level", "warn"});
    ASSERT_TRUE(Pump([&] { return infra_beats_ > 0; }, 30s))
        << "no heartbeat from " << infra_sender_;
  }

  // The fake SCM's heartbeat: 10 Hz on a thread of its own while `beating_`.
  void StartBeating() {
    beating_ = true;
    scm_thread_ = std::thread([this] {
      dds::Message<msg::Heartbeat> m;
      dds::SetString(m->sender, "scm");
      dds::SetString(m->city, city_);
      m->session_id = kScmSession;
      m->period_ms = 100;
      m->state = 1;  // RUNNING
      while (beating_) {
        m->sequence_number = ++scm_sequence_;
        // Before the write: the host cannot take a heartbeat earlier than this.
        last_beat_ = SteadyClock::now().time_since_epoch().count();
        heartbeat_writer_.Write(m);
        std::this_thread::sleep_for(100ms);
      }
    });
  }
  // Stops the heartbeat; returns when the last one was sent.
  SteadyClock::time_point StopBeating() {
    beating_ = false;
    scm_thread_.join();
    return SteadyClock::time_point(SteadyClock::duration(last_beat_.load()));
  }

  // A simulator's /clock: from 100 s, 20 ms per 20 ms of wall time while `sim_advancing_`.
  void StartClock() {
    clock_running_ = true;
    clock_thread_ = std::thread([this] {
      dds::Writer<msg::Clock> writer(participant_, dds::topics::Clock());
      msg::Clock m{};
      while (clock_running_) {
        if (sim_advancing_) sim_time_ = sim_time_.load() + 20ms;
        m.clock = dds::ToMsg(sim_time_.load());
        writer.Write(m);
        std::this_thread::sleep_for(20ms);
      }
    });
  }

  void Command(std::uint32_t head, std::int32_t value) {
    dds::Message<msg::Int32> m;
    m->data = value;
    commands_.at(head)->Write(m);
  }

  // Takes everything that arrived, until `done()` or `timeout`.
  bool Pump(const std::function<bool()>& done, std::chrono::milliseconds timeout = 10s) {
    const auto deadline = SteadyClock::now() + timeout;
    for (;;) {
      Collect();
      if (done()) return true;
      if (SteadyClock::now() >= deadline) return false;
      std::this_thread::sleep_for(5ms);
    }
  }
  void Collect() {
    dds::Message<msg::DeviceStatus> s;
    while (statuses_.TakeOne(s)) {
      status_[std::string(dds::View(s->device_id))] = Status{s->health,
                                                             s->mode,
                                                             s->backend,
                                                             s->displayed_state,
                                                             std::string(dds::View(s->detail)),
                                                             dds::FromMsg(s->header.stamp),
                                                             std::string(dds::View(s->city)),
                                                             std::string(dds::View(s->host)),
                                                             s->last_command_id};
    }
    dds::Message<msg::Event> e;
    while (events_.TakeOne(e)) {
      events_seen_.push_back(
          EventSeen{e->severity, std::string(dds::View(e->source)), std::string(dds::View(e->code)),
                    std::string(dds::View(e->message)), std::string(dds::View(e->device_id)),
                    e->active, e->intersection_id});
    }
    dds::Message<msg::Int32> m;
    for (auto& [head, reader] : states_) {
      while (reader->TakeOne(m)) state_[head] = m->data;
    }
    dds::Message<msg::Heartbeat> h;
    while (heartbeats_.TakeOne(h)) {
      if (dds::View(h->sender) != infra_sender_) continue;
      ++infra_beats_;
      infra_state_ = h->state;
    }
  }
  // Waits until signal_<head>'s status shows `aspect` in `mode`.
  bool WaitForAspect(std::uint32_t head, Aspect aspect, std::uint8_t mode,
                     std::chrono::milliseconds timeout = 10s) {
    const std::string id = "signal_" + std::to_string(head);
    return Pump([&] { return status_[id].displayed == ToWire(aspect) && status_[id].mode == mode; },
                timeout);
  }
  const EventSeen* FindEvent(const std::string& code, const std::string& device_id) const {
    for (const auto& e : events_seen_) {
      if (e.code == code && e.device_id == device_id) return &e;
    }
    return nullptr;
  }

  std::string partition_;
  fs::path dir_;
  dds::Participant participant_;
  dds::Writer<msg::Heartbeat> heartbeat_writer_;
  dds::Reader<msg::Heartbeat> heartbeats_;
  dds::Reader<msg::DeviceStatus> statuses_;
  dds::Reader<msg::Event> events_;
  dds::Writer<msg::DeviceCommand> device_commands_;
  std::map<std::uint32_t, std::unique_ptr<dds::Writer<msg::Int32>>> commands_;
  std::map<std::uint32_t, std::unique_ptr<dds::Reader<msg::Int32>>> states_;
  static constexpr std::uint64_t kScmSession = 4242;
  std::string city_ = "driving_school";
  std::string infra_sender_ = "infra/proc_test";
  std::unique_ptr<ChildProcess> emulator_;
  std::unique_ptr<ChildProcess> infra_;
  std::atomic<bool> beating_{false};
  std::atomic<std::uint64_t> scm_sequence_{0};
  std::atomic<SteadyClock::rep> last_beat_{0};
  std::atomic<bool> clock_running_{false};
  std::atomic<bool> sim_advancing_{true};
  std::atomic<Time> sim_time_{TimeFromSeconds(100)};
  std::thread clock_thread_;
  std::thread scm_thread_;
  std::map<std::string, Status> status_;
  std::map<std::uint32_t, std::int32_t> state_;
  std::vector<EventSeen> events_seen_;
  int infra_beats_ = 0;
  std::uint8_t infra_state_ = 255;
};

TEST_F(InfraProcessTest, FollowsTheScmAndFlashesOnItsOwnWhenTheHeartbeatStops) {
  StartInfra();
  // Without the SCM every head flashes red: the state topic alternates red and dark.
  ASSERT_TRUE(WaitForAspect(1, Aspect::kFlashingRed, kFlash));
  EXPECT_EQ(status_["signal_1"].detail, "start-up; waiting for the SCM's heartbeat");
  EXPECT_TRUE(Pump([&] { return state_[1] == 1; }));
  EXPECT_TRUE(Pump([&] { return state_[1] == 0; }));

  StartBeating();
  Command(1, ToWire(Aspect::kRed));
  ASSERT_TRUE(WaitForAspect(1, Aspect::kRed, kNormal));
  EXPECT_TRUE(Pump([&] { return state_[1] == 1; }));
  Command(1, ToWire(Aspect::kGreen));
  ASSERT_TRUE(WaitForAspect(1, Aspect::kGreen, kNormal));
  EXPECT_TRUE(Pump([&] { return state_[1] == 3; }));
  EXPECT_EQ(status_["signal_1"].health, kOk);
  EXPECT_EQ(status_["signal_1"].backend, kSimulated);

  // The SCM falls silent: flash after the 1 s timeout, not before.
  const auto silent_since = StopBeating();
  ASSERT_TRUE(WaitForAspect(1, Aspect::kFlashingRed, kFlash, 5s));
  const auto took = SteadyClock::now() - silent_since;
  EXPECT_GT(took, 950ms);
  EXPECT_LT(took, 3s) << "1 s timeout, 20 ms ticks, and a margin for a sanitizer on a loaded "
                         "machine (not for a host that never times out)";
  EXPECT_EQ(status_["signal_1"].detail, "lost SCM heartbeat; waiting for the SCM's heartbeat");
  ASSERT_TRUE(Pump([&] { return FindEvent("local_flash", "signal_1") != nullptr; }));
  EXPECT_EQ(FindEvent("local_flash", "signal_1")->source, "infra/proc_test");

  // The heartbeat returns: the latched green must not come back; a new red ends the flash.
  StartBeating();
  EXPECT_TRUE(Pump([&] {
    return status_["signal_1"].detail ==
           "lost SCM heartbeat; waiting for a new red, off or flashing command";
  }));
  EXPECT_FALSE(WaitForAspect(1, Aspect::kGreen, kNormal, 500ms));
  Command(1, ToWire(Aspect::kRed));
  EXPECT_TRUE(WaitForAspect(1, Aspect::kRed, kNormal));

  EXPECT_EQ(infra_->Stop(30s), 0);
}

TEST_F(InfraProcessTest, RefusesIllegalCommandsAndCarriesOn) {
  StartInfra();
  StartBeating();
  for (const Aspect a : {Aspect::kRed, Aspect::kGreen}) {
    Command(2, ToWire(a));
    ASSERT_TRUE(WaitForAspect(2, a, kNormal));
  }
  Command(2, ToWire(Aspect::kRed));  // green -> red skips yellow
  ASSERT_TRUE(Pump([&] { return status_["signal_2"].health == kDegraded; }));
  EXPECT_EQ(status_["signal_2"].detail, "refused green -> red: a green must end in yellow");
  EXPECT_EQ(status_["signal_2"].displayed, ToWire(Aspect::kGreen));
  ASSERT_TRUE(Pump([&] { return FindEvent("illegal_sequence", "signal_2") != nullptr; }));
  const EventSeen& e = *FindEvent("illegal_sequence", "signal_2");
  EXPECT_EQ(e.severity, 2) << "WARNING";
  EXPECT_EQ(e.source, "infra/proc_test");
  EXPECT_EQ(e.message, "signal_2 refused green -> red: a green must end in yellow");

  Command(2, 9);  // not an aspect
  ASSERT_TRUE(Pump(
      [&] { return status_["signal_2"].detail == "refused command 9: not an aspect (0..5)"; }));
  EXPECT_EQ(status_["signal_2"].displayed, ToWire(Aspect::kGreen));
  Command(2, ToWire(Aspect::kYellow));
  EXPECT_TRUE(WaitForAspect(2, Aspect::kYellow, kNormal));
  EXPECT_TRUE(Pump([&] { return status_["signal_2"].health == kOk; }));
  EXPECT_TRUE(infra_->running());
}

TEST_F(InfraProcessTest, APhysicalHeadFollowsThroughItsControllerAndReportsItsLamps) {
  StartInfra();
  StartBeating();
  Command(4, ToWire(Aspect::kRed));
  ASSERT_TRUE(WaitForAspect(4, Aspect::kRed, kNormal));
  EXPECT_EQ(status_["signal_4"].backend, kPhysical);
  EXPECT_TRUE(Pump([&] { return state_[4] == 1; })) << "the lamps as the controller senses them";
  EXPECT_NE(emulator_->pid(), infra_->pid());
  emulator_->Write("fail red\n");
  ASSERT_EQ(emulator_->ReadLine(10s), "ok fail red");
  ASSERT_TRUE(Pump([&] { return status_["signal_4"].health == kFault; }));
  EXPECT_EQ(status_["signal_4"].detail, "red lamp failed (open_circuit)");
  EXPECT_TRUE(Pump([&] { return state_[4] == 0; })) << "a burnt-out red is dark";
}

TEST_F(InfraProcessTest, StopsPromptlyOnSigtermAndSaysSo) {
  StartInfra();
  ASSERT_EQ(::kill(infra_->pid(), SIGTERM), 0);
  // Promptly: the host stops within its loop's pass (seconds at most under a sanitizer); the
  // deadline only tells that from a host that ignores SIGTERM.
  const auto code = infra_->Wait(30s);
  ASSERT_TRUE(code.has_value()) << "still running 30 s after SIGTERM";
  EXPECT_EQ(*code, 0);
  EXPECT_TRUE(Pump([&] { return infra_state_ == 2; })) << "a STOPPING heartbeat";
  EXPECT_TRUE(
      Pump([&] { return status_["signal_1"].detail == "device host infra/proc_test stopped"; }));
  // The physical head was left flashing red (its controller's watchdog would do it anyway).
  std::string status;
  for (int i = 0; i < 100 && status.find("aspect=flashing_red") == std::string::npos; ++i) {
    emulator_->Write("status\n");
    status = emulator_->ReadLine(10s).value_or("");
  }
  EXPECT_NE(status.find("aspect=flashing_red"), std::string::npos) << status;
}

TEST_F(InfraProcessTest, OnTheSimulatedClockTimeIsTheSimulatorsTime) {
  StartClock();
  StartInfra({"--clock", "sim"});
  StartBeating();
  Command(1, ToWire(Aspect::kRed));
  Command(4, ToWire(Aspect::kRed));
  ASSERT_TRUE(WaitForAspect(1, Aspect::kRed, kNormal));
  ASSERT_TRUE(WaitForAspect(4, Aspect::kRed, kNormal));
  const Time stamp = status_["signal_1"].stamp;
  EXPECT_GE(stamp, TimeFromSeconds(100)) << "stamped in /clock time: " << ToString(stamp);
  EXPECT_LT(stamp, TimeFromSeconds(200)) << "stamped in /clock time: " << ToString(stamp);

  // The simulation pauses and the SCM falls silent: no simulated time passes, no flash.
  sim_advancing_ = false;
  StopBeating();
  EXPECT_FALSE(WaitForAspect(1, Aspect::kFlashingRed, kFlash, 2500ms));
  // The serial link lives in real time: the physical head's controller was kept alive (its
  // watchdog would have flashed red after 2 s of silence).
  emulator_->Write("status\n");
  const std::string mcu = emulator_->ReadLine(10s).value_or("");
  EXPECT_NE(mcu.find("aspect=red"), std::string::npos) << mcu;
  EXPECT_NE(mcu.find("watchdog=0"), std::string::npos) << mcu;
  // The simulation resumes without the SCM: a second of simulated time later, it flashes.
  const Time resumed = sim_time_.load();
  sim_advancing_ = true;
  ASSERT_TRUE(WaitForAspect(1, Aspect::kFlashingRed, kFlash));
  // The last heartbeat was taken up to a period (and the host's view of /clock) before the
  // pause: at least half the 1 s time-out was left when the simulation resumed.
  EXPECT_GE(status_["signal_1"].stamp - resumed, 500ms);
  EXPECT_EQ(infra_->Stop(30s), 0) << "a blocked simulated clock does not delay shutdown";
}

TEST_F(InfraProcessTest, ADeviceCommandResetsExactlyTheMonitorItNames) {
  StartSmallTown();
  StartBeating();
  // Both intersections latch: two conflicting greens each.
  for (const std::uint32_t h : {1u, 2u, 4u, 5u}) Command(h, ToWire(Aspect::kRed));
  for (const std::uint32_t h : {1u, 2u, 4u, 5u})
    ASSERT_TRUE(WaitForAspect(h, Aspect::kRed, kNormal));
  for (const std::uint32_t h : {1u, 2u, 4u, 5u}) Command(h, ToWire(Aspect::kGreen));
  ASSERT_TRUE(Pump([&] {
    return status_["mmu_north_t"].health == kFault && status_["mmu_centre"].health == kFault;
  })) << "both monitors latch";
  EXPECT_EQ(status_["mmu_north_t"].city, "small_town");
  EXPECT_EQ(status_["mmu_north_t"].host, "infra/small_town_lights");
  EXPECT_EQ(status_["mmu_north_t"].last_command_id, 0u);
  ASSERT_TRUE(Pump([&] { return FindEvent("mmu_conflict", "mmu_north_t") != nullptr; }));
  const std::uint32_t north_t = FindEvent("mmu_conflict", "mmu_north_t")->intersection_id;
  ASSERT_NE(north_t, 0u);

  // The SCM accepted an operator's reset of north_t.
  ASSERT_TRUE(device_commands_.WaitForReaders(1, 10s));
  dds::Message<msg::DeviceCommand> reset;
  dds::SetString(reset->city, "small_town");
  reset->scm_session = kScmSession;
  reset->command_id = 1;
  dds::SetString(reset->device_id, "mmu_north_t");
  reset->intersection_id = north_t;
  reset->command = autodrive_msgs_msg_DeviceCommand_Constants_RESET_MONITOR;
  dds::SetString(reset->issued_by, "alice");
  reset->request_id = 7;
  device_commands_.Write(reset);
  ASSERT_TRUE(Pump([&] {
    return status_["mmu_north_t"].health == kOk && status_["mmu_north_t"].last_command_id == 1;
  })) << "north_t reset and acknowledged";
  EXPECT_EQ(status_["mmu_centre"].health, kFault);
  EXPECT_EQ(status_["mmu_centre"].last_command_id, 0u);
  // north_t's heads follow a new red; centre stays latched and its heads flash.
  Command(1, ToWire(Aspect::kRed));
  EXPECT_TRUE(WaitForAspect(1, Aspect::kRed, kNormal));
  Command(4, ToWire(Aspect::kRed));
  EXPECT_FALSE(WaitForAspect(4, Aspect::kRed, kNormal, 500ms));
  EXPECT_EQ(status_["mmu_centre"].health, kFault);
  EXPECT_EQ(status_["signal_4"].mode, kFlash);
  EXPECT_EQ(infra_->Stop(30s), 0);
}

TEST(InfraProgram, RefusesABadConfigNamingFileLineAndKey) {
  const fs::path config =
      fs::temp_directory_path() / ("infra_bad_" + std::to_string(::getpid()) + ".yaml");
  std::ofstream(config) << "name: x\ncity: c\nmap: m.yaml\nflash_period_s: 0\n";
  ChildProcess infra({ExecutableDir() + "/autodrive-infra", "--config", config.string()});
  EXPECT_EQ(infra.Wait(30s), 1);
  fs::remove(config);
}

}  // namespace
}  // namespace autodrive
