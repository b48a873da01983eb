// The device host in-process, over real DDS: a test "SCM" on its own participant talks to a
// DeviceHost whose passes the test drives with explicit times. Simulated backends are injected
// so that lamp failures can be staged. Nothing waits for a fixed time: after writing, the test
// steps the host (at the same host time) until it has taken what was written, and it waits
// for what the host publishes with a generous real-time deadline.
#include "infrastructure/device_host.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <map>
#include <thread>

#include "common/dds/conversions.h"
#include "common/dds/identity.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/test_support.h"
#include "infrastructure/simulated_backend.h"

namespace autodrive::infrastructure {
namespace {

using namespace std::chrono_literals;
using SteadyClock = std::chrono::steady_clock;

// How long the test waits in real time for something that should happen at once.
constexpr auto kPatience = 10s;

constexpr std::uint8_t kOk = 0, kFault = 2, kOffline = 3;
constexpr std::uint8_t kNormal = 0, kFlash = 1;
constexpr std::uint8_t kWarning = 2, kCritical = 4;

// What a DeviceStatus said.
struct Status {
  std::uint8_t health = 255;
  std::uint8_t mode = 255;
  std::int32_t displayed = -1;
  std::string detail;
  std::uint8_t backend = 0;
  std::string city;
  std::string host;
  std::uint64_t last_command_id = 0;
  Time stamp{};
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
  DeviceHostTest() : DeviceHostTest("driving_school") {}
  // A host of every head of config/maps/<map>.yaml, serving city <map>.
  explicit DeviceHostTest(const std::string& map)
      : partition_("infra_host_" + std::to_string(::getpid()) + "_" +
                   ::testing::UnitTest::GetInstance()->current_test_info()->name()),
        host_side_(Join(partition_)),
        scm_side_(Join(partition_)),
        heartbeat_(scm_side_, dds::topics::Heartbeat()),
        device_commands_(scm_side_, dds::topics::DeviceCommands()),
        // The topic is keyless and keeps one sample per writer; a reader with the catalogue's
        // depth of 1 would keep only the latest of all the devices' statuses.
        statuses_(scm_side_, dds::topics::Devices().name, dds::Qos::LatchedState(256)),
        events_(scm_side_, dds::topics::Events()),
        host_heartbeats_(scm_side_, dds::topics::InfraHeartbeat()) {
    config_.name = "test";
    config_.city = map;
    config_.map = (test::SourceDir() / "config" / "maps" / (map + ".yaml")).string();
    config_.scm_heartbeat_timeout_s = 1s;
    HostPlan plan = PlanHost(config_, config_.map);
    for (const auto& x : plan.map.intersections) intersections_.emplace(x.name, x.id);
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
    EXPECT_TRUE(device_commands_.WaitForReaders(1, kPatience)) << "device commands are volatile";
  }

  // The host's time now: explicit, or read from `wall_` when a test installs one.
  ClockReading Reading() const {
    if (wall_) return wall_->Read();
    return {now_, Time(now_.time_since_epoch()), clock_session_};
  }

