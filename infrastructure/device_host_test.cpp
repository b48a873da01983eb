// The device host in-process, over real DDS: a test "SCM" on its own participant talks to a
// DeviceHost whose ticks the test drives with explicit times. Simulated backends are injected
// so that lamp failures can be staged.
#include "infrastructure/device_host.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <map>
#include <thread>

#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/test_support.h"
#include "infrastructure/simulated_backend.h"
#include "maps/map_io.h"

namespace autodrive::infrastructure {
namespace {

using namespace std::chrono_literals;

// What a DeviceStatus said.
struct Status {
  std::uint8_t health = 0;
  std::uint8_t mode = 0;
  std::int32_t displayed = -1;
  std::string detail;
  std::uint8_t backend = 0;
};

// What an Event said.
struct EventSeen {
  std::uint8_t severity = 0;
  std::string source;
  std::string code;
  std::string message;
  std::uint32_t intersection_id = 0;
  std::string device_id;
  bool active = false;
};

dds::Participant Join(const std::string& partition) {
  dds::ParticipantOptions o;
  o.partition = partition;
  return dds::Participant(o);
}

class DeviceHostTest : public ::testing::Test {
 protected:
  DeviceHostTest()
      : partition_("infra_host_" + std::to_string(::getpid()) + "_" +
                   ::testing::UnitTest::GetInstance()->current_test_info()->name()),
        host_side_(Join(partition_)),
        scm_side_(Join(partition_)),
        heartbeat_(scm_side_, dds::topics::Heartbeat()),
        requests_(scm_side_, dds::topics::OperatorRequests()),
        // The topic is keyless and keeps one sample per writer; a reader with the catalogue's
        // depth of 1 would keep only the latest of all the devices' statuses.
        statuses_(scm_side_, dds::topics::Devices().name, dds::Qos::LatchedState(256)),
        events_(scm_side_, dds::topics::Events()),
        host_heartbeats_(scm_side_, dds::topics::Heartbeat()) {
    config_.name = "test";
    config_.map = (test::SourceDir() / "config" / "maps" / "driving_school.yaml").string();
    config_.scm_heartbeat_timeout_s = 1s;
    HostPlan plan = PlanHost(config_, config_.map);
    for (const auto& h : plan.heads) {
      commands_.emplace(h.id.value(), std::make_unique<dds::Writer<msg::Int32>>(
                                          scm_side_, dds::topics::SignalCommand(h.id)));
      states_.emplace(h.id.value(), std::make_unique<dds::Reader<msg::Int32>>(
                                        scm_side_, dds::topics::SignalState(h.id)));
    }
    host_ = std::make_unique<DeviceHost>(config_, std::move(plan), host_side_, Reading(),
                                         [this](const HeadPlan& h) {
                                           auto backend = std::make_unique<SimulatedBackend>();
                                           backends_[h.id.value()] = backend.get();
                                           return backend;
                                         });
  }

  // One 20 ms tick of the host; the test SCM beats every 100 ms while `scm_alive_`.
  void Tick() {
    now_ += 20ms;
    if (scm_alive_ && ticks_++ % 5 == 0) {
      dds::Message<msg::Heartbeat> m;
      dds::SetString(m->sender, "scm");
      m->session_id = 1;
      m->sequence_number = ++scm_sequence_;
      m->period_ms = 100;
      m->state = 1;
      heartbeat_.Write(m);
    }
    std::this_thread::sleep_for(2ms);  // lets DDS deliver: real time, not the host's
    host_->Step(Reading());
    Collect();
  }
  // Ticks until `done()` or 1000 ticks (20 s of host time, ~5 s of real time).
  bool TickUntil(const std::function<bool()>& done) {
    for (int i = 0; i < 1000; ++i) {
      if (done()) return true;
      Tick();
    }
    return done();
  }
  void Command(std::uint32_t head, Aspect aspect) {
    dds::Message<msg::Int32> m;
    m->data = ToWire(aspect);
    commands_.at(head)->Write(m);
  }
  // Brings `head` to `aspect` through red (and green for yellow), waiting for each step.
  void Reach(std::uint32_t head, const std::vector<Aspect>& steps) {
    for (const Aspect a : steps) {
      Command(head, a);
      ASSERT_TRUE(TickUntil([&] {
        const auto& d = host_->device(SignalHeadId(head));
        return d.aspect() == a && !d.in_fail_safe() && state_[head] == StateWire(LampsFor(a));
      })) << SignalHeadName(SignalHeadId(head))
          << " did not reach " << ToString(a);
    }
  }
  void Collect() {
    dds::Message<msg::DeviceStatus> s;
    while (statuses_.TakeOne(s)) {
      status_[std::string(dds::View(s->device_id))] = Status{
          s->health, s->mode, s->displayed_state, std::string(dds::View(s->detail)), s->backend};
    }
    dds::Message<msg::Event> e;
    while (events_.TakeOne(e)) {
      seen_.push_back(EventSeen{e->severity, std::string(dds::View(e->source)),
                                std::string(dds::View(e->code)), std::string(dds::View(e->message)),
                                e->intersection_id, std::string(dds::View(e->device_id)),
                                e->active});
    }
    dds::Message<msg::Int32> m;
    for (auto& [id, reader] : states_) {
      while (reader->TakeOne(m)) state_[id] = m->data;
    }
    dds::Message<msg::Heartbeat> h;
    while (host_heartbeats_.TakeOne(h)) {
      if (dds::View(h->sender) == "infra/test") host_heartbeat_states_.push_back(h->state);
    }
  }
  const EventSeen* FindEvent(const std::string& code, bool active) const {
    for (const auto& e : seen_) {
      if (e.code == code && e.active == active) return &e;
    }
    return nullptr;
  }