  // One 20 ms step of host time; the test SCM beats every 100 ms while `scm_alive_`.
  void Tick() {
    now_ += 20ms;
    if (scm_alive_ && ticks_++ % 5 == 0) Beat();
    Deliver();
    Collect();
  }
  // An SCM heartbeat (sender "scm").
  void Beat(const std::string& city = "", std::uint64_t session = 0, std::uint8_t state = 1) {
    dds::Message<msg::Heartbeat> m;
    dds::SetString(m->sender, "scm");
    dds::SetString(m->city, city.empty() ? config_.city : city);
    m->session_id = session == 0 ? scm_session_ : session;
    m->sequence_number = ++scm_sequence_;
    m->period_ms = 100;
    m->state = state;
    heartbeat_.Write(m);
    ++sent_heartbeats_;
  }
  // Steps the host at the current host time until it has taken every sample the test wrote
  // (light and device commands of every writer, SCM heartbeats).
  void Deliver() {
    const auto deadline = SteadyClock::now() + kPatience;
    for (;;) {
      host_->Step(Reading());
      const HostCounters& c = host_->counters();
      if (c.scm_heartbeats >= sent_heartbeats_ && c.commands >= sent_commands_ &&
          c.device_commands >= sent_device_commands_) {
        return;
      }
      if (SteadyClock::now() > deadline) {
        ADD_FAILURE() << "the host did not take what the test wrote: heartbeats "
                      << c.scm_heartbeats << "/" << sent_heartbeats_ << ", commands " << c.commands
                      << "/" << sent_commands_ << ", device commands " << c.device_commands << "/"
                      << sent_device_commands_;
        return;
      }
      std::this_thread::sleep_for(100us);
    }
  }
  // Ticks until `done()` or 1000 ticks (20 s of host time).
  bool TickUntil(const std::function<bool()>& done) {
    for (int i = 0; i < 1000; ++i) {
      if (done()) return true;
      Tick();
    }
    return done();
  }
  // Steps the host without moving its time until `done()` (on what the test's readers got),
  // or `kPatience` of real time.
  bool Settle(const std::function<bool()>& done) {
    const auto deadline = SteadyClock::now() + kPatience;
    for (;;) {
      Collect();
      if (done()) return true;
      if (SteadyClock::now() > deadline) return false;
      host_->Step(Reading());
      std::this_thread::sleep_for(100us);
    }
  }
  void Command(std::uint32_t head, Aspect aspect) {
    dds::Message<msg::Int32> m;
    m->data = ToWire(aspect);
    commands_.at(head)->Write(m);
    ++sent_commands_;
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
  // Makes `a` and `b` (conflicting heads of one intersection) green together until that
  // intersection's monitor latches.
  void Latch(std::uint32_t a, std::uint32_t b, const std::string& intersection) {
    Reach(a, {Aspect::kRed, Aspect::kGreen});
    Reach(b, {Aspect::kRed});
    Command(b, Aspect::kGreen);  // the device accepts it: conflicts are not its business
    const auto* monitor = host_->monitor(intersections_.at(intersection));
    ASSERT_NE(monitor, nullptr);
    ASSERT_TRUE(TickUntil([&] { return monitor->latched(); })) << intersection;
  }
  // The SCM's device command: reset the monitor of `intersection`.
  dds::Message<msg::DeviceCommand> Reset(const std::string& intersection,
                                         std::uint64_t command_id) {
    dds::Message<msg::DeviceCommand> m;
    dds::SetString(m->city, config_.city);
    m->scm_session = scm_session_;
    m->command_id = command_id;
    dds::SetString(m->device_id, "mmu_" + intersection);
    m->intersection_id = intersections_.at(intersection).value();
    m->command = autodrive_msgs_msg_DeviceCommand_Constants_RESET_MONITOR;
    dds::SetString(m->issued_by, "alice");
    m->request_id = 40 + command_id;
    return m;
  }
  void Send(const dds::Message<msg::DeviceCommand>& m) {
    device_commands_.Write(m);
    ++sent_device_commands_;
  }
  void Collect() {
    dds::Message<msg::DeviceStatus> s;
    while (statuses_.TakeOne(s)) {
      status_[std::string(dds::View(s->device_id))] = Status{s->health,
                                                             s->mode,
                                                             s->displayed_state,
                                                             std::string(dds::View(s->detail)),
                                                             s->backend,
                                                             std::string(dds::View(s->city)),
                                                             std::string(dds::View(s->host)),
                                                             s->last_command_id,
                                                             dds::FromMsg(s->header.stamp)};
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
      if (dds::View(h->sender) == "infra/test") {
        host_heartbeat_states_.push_back(h->state);
        host_heartbeat_cities_.emplace_back(dds::View(h->city));
        host_heartbeat_stamps_.push_back(dds::FromMsg(h->header.stamp));
      }
    }
  }
  const EventSeen* FindEvent(const std::string& code, bool active = true,
                             const std::string& device_id = "") const {
    for (const auto& e : seen_) {
      if (e.code == code && e.active == active && (device_id.empty() || e.device_id == device_id)) {
        return &e;
      }
    }
    return nullptr;
  }
  std::size_t CountEvents(const std::string& code) const {
    std::size_t n = 0;
    for (const auto& e : seen_) n += e.code == code ? 1u : 0u;
    return n;
  }

  std::string partition_;
  dds::Participant host_side_;
  dds::Participant scm_side_;
  InfraConfig config_;
  dds::Writer<msg::Heartbeat> heartbeat_;
  dds::Writer<msg::DeviceCommand> device_commands_;
  dds::Reader<msg::DeviceStatus> statuses_;
  dds::Reader<msg::Event> events_;
  dds::Reader<msg::Heartbeat> host_heartbeats_;
  std::map<std::uint32_t, std::unique_ptr<dds::Writer<msg::Int32>>> commands_;
  std::map<std::uint32_t, std::unique_ptr<dds::Reader<msg::Int32>>> states_;
  std::map<std::uint32_t, SimulatedBackend*> backends_;
  std::map<std::string, IntersectionId> intersections_;
  MonoTime now_ = MonoFromSeconds(1000);
  std::uint64_t clock_session_ = 0;
  std::unique_ptr<WallClock> wall_;
  std::unique_ptr<DeviceHost> host_;
  bool scm_alive_ = true;
  int ticks_ = 0;
  std::uint64_t scm_session_ = 0x5c0ffee;
  std::uint64_t scm_sequence_ = 0;
  std::uint64_t sent_heartbeats_ = 0;
  std::uint64_t sent_commands_ = 0;
  std::uint64_t sent_device_commands_ = 0;
  std::map<std::string, Status> status_;
  std::map<std::uint32_t, std::int32_t> state_;
  std::vector<EventSeen> seen_;
  std::vector<std::uint8_t> host_heartbeat_states_;
  std::vector<std::string> host_heartbeat_cities_;
  std::vector<Time> host_heartbeat_stamps_;
};

// Two signalised intersections on one host: north_t (signal_1..3) and centre (signal_4..7).
class SmallTownHostTest : public DeviceHostTest {
 protected:
  SmallTownHostTest() : DeviceHostTest("small_town") {}
};

TEST_F(DeviceHostTest, HeadsFollowCommandsAndPublishTheirLampsAndStatus) {
  EXPECT_EQ(host_->heads().size(), 4u);
  Reach(1, {Aspect::kRed, Aspect::kGreen});
  ASSERT_TRUE(TickUntil([&] { return status_["signal_1"].displayed == ToWire(Aspect::kGreen); }));
  const Status s = status_["signal_1"];
  EXPECT_EQ(s.health, kOk);
  EXPECT_EQ(s.mode, kNormal);
  EXPECT_EQ(s.detail, "");
  EXPECT_EQ(s.backend, 1) << "SIMULATED";
  EXPECT_EQ(s.city, "driving_school");
  EXPECT_EQ(s.host, "infra/test");
  EXPECT_EQ(s.last_command_id, 0u);
  EXPECT_EQ(backends_[1]->aspect(), Aspect::kGreen);
  ASSERT_TRUE(Settle([&] { return status_.count("mmu_driving_school_crossing") > 0; }));
  EXPECT_EQ(status_["mmu_driving_school_crossing"].city, "driving_school");
  EXPECT_EQ(status_["mmu_driving_school_crossing"].last_command_id, 0u) << "none carried out";
  EXPECT_TRUE(TickUntil([&] { return !host_heartbeat_states_.empty(); }));
  EXPECT_EQ(host_heartbeat_states_.front(), 1) << "RUNNING";
  EXPECT_EQ(host_heartbeat_cities_.front(), "driving_school");
  EXPECT_EQ(host_->counters().scm_changes, 1u) << "one SCM followed from the start";
}

// The host's heartbeat goes on the device hosts' topic, never on the SCM's, and the host does
// not read the device hosts' topic: an "scm" heartbeat there (what any light host's identity may
// write) is not followed.
TEST_F(DeviceHostTest, HostHeartbeatsGoOnTheirOwnTopicAndAreNotTakenForTheScms) {
  scm_alive_ = false;
  dds::Participant other = Join(partition_);
  dds::Reader<msg::Heartbeat> scm_topic(other, dds::topics::Heartbeat());
  dds::Reader<msg::Heartbeat> infra_topic(other, dds::topics::InfraHeartbeat());
  dds::Writer<msg::Heartbeat> forger(other, dds::topics::InfraHeartbeat());
  ASSERT_TRUE(scm_topic.WaitForWriters(1, kPatience)) << "the test's SCM heartbeat writer";
  ASSERT_TRUE(forger.WaitForReaders(2, kPatience)) << "this test's two readers";
  dds::Message<msg::Heartbeat> forged;
  dds::SetString(forged->sender, "scm");
  dds::SetString(forged->city, config_.city);
  forged->session_id = scm_session_;
  forged->state = 1;  // RUNNING
  Command(1, Aspect::kRed);
  for (int i = 0; i < 100; ++i) {
    forged->sequence_number = static_cast<std::uint64_t>(i);
    if (i % 5 == 0) forger.Write(forged);
    Tick();
  }
  EXPECT_FALSE(host_heartbeat_states_.empty()) << "our own heartbeat went round";
  // Once the other participant has heard the host's heartbeat it knows the host's endpoints:
  // none of them reads the device hosts' topic or writes the SCM's.
  const auto deadline = SteadyClock::now() + kPatience;
  bool host_heard = false;
  dds::Message<msg::Heartbeat> m;
  while (!host_heard && SteadyClock::now() < deadline) {
    infra_topic.WaitForData(100ms);
    while (infra_topic.TakeOne(m)) host_heard = host_heard || dds::View(m->sender) == "infra/test";
  }
  ASSERT_TRUE(host_heard);
  EXPECT_EQ(scm_topic.matched_writers(), 1u) << "the host writes no SCM heartbeat";
  EXPECT_EQ(forger.matched_readers(), 2u) << "the host reads no device host's heartbeat";
  EXPECT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kFlashingRed);
  EXPECT_EQ(status_["signal_1"].mode, kFlash);
  EXPECT_EQ(status_["signal_1"].detail, "start-up; waiting for the SCM's heartbeat");
  EXPECT_EQ(host_->counters().scm_heartbeats, 0u);
  EXPECT_EQ(host_->counters().held_commands, 1u) << "kept until an SCM is known";
}

TEST_F(DeviceHostTest, ABurntOutLampIsReportedAsAFault) {
  Reach(1, {Aspect::kRed, Aspect::kGreen});
  backends_[1]->FailLamp(Lamp::kGreen);
  ASSERT_TRUE(TickUntil([&] { return status_["signal_1"].health == kFault; }));
  EXPECT_EQ(status_["signal_1"].detail, "green lamp failed (open_circuit)");
  EXPECT_TRUE(TickUntil([&] { return state_[1] == 0; })) << "the state is what the lamps show";
  ASSERT_TRUE(TickUntil([&] { return FindEvent("lamp_fault") != nullptr; }));
  const EventSeen* e = FindEvent("lamp_fault");
  EXPECT_EQ(e->severity, 3) << "ALARM";
  EXPECT_EQ(e->source, "infra/test");
  EXPECT_EQ(e->device_id, "signal_1");
  backends_[1]->RepairLamp(Lamp::kGreen);
  EXPECT_TRUE(TickUntil([&] { return status_["signal_1"].health == kOk; }));
}

TEST_F(DeviceHostTest, TheTwinsFaultInjectionBurnsALampUnplugsAHeadAndRefusesWhatIsNotAFault) {
  // A scenario's events, over DDS: what SimulatedBackend does in the tests above.
  dds::Writer<msg::SimFault> faults(scm_side_, dds::topics::SimFaults());
  ASSERT_TRUE(faults.WaitForReaders(1, kPatience)) << "the host reads faults: its heads simulate";
  const auto inject = [&](std::uint32_t head, std::uint8_t action, std::uint8_t lamp,
                          const std::string& reason = "") {
    dds::Message<msg::SimFault> m;
    dds::SetString(m->header.frame_id, "scenario");
    m->head = head;
    m->action = action;
    m->lamp = lamp;
    dds::SetString(m->reason, reason);
    faults.Write(m);
  };
  Reach(1, {Aspect::kRed, Aspect::kGreen});
  inject(1, autodrive_msgs_msg_SimFault_Constants_FAIL_LAMP,
         autodrive_msgs_msg_SimFault_Constants_GREEN);
  ASSERT_TRUE(TickUntil([&] { return status_["signal_1"].health == kFault; }));
  EXPECT_EQ(status_["signal_1"].detail, "green lamp failed (open_circuit)");
  ASSERT_TRUE(TickUntil([&] { return FindEvent("sim_fault", false, "signal_1") != nullptr; }));
  EXPECT_NE(FindEvent("sim_fault", false)->message.find("green lamp burnt out"), std::string::npos)
      << FindEvent("sim_fault", false)->message;
  EXPECT_NE(FindEvent("sim_fault", false)->message.find("'scenario'"), std::string::npos);
  inject(1, autodrive_msgs_msg_SimFault_Constants_REPAIR_LAMP,
         autodrive_msgs_msg_SimFault_Constants_GREEN);
  EXPECT_TRUE(TickUntil([&] { return status_["signal_1"].health == kOk; }));

  inject(2, autodrive_msgs_msg_SimFault_Constants_UNPLUG_HEAD, 0, "cable pulled");
  ASSERT_TRUE(TickUntil([&] { return status_["signal_2"].health == kOffline; }));
  EXPECT_NE(FindEvent("device_offline", true, "signal_2"), nullptr);
  inject(2, autodrive_msgs_msg_SimFault_Constants_PLUG_HEAD, 0);
  EXPECT_TRUE(TickUntil([&] { return status_["signal_2"].health != kOffline; }));

  // Not a fault: an unknown action, a lamp that is none. Another host's head: not ours.
  inject(3, 9, 0);
  inject(3, autodrive_msgs_msg_SimFault_Constants_FAIL_LAMP, 7);
  inject(99, autodrive_msgs_msg_SimFault_Constants_UNPLUG_HEAD, 0);
  ASSERT_TRUE(TickUntil([&] { return CountEvents("sim_fault_refused") == 2; }));
  EXPECT_EQ(host_->counters().sim_faults_refused, 2U);
  EXPECT_EQ(host_->counters().sim_faults, 4U);
  EXPECT_EQ(host_->device(SignalHeadId(3)).health(), Health::kOk);
}

TEST_F(DeviceHostTest, ACutLinkDropsTheScmsTrafficAndSilencesTheHostUntilItIsRestored) {
  dds::Writer<msg::SimFault> faults(scm_side_, dds::topics::SimFaults());
  ASSERT_TRUE(faults.WaitForReaders(1, kPatience));
  const auto link = [&](const std::string& host, std::uint8_t action) {
    dds::Message<msg::SimFault> m;
    dds::SetString(m->header.frame_id, "scenario");
    dds::SetString(m->host, host);
    m->action = action;
    faults.Write(m);
  };
  Reach(1, {Aspect::kRed, Aspect::kGreen});
  // Another host's link: nothing happens here (taken before the next, from the same writer).
  link("elsewhere", autodrive_msgs_msg_SimFault_Constants_LINK_CUT);
  link("test", autodrive_msgs_msg_SimFault_Constants_LINK_CUT);
  // The pass that cut it is the one at which the counter moved: everything the host sent before
  // is stamped earlier, whenever it arrives (so a loaded machine cannot fool what follows).
  ASSERT_TRUE(TickUntil([&] { return host_->counters().sim_faults == 1; }));
  const Time cut_at = Reading().wire;
  ASSERT_TRUE(Settle([&] { return FindEvent("sim_fault", false) != nullptr; }))
      << "said before the link goes";
  EXPECT_NE(FindEvent("sim_fault", false)->message.find("the link with the SCM is cut"),
            std::string::npos);
  const auto heard_since = [&](Time t) {
    const bool beat = std::ranges::any_of(host_heartbeat_stamps_, [&](Time s) { return s >= t; });
    const bool status =
        std::ranges::any_of(status_, [&](const auto& s) { return s.second.stamp >= t; });
    return beat || status;
  };
  // The SCM goes on beating and commanding: all of it is lost, so the head falls back to its
  // own flash after the heartbeat time-out (1 s), and nothing of the host reaches the SCM.
  Command(1, Aspect::kYellow);
  ASSERT_TRUE(TickUntil([&] { return host_->device(SignalHeadId(1)).in_fail_safe(); }));
  EXPECT_GT(host_->counters().dropped_on_cut_link, 5U);
  EXPECT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kFlashingRed);
  for (int i = 0; i < 100; ++i) Tick();  // 2 s: two status periods
  EXPECT_FALSE(heard_since(cut_at)) << "no heartbeat or status from the cut on";
  EXPECT_EQ(FindEvent("local_flash", true, "signal_1"), nullptr) << "not heard: the link is cut";
  // The lamps still light: the cars see the flash.
  EXPECT_TRUE(TickUntil([&] { return state_[1] == 0; }));
  EXPECT_TRUE(TickUntil([&] { return state_[1] == 1; }));
  // Restored: the host is heard again (heartbeat and statuses stamped after the restore) and
  // follows the SCM's next commands.
  link("test", autodrive_msgs_msg_SimFault_Constants_LINK_RESTORE);
  ASSERT_TRUE(TickUntil([&] { return host_->counters().sim_faults == 2; }));
  const Time restored_at = Reading().wire;
  EXPECT_TRUE(TickUntil([&] {
    return std::ranges::any_of(host_heartbeat_stamps_, [&](Time t) { return t >= restored_at; }) &&
           std::ranges::any_of(status_,
                               [&](const auto& x) { return x.second.stamp >= restored_at; });
  }));
  EXPECT_EQ(host_->counters().sim_faults, 2U);
  // A command counts once the SCM's heartbeat is heard again (the device's rule after a loss).
  ASSERT_TRUE(TickUntil([&] { return host_->device(SignalHeadId(1)).scm_alive(); }));
  Reach(1, {Aspect::kRed});
}

TEST_F(DeviceHostTest, APassDrivesOnlyTheHeadsWithSomethingNew) {
  // A host of thousands of heads must not show and poll every head at every pass.
  for (const auto& [id, writer] : commands_) Reach(id, {Aspect::kRed});
  for (int i = 0; i < 10; ++i) Tick();
  const auto driven = [&] { return host_->counters().heads_driven; };
  std::uint64_t before = driven();
  host_->Step(Reading());
  EXPECT_EQ(driven(), before) << "nothing new, no deadline: no head driven";
  Beat();
  Deliver();
  EXPECT_EQ(driven(), before) << "a heartbeat of the SCM followed changes no head";
  Command(1, Aspect::kGreen);
  Deliver();
  EXPECT_EQ(driven(), before + 1) << "only the commanded head";
  EXPECT_EQ(backends_[1]->aspect(), Aspect::kGreen);
  before = driven();
  backends_[2]->FailLamp(Lamp::kRed);  // not through the device: the backend says it changed
  host_->Step(Reading());
  EXPECT_EQ(driven(), before + 1) << "only the head whose backend changed";
  EXPECT_EQ(host_->device(SignalHeadId(2)).health(), Health::kFault);
  // The statuses still go out every period, although no head is driven for them.
  Collect();
  status_.clear();
  before = driven();
  now_ += config_.status_period_s;
  host_->Step(Reading());
  ASSERT_TRUE(Settle([&] { return status_.size() >= commands_.size(); }));
  EXPECT_EQ(driven(), before);
  EXPECT_EQ(status_["signal_2"].health, kFault);
  EXPECT_EQ(status_["signal_1"].displayed, ToWire(Aspect::kGreen));
  // A lost heartbeat is a deadline of every head: each is driven into its fail-safe flash.
  before = driven();
  now_ += config_.scm_heartbeat_timeout_s + 1ms;
  host_->Step(Reading());
  EXPECT_EQ(driven(), before + commands_.size());
  for (const auto& [id, writer] : commands_) {
    EXPECT_TRUE(host_->device(SignalHeadId(id)).in_fail_safe()) << id;
  }
}

TEST_F(DeviceHostTest, TheMonitorLatchesOnConflictingGreensAndOnlyTheScmsResetClearsIt) {
  const auto* monitor = host_->monitor(IntersectionId(1));
  ASSERT_NE(monitor, nullptr);
  Latch(1, 2, "driving_school_crossing");
  ASSERT_TRUE(TickUntil([&] { return FindEvent("mmu_conflict") != nullptr; }));
  const EventSeen latch = *FindEvent("mmu_conflict");
  EXPECT_EQ(latch.severity, kCritical);
  EXPECT_EQ(latch.device_id, "mmu_driving_school_crossing");
  EXPECT_EQ(latch.intersection_id, 1u);
  EXPECT_NE(latch.message.find("signal_1 showed green and signal_2 showed green together"),
            std::string::npos)
      << latch.message;
  for (std::uint32_t h = 1; h <= 4; ++h) {
    EXPECT_EQ(host_->device(SignalHeadId(h)).aspect(), Aspect::kFlashingRed) << h;
  }
  ASSERT_TRUE(TickUntil([&] { return status_["mmu_driving_school_crossing"].health == kFault; }));
  EXPECT_EQ(status_["mmu_driving_school_crossing"].mode, kFlash);

  // Commands are ignored while latched.
  Command(1, Aspect::kRed);
  for (int i = 0; i < 50; ++i) Tick();
  EXPECT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kFlashingRed);
  EXPECT_TRUE(monitor->latched());

  // The SCM's device command clears the latch and is acknowledged.
  Send(Reset("driving_school_crossing", 1));
  Tick();
  EXPECT_FALSE(monitor->latched());
  EXPECT_EQ(host_->counters().monitor_resets, 1u);
  ASSERT_TRUE(Settle([&] { return FindEvent("mmu_conflict", /*active=*/false) != nullptr; }));
  EXPECT_NE(FindEvent("mmu_conflict", false)->message.find("operator 'alice', request 41"),
            std::string::npos)
      << FindEvent("mmu_conflict", false)->message;
  EXPECT_TRUE(Settle([&] {
    return status_["mmu_driving_school_crossing"].health == kOk &&
           status_["mmu_driving_school_crossing"].last_command_id == 1;
  })) << "acknowledged at once, without waiting for the status period";
  // Heads wait for a new command (the latched red is old), then follow it.
  for (int i = 0; i < 20; ++i) Tick();
  EXPECT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kFlashingRed);
  Reach(1, {Aspect::kRed});
}

TEST_F(DeviceHostTest, TheMonitorSeesAGreenLampStuckOnUnderARed) {
  Reach(1, {Aspect::kRed, Aspect::kGreen});
  Reach(3, {Aspect::kRed});
  backends_[3]->StickLamp(Lamp::kGreen);  // the device thinks it shows red
  ASSERT_TRUE(TickUntil([&] { return FindEvent("mmu_conflict") != nullptr; }));
  EXPECT_NE(FindEvent("mmu_conflict")->message.find("signal_3 showed green"), std::string::npos);
}