  std::string partition_;
  dds::Participant host_side_;
  dds::Participant scm_side_;
  InfraConfig config_;
  dds::Writer<msg::Heartbeat> heartbeat_;
  dds::Writer<msg::OperatorRequest> requests_;
  dds::Reader<msg::DeviceStatus> statuses_;
  dds::Reader<msg::Event> events_;
  dds::Reader<msg::Heartbeat> host_heartbeats_;
  std::map<std::uint32_t, std::unique_ptr<dds::Writer<msg::Int32>>> commands_;
  std::map<std::uint32_t, std::unique_ptr<dds::Reader<msg::Int32>>> states_;
  std::map<std::uint32_t, SimulatedBackend*> backends_;
  std::unique_ptr<DeviceHost> host_;
  ClockReading Reading() const { return {now_, Time(now_.time_since_epoch()), 0}; }
  MonoTime now_ = MonoFromSeconds(1000);
  bool scm_alive_ = true;
  int ticks_ = 0;
  std::uint64_t scm_sequence_ = 0;
  std::map<std::string, Status> status_;
  std::map<std::uint32_t, std::int32_t> state_;
  std::vector<EventSeen> seen_;
  std::vector<std::uint8_t> host_heartbeat_states_;
};

TEST_F(DeviceHostTest, HeadsFollowCommandsAndPublishTheirLampsAndStatus) {
  EXPECT_EQ(host_->heads().size(), 4u);
  Reach(1, {Aspect::kRed, Aspect::kGreen});
  ASSERT_TRUE(TickUntil([&] { return status_["signal_1"].displayed == ToWire(Aspect::kGreen); }));
  const Status s = status_["signal_1"];
  EXPECT_EQ(s.health, 0);
  EXPECT_EQ(s.mode, 0);
  EXPECT_EQ(s.detail, "");
  EXPECT_EQ(s.backend, 1) << "SIMULATED";
  EXPECT_EQ(backends_[1]->aspect(), Aspect::kGreen);
  EXPECT_TRUE(TickUntil([&] { return !host_heartbeat_states_.empty(); }));
  EXPECT_EQ(host_heartbeat_states_.front(), 1) << "RUNNING";
}

TEST_F(DeviceHostTest, HostHeartbeatsAreNotTakenForTheScms) {
  scm_alive_ = false;
  Command(1, Aspect::kRed);
  for (int i = 0; i < 100; ++i) Tick();
  EXPECT_FALSE(host_heartbeat_states_.empty()) << "our own heartbeat went round";
  EXPECT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kFlashingRed);
  EXPECT_EQ(status_["signal_1"].mode, 1) << "FLASH";
  EXPECT_EQ(status_["signal_1"].detail, "start-up; waiting for the SCM's heartbeat");
  EXPECT_EQ(host_->counters().scm_heartbeats, 0u);
}

TEST_F(DeviceHostTest, ABurntOutLampIsReportedAsAFault) {
  Reach(1, {Aspect::kRed, Aspect::kGreen});
  backends_[1]->FailLamp(Lamp::kGreen);
  ASSERT_TRUE(TickUntil([&] { return status_["signal_1"].health == 2; }));
  EXPECT_EQ(status_["signal_1"].detail, "green lamp failed (open_circuit)");
  EXPECT_TRUE(TickUntil([&] { return state_[1] == 0; })) << "the state is what the lamps show";
  ASSERT_TRUE(TickUntil([&] { return FindEvent("lamp_fault", true) != nullptr; }));
  const EventSeen* e = FindEvent("lamp_fault", true);
  EXPECT_EQ(e->severity, 3) << "ALARM";
  EXPECT_EQ(e->source, "infra/test");
  EXPECT_EQ(e->device_id, "signal_1");
  backends_[1]->RepairLamp(Lamp::kGreen);
  EXPECT_TRUE(TickUntil([&] { return status_["signal_1"].health == 0; }));
}

TEST_F(DeviceHostTest, TheMonitorLatchesOnConflictingGreensAndOnlyAnOperatorResetClearsIt) {
  const auto* monitor = host_->monitor(IntersectionId(1));
  ASSERT_NE(monitor, nullptr);
  Reach(1, {Aspect::kRed, Aspect::kGreen});
  Reach(2, {Aspect::kRed});
  Command(2, Aspect::kGreen);  // the device accepts it: conflicts are not its business
  ASSERT_TRUE(TickUntil([&] { return FindEvent("mmu_conflict", true) != nullptr; }));
  const EventSeen latch = *FindEvent("mmu_conflict", true);
  EXPECT_EQ(latch.severity, 4) << "CRITICAL";
  EXPECT_EQ(latch.device_id, "mmu_driving_school_crossing");
  EXPECT_EQ(latch.intersection_id, 1u);
  EXPECT_NE(latch.message.find("signal_1 showed green and signal_2 showed green together"),
            std::string::npos)
      << latch.message;
  for (std::uint32_t h = 1; h <= 4; ++h) {
    EXPECT_EQ(host_->device(SignalHeadId(h)).aspect(), Aspect::kFlashingRed) << h;
  }
  ASSERT_TRUE(TickUntil([&] { return status_["mmu_driving_school_crossing"].health == 2; }));
  EXPECT_EQ(status_["mmu_driving_school_crossing"].mode, 1) << "FLASH";

  // Commands are ignored while latched.
  Command(1, Aspect::kRed);
  for (int i = 0; i < 50; ++i) Tick();
  EXPECT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kFlashingRed);