TEST_F(DeviceHostTest, StoppingSaysStoppingAndOffline) {
  Reach(1, {Aspect::kRed});
  host_->Stop(Reading());
  ASSERT_TRUE(Settle([&] { return status_["signal_1"].health == kOffline; }));
  EXPECT_EQ(status_["signal_1"].detail, "device host infra/test stopped");
  EXPECT_EQ(backends_[1]->aspect(), Aspect::kFlashingRed);
  EXPECT_TRUE(Settle([&] {
    return !host_heartbeat_states_.empty() && host_heartbeat_states_.back() == 2;
  })) << "STOPPING";
}

TEST_F(SmallTownHostTest, ADeviceCommandResetsTheMonitorItNamesAndNoOther) {
  Latch(1, 2, "north_t");
  Latch(4, 5, "centre");
  const ConflictMonitor& north = *host_->monitor(intersections_.at("north_t"));
  const ConflictMonitor& centre = *host_->monitor(intersections_.at("centre"));
  ASSERT_TRUE(north.latched());
  ASSERT_TRUE(centre.latched());

  Send(Reset("north_t", 1));
  Tick();
  EXPECT_FALSE(north.latched());
  EXPECT_TRUE(centre.latched()) << "a reset reaches only the monitor it names";
  EXPECT_EQ(host_->last_command_id(intersections_.at("north_t")), 1u);
  EXPECT_EQ(host_->last_command_id(intersections_.at("centre")), 0u);
  ASSERT_TRUE(Settle([&] { return status_["mmu_north_t"].last_command_id == 1; }));
  EXPECT_EQ(status_["mmu_north_t"].health, kOk);
  EXPECT_EQ(status_["mmu_centre"].health, kFault);
  EXPECT_EQ(status_["mmu_centre"].last_command_id, 0u);

  // north_t's heads follow a new red; centre's stay forced to flash.
  Reach(1, {Aspect::kRed});
  Command(4, Aspect::kRed);
  for (int i = 0; i < 20; ++i) Tick();
  EXPECT_TRUE(host_->device(SignalHeadId(4)).forced());
  EXPECT_EQ(host_->device(SignalHeadId(4)).aspect(), Aspect::kFlashingRed);

  Send(Reset("centre", 2));
  Tick();
  EXPECT_FALSE(centre.latched());
  ASSERT_TRUE(Settle([&] { return status_["mmu_centre"].last_command_id == 2; }));
  EXPECT_EQ(status_["mmu_north_t"].last_command_id, 1u);
}

TEST_F(SmallTownHostTest, ARedTakenInTheSamePassAsTheResetEndsTheFlash) {
  Latch(1, 2, "north_t");
  // The SCM resets, then commands red at once. Both reach the host before its next pass (a
  // write is delivered to the readers of this process before it returns).
  Send(Reset("north_t", 1));
  Command(1, Aspect::kRed);
  const std::uint64_t commands = host_->counters().commands;
  host_->Step(Reading());
  ASSERT_EQ(host_->counters().commands, commands + 1) << "the red was not in this pass";
  ASSERT_EQ(host_->counters().device_commands_done, 1u) << "the reset was not in this pass";
  EXPECT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kRed)
      << host_->device(SignalHeadId(1)).detail();
  EXPECT_EQ(host_->device(SignalHeadId(2)).aspect(), Aspect::kFlashingRed)
      << "no new command for signal_2 yet";
  // The SCM sends signal_2's red again (it re-sends until the device shows it): it ends the
  // flash too.
  Command(2, Aspect::kRed);
  ASSERT_TRUE(TickUntil([&] { return state_[2] == 1 && status_["signal_2"].mode == kNormal; }));
  EXPECT_EQ(host_->device(SignalHeadId(2)).aspect(), Aspect::kRed);
}

TEST_F(SmallTownHostTest, DeviceCommandsForAnotherCitySessionOrIntersectionResetNothing) {
  Latch(1, 2, "north_t");
  const ConflictMonitor& north = *host_->monitor(intersections_.at("north_t"));

  auto other_city = Reset("north_t", 1);
  dds::SetString(other_city->city, "driving_school");
  Send(other_city);
  auto other_session = Reset("north_t", 2);
  other_session->scm_session = scm_session_ + 1;
  Send(other_session);
  auto intersection_zero = Reset("north_t", 3);
  intersection_zero->intersection_id = 0;
  Send(intersection_zero);
  auto other_intersection = Reset("north_t", 4);
  other_intersection->intersection_id = intersections_.at("centre").value();
  Send(other_intersection);
  auto unknown_command = Reset("north_t", 5);
  unknown_command->command = 7;
  Send(unknown_command);
  // The right session, from someone else than the SCM.
  dds::Participant rogue = Join(partition_);
  dds::Writer<msg::DeviceCommand> rogue_writer(rogue, dds::topics::DeviceCommands());
  ASSERT_TRUE(rogue_writer.WaitForReaders(1, kPatience));
  rogue_writer.Write(Reset("north_t", 6));
  ++sent_device_commands_;
  for (int i = 0; i < 10; ++i) Tick();

  EXPECT_TRUE(north.latched());
  EXPECT_EQ(host_->counters().device_commands_ignored, 6u);
  EXPECT_EQ(host_->counters().device_commands_done, 0u);
  EXPECT_EQ(host_->last_command_id(intersections_.at("north_t")), 0u);
  EXPECT_TRUE(host_->device(SignalHeadId(1)).forced());
  ASSERT_TRUE(Settle([&] { return FindEvent("device_command_ignored") != nullptr; }));
  const EventSeen& e = *FindEvent("device_command_ignored");
  EXPECT_EQ(e.severity, kWarning);
  EXPECT_EQ(e.message,
            "infra/test ignored device command 1 for 'mmu_north_t' (intersection 1, operator "
            "'alice', request 41): it is for city 'driving_school', this host serves "
            "'small_town' (1 ignored so far)");
  EXPECT_EQ(CountEvents("device_command_ignored"), 1u) << "rate-limited";
  EXPECT_EQ(status_["mmu_north_t"].last_command_id, 0u);

  // The real one still works.
  Send(Reset("north_t", 7));
  Tick();
  EXPECT_FALSE(north.latched());
  EXPECT_EQ(host_->last_command_id(intersections_.at("north_t")), 7u);
}