  // A reset for another intersection does nothing; the right one clears the latch.
  ASSERT_TRUE(requests_.WaitForReaders(1, 10s));
  dds::Message<msg::OperatorRequest> request;
  dds::SetString(request->client_id, "test");
  dds::SetString(request->command, "reset");
  request->request_id = 1;
  request->intersection_id = 7;
  requests_.Write(request);
  for (int i = 0; i < 50; ++i) Tick();
  EXPECT_TRUE(monitor->latched());
  request->request_id = 2;
  request->intersection_id = 1;
  requests_.Write(request);
  ASSERT_TRUE(TickUntil([&] { return FindEvent("mmu_conflict", false) != nullptr; }));
  EXPECT_FALSE(monitor->latched());
  EXPECT_TRUE(TickUntil([&] { return status_["mmu_driving_school_crossing"].health == 0; }));
  // Heads wait for a new command (the latched red is old), then follow it.
  for (int i = 0; i < 20; ++i) Tick();
  EXPECT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kFlashingRed);
  Reach(1, {Aspect::kRed});
}

TEST_F(DeviceHostTest, TheMonitorSeesAGreenLampStuckOnUnderARed) {
  Reach(1, {Aspect::kRed, Aspect::kGreen});
  Reach(3, {Aspect::kRed});
  backends_[3]->StickLamp(Lamp::kGreen);  // the device thinks it shows red
  ASSERT_TRUE(TickUntil([&] { return FindEvent("mmu_conflict", true) != nullptr; }));
  EXPECT_NE(FindEvent("mmu_conflict", true)->message.find("signal_3 showed green"),
            std::string::npos);
}

TEST_F(DeviceHostTest, StoppingSaysStoppingAndOffline) {
  Reach(1, {Aspect::kRed});
  host_->Stop(Reading());
  ASSERT_TRUE(TickUntil([&] { return status_["signal_1"].health == 3; }));
  EXPECT_EQ(status_["signal_1"].detail, "device host infra/test stopped");
  EXPECT_EQ(backends_[1]->aspect(), Aspect::kFlashingRed);
  EXPECT_TRUE(TickUntil([&] {
    return !host_heartbeat_states_.empty() && host_heartbeat_states_.back() == 2;
  })) << "STOPPING";
}

}  // namespace
}  // namespace autodrive::infrastructure