TEST_F(SmallTownHostTest, ADeviceCommandForAnotherHostsDeviceIsOnlyCounted) {
  auto elsewhere = Reset("north_t", 1);
  dds::SetString(elsewhere->device_id, "mmu_harbour");
  Send(elsewhere);
  Tick();
  EXPECT_EQ(host_->counters().device_commands_not_ours, 1u);
  EXPECT_EQ(host_->counters().device_commands_ignored, 0u);
  for (int i = 0; i < 10; ++i) Tick();
  EXPECT_EQ(FindEvent("device_command_ignored"), nullptr) << "another host's business";
}

TEST_F(SmallTownHostTest, ARepeatedDeviceCommandIsNotCarriedOutTwice) {
  Latch(1, 2, "north_t");
  Send(Reset("north_t", 1));
  Tick();
  const ConflictMonitor& north = *host_->monitor(intersections_.at("north_t"));
  ASSERT_FALSE(north.latched());
  // A new conflict latches it again; the old reset, sent again, must not clear the new latch.
  Reach(1, {Aspect::kRed, Aspect::kGreen});
  Reach(2, {Aspect::kRed});
  Command(2, Aspect::kGreen);
  ASSERT_TRUE(TickUntil([&] { return north.latched(); }));
  Send(Reset("north_t", 1));
  Tick();
  EXPECT_TRUE(north.latched());
  EXPECT_EQ(host_->counters().device_commands_repeated, 1u);
  EXPECT_EQ(host_->last_command_id(intersections_.at("north_t")), 1u);
  Send(Reset("north_t", 2));
  Tick();
  EXPECT_FALSE(north.latched());
}

TEST_F(DeviceHostTest, AnScmHeartbeatOfAnotherCityIsIgnoredAndReportedOncePerSession) {
  scm_alive_ = false;
  Command(1, Aspect::kRed);
  for (int i = 0; i < 10; ++i) {
    Beat("small_town", 77);
    Tick();
  }
  Beat("small_town", 78);
  for (int i = 0; i < 10; ++i) Tick();
  EXPECT_EQ(host_->counters().foreign_scm_heartbeats, 11u);
  EXPECT_EQ(host_->counters().scm_changes, 0u);
  EXPECT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kFlashingRed);
  EXPECT_EQ(status_["signal_1"].detail, "start-up; waiting for the SCM's heartbeat");
  ASSERT_TRUE(Settle([&] { return CountEvents("foreign_scm") >= 2; }));
  EXPECT_EQ(CountEvents("foreign_scm"), 2u) << "once per foreign session";
  const EventSeen& e = *FindEvent("foreign_scm");
  EXPECT_EQ(e.severity, kWarning);
  EXPECT_EQ(e.message,
            "infra/test ignores the heartbeat of the SCM of city 'small_town' (session 0x4d): it "
            "serves city 'driving_school'");
  // Our city's SCM is followed as usual.
  scm_alive_ = true;
  ASSERT_TRUE(TickUntil([&] { return host_->device(SignalHeadId(1)).aspect() == Aspect::kRed; }));
}

TEST_F(DeviceHostTest, ACommandFromAnotherParticipantCannotChangeTheLampsWhileTheScmsCan) {
  Reach(1, {Aspect::kRed});
  // A lab member's tool: a plain writer of signal_1/command, latched like the SCM's.
  dds::Participant rogue = Join(partition_);
  dds::Writer<msg::Int32> rogue_writer(rogue, dds::topics::SignalCommand(SignalHeadId(1)));
  ASSERT_TRUE(rogue_writer.WaitForReaders(1, kPatience));
  dds::Message<msg::Int32> green;
  green->data = ToWire(Aspect::kGreen);
  for (int i = 0; i < 3; ++i) {
    rogue_writer.Write(green);
    ++sent_commands_;
    Tick();
  }
  for (int i = 0; i < 20; ++i) Tick();
  EXPECT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kRed);
  EXPECT_EQ(state_[1], 1) << "the lamps still show red";
  EXPECT_EQ(host_->counters().foreign_commands, 3u);
  ASSERT_TRUE(Settle([&] { return FindEvent("foreign_command") != nullptr; }));
  EXPECT_EQ(CountEvents("foreign_command"), 1u) << "rate-limited";
  const EventSeen& e = *FindEvent("foreign_command");
  EXPECT_EQ(e.severity, kWarning);
  EXPECT_EQ(e.device_id, "signal_1");
  EXPECT_EQ(e.message, "signal_1 ignored command green from participant " +
                           dds::KeyOf(rogue).ToString() + ": only the SCM's participant (" +
                           dds::KeyOf(scm_side_).ToString() + ") commands it (1 ignored so far)");
  // The SCM's own writer can.
  Reach(1, {Aspect::kGreen});
}

TEST_F(DeviceHostTest, ALatchedScmCommandWrittenBeforeTheHeartbeatIsAppliedOnceItComes) {
  scm_alive_ = false;
  Command(1, Aspect::kRed);  // the SCM's, latched, before any heartbeat
  // Someone else's latched command, also before the heartbeat.
  dds::Participant rogue = Join(partition_);
  dds::Writer<msg::Int32> rogue_writer(rogue, dds::topics::SignalCommand(SignalHeadId(2)));
  dds::Message<msg::Int32> flashing_yellow;
  flashing_yellow->data = ToWire(Aspect::kFlashingYellow);
  rogue_writer.Write(flashing_yellow);
  ++sent_commands_;
  for (int i = 0; i < 10; ++i) Tick();
  EXPECT_EQ(host_->counters().held_commands, 2u);
  EXPECT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kFlashingRed);

  scm_alive_ = true;
  ASSERT_TRUE(TickUntil([&] { return host_->device(SignalHeadId(1)).aspect() == Aspect::kRed; }));
  EXPECT_EQ(host_->device(SignalHeadId(1)).mode(), Mode::kNormal);
  EXPECT_EQ(host_->device(SignalHeadId(2)).aspect(), Aspect::kFlashingRed)
      << "the other participant's command was not applied";
  EXPECT_EQ(host_->counters().foreign_commands, 1u) << "reported once the SCM was known";
  ASSERT_TRUE(Settle([&] { return FindEvent("foreign_command", true, "signal_2") != nullptr; }));
}

TEST_F(DeviceHostTest, AnScmHeartbeatFromAnotherParticipantIsAnScmRestart) {
  Reach(1, {Aspect::kRed, Aspect::kGreen});
  // Same session id, another participant: not the SCM the host follows.
  dds::Participant other = Join(partition_);
  dds::Writer<msg::Heartbeat> other_heartbeat(other, dds::topics::Heartbeat());
  dds::Message<msg::Heartbeat> m;
  dds::SetString(m->sender, "scm");
  dds::SetString(m->city, config_.city);
  m->session_id = scm_session_;
  m->state = 1;
  ASSERT_TRUE(other_heartbeat.WaitForReaders(1, kPatience));  // the host's
  other_heartbeat.Write(m);
  ++sent_heartbeats_;
  Tick();
  EXPECT_EQ(host_->counters().scm_changes, 2u);
  EXPECT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kFlashingRed);
  EXPECT_EQ(host_->device(SignalHeadId(1)).detail(),
            "SCM restarted; waiting for a new red, off or flashing command");
}

TEST_F(DeviceHostTest, ASimulatedClockRestartPutsTheHeadsBackInStartUpFlashInsteadOfFreezing) {
  Reach(1, {Aspect::kRed, Aspect::kGreen});
  Reach(2, {Aspect::kRed});
  // The simulator restarts: /clock goes back from 1000 s to 5 s, a new session.
  scm_alive_ = false;
  clock_session_ = 1;
  now_ = MonoFromSeconds(5);
  Tick();
  for (std::uint32_t h = 1; h <= 4; ++h) {
    EXPECT_EQ(host_->device(SignalHeadId(h)).aspect(), Aspect::kFlashingRed) << h;
  }
  EXPECT_EQ(host_->device(SignalHeadId(1)).detail(),
            "simulated clock restarted (session 1); waiting for the SCM's heartbeat");
  EXPECT_EQ(host_->counters().clock_restarts, 1u);
  ASSERT_TRUE(Settle([&] { return FindEvent("local_flash", true, "signal_1") != nullptr; }));
  EXPECT_EQ(FindEvent("local_flash", true, "signal_1")->message,
            "signal_1 flashes red on its own: simulated clock restarted (session 1)");

  // Statuses and the host's heartbeat go on in the new timeline (nothing waits for 1000 s).
  const std::size_t beats = host_heartbeat_stamps_.size();
  for (int i = 0; i < 50; ++i) Tick();
  ASSERT_TRUE(Settle([&] { return host_heartbeat_stamps_.size() >= beats + 5; }));
  EXPECT_LT(host_heartbeat_stamps_.back(), TimeFromSeconds(10));
  EXPECT_LT(status_["signal_2"].stamp, TimeFromSeconds(10));
  EXPECT_GE(status_["signal_2"].stamp, TimeFromSeconds(5));
  EXPECT_EQ(status_["signal_2"].mode, kFlash);

  // The SCM beats again: the red signal_2 had counts as a latched command (start-up rules); the
  // green of signal_1 does not end a flash.
  scm_alive_ = true;
  ASSERT_TRUE(TickUntil([&] { return host_->device(SignalHeadId(2)).aspect() == Aspect::kRed; }));
  EXPECT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kFlashingRed);
  Reach(1, {Aspect::kRed});
  // The heartbeat time-out runs on the new timeline: silence flashes the heads within it.
  scm_alive_ = false;
  const MonoTime silent = now_;
  ASSERT_TRUE(TickUntil([&] { return host_->device(SignalHeadId(1)).in_fail_safe(); }));
  EXPECT_LE(now_ - silent, 1200ms);
}

TEST_F(DeviceHostTest, AWallClockStepOfFiveSecondsDoesNotMakeAHeadFlash) {
  // A wall clock whose steady source is the test's host time, and whose wall source the test
  // steps.
  Duration wall_offset{0};
  wall_ = std::make_unique<WallClock>(WallTimeSources{
      [&] { return Time(now_.time_since_epoch()) + wall_offset; }, [&] { return now_; }});
  Reach(1, {Aspect::kRed, Aspect::kGreen});
  for (const Duration step : {Duration(5s), Duration(-5s), Duration(-5s), Duration(5s)}) {
    wall_offset += step;
    for (int i = 0; i < 100; ++i) {  // 2 s of heartbeats every 100 ms
      Tick();
      ASSERT_EQ(host_->device(SignalHeadId(1)).aspect(), Aspect::kGreen)
          << "after a step of " << ToSeconds(step) << " s";
      ASSERT_FALSE(host_->device(SignalHeadId(1)).in_fail_safe());
    }
  }
  EXPECT_EQ(wall_->steps(), 4u);
  // Wire times moved with the wall clock.
  ASSERT_TRUE(Settle([&] {
    return !host_heartbeat_stamps_.empty() &&
           host_heartbeat_stamps_.back() - Time(now_.time_since_epoch()) < 1s;
  }));
}

TEST_F(DeviceHostTest, RunFollowsTheScmOnASimulatedClockAndStopsWhenInterrupted) {
  // The loop on its own thread; the test only talks to it over DDS.
  SimClock sim;
  WallClock pace;
  sim.AdvanceTo(TimeFromSeconds(1000));
  std::thread loop([&] { host_->Run(sim, pace); });
  std::atomic<bool> beating{true};
  std::thread scm([&] {
    for (std::uint64_t n = 1; beating; ++n) {
      dds::Message<msg::Heartbeat> m;
      dds::SetString(m->sender, "scm");
      dds::SetString(m->city, config_.city);
      m->session_id = scm_session_;
      m->sequence_number = n;
      m->state = 1;
      heartbeat_.Write(m);
      std::this_thread::sleep_for(20ms);  // the SCM's pace, not a wait for a result
    }
  });
  const auto wait_for = [&](const std::function<bool()>& done) {
    const auto deadline = SteadyClock::now() + kPatience;
    for (;;) {
      Collect();
      if (done()) return true;
      if (SteadyClock::now() > deadline) return false;
      (void)statuses_.WaitForData(50ms);
    }
  };
  dds::Message<msg::Int32> red;
  red->data = ToWire(Aspect::kRed);
  commands_.at(1)->Write(red);
  // No simulated time passes, yet the command is shown: the loop wakes for data.
  EXPECT_TRUE(wait_for([&] { return status_["signal_1"].displayed == ToWire(Aspect::kRed); }));
  // The simulator restarts: the heads go back to start-up flash (an event says why; the
  // status may never show it when a heartbeat comes in the same pass), then follow the SCM
  // again.
  sim.AdvanceTo(TimeFromSeconds(3));
  EXPECT_TRUE(wait_for([&] {
    const EventSeen* e = FindEvent("local_flash", true, "signal_1");
    return e != nullptr && e->message.find("simulated clock restarted") != std::string::npos;
  }));
  EXPECT_TRUE(wait_for([&] {
    return status_["signal_1"].displayed == ToWire(Aspect::kRed) &&
           status_["signal_1"].mode == kNormal && status_["signal_1"].stamp < TimeFromSeconds(10);
  })) << "red again, in the new timeline";
  beating = false;
  scm.join();
  pace.Interrupt();
  loop.join();
  EXPECT_TRUE(wait_for([&] { return status_["signal_1"].health == kOffline; })) << "Stop ran";
}

}  // namespace
}  // namespace autodrive::infrastructure
