#include "scm/io/publishers.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <array>
#include <atomic>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "autodrive_msgs/msg/DeviceCommand.h"
#include "autodrive_msgs/msg/Event.h"
#include "autodrive_msgs/msg/Heartbeat.h"
#include "autodrive_msgs/msg/IntersectionState.h"
#include "autodrive_msgs/msg/SignalGroupState.h"
#include "autodrive_msgs/msg/SignalRequestStatus.h"
#include "autodrive_msgs/msg/TrackedVehicle.h"

#include "common/dds/conversions.h"
#include "common/dds/topics.h"
#include "common/error.h"

namespace autodrive::scm {

namespace {

std::uint8_t ToWire(RequestStatus status) {
  switch (status) {
    case RequestStatus::kGranted:
      return autodrive_msgs_msg_SignalRequestStatus_Constants_GRANTED;
    case RequestStatus::kRejected:
      return autodrive_msgs_msg_SignalRequestStatus_Constants_REJECTED;
    case RequestStatus::kCompleted:
      return autodrive_msgs_msg_SignalRequestStatus_Constants_COMPLETED;
    case RequestStatus::kCancelled:
      return autodrive_msgs_msg_SignalRequestStatus_Constants_CANCELLED;
  }
  AUTODRIVE_CHECK(false, "unknown request status " << static_cast<int>(status));
}

std::uint8_t ToWire(ScmState state) {
  switch (state) {
    case ScmState::kStarting:
      return autodrive_msgs_msg_Heartbeat_Constants_STARTING;
    case ScmState::kRunning:
      return autodrive_msgs_msg_Heartbeat_Constants_RUNNING;
    case ScmState::kStopping:
      return autodrive_msgs_msg_Heartbeat_Constants_STOPPING;
  }
  AUTODRIVE_CHECK(false, "unknown SCM state " << static_cast<int>(state));
}

/// J2735 MovementPhaseState of an aspect.
std::uint8_t EventState(Aspect a) {
  switch (a) {
    case Aspect::kOff:
      return autodrive_msgs_msg_SignalGroupState_Constants_DARK;
    case Aspect::kRed:
      return autodrive_msgs_msg_SignalGroupState_Constants_STOP_AND_REMAIN;
    case Aspect::kYellow:
      return autodrive_msgs_msg_SignalGroupState_Constants_PROTECTED_CLEARANCE;
    case Aspect::kGreen:
      return autodrive_msgs_msg_SignalGroupState_Constants_PROTECTED_MOVEMENT_ALLOWED;
    case Aspect::kFlashingRed:
      return autodrive_msgs_msg_SignalGroupState_Constants_STOP_THEN_PROCEED;
    case Aspect::kFlashingYellow:
      return autodrive_msgs_msg_SignalGroupState_Constants_CAUTION_CONFLICTING_TRAFFIC;
  }
  return autodrive_msgs_msg_SignalGroupState_Constants_UNAVAILABLE;
}

/// J2735 IntersectionStatusObject bits of a controller.
std::uint16_t StatusBits(const IntersectionController& c) {
  std::uint16_t status = 0;
  const Mode mode = c.effective_mode();
  if (c.latched()) {
    status |= autodrive_msgs_msg_IntersectionState_Constants_FAILURE_FLASH |
              autodrive_msgs_msg_IntersectionState_Constants_FAILURE_MODE;
  }
  if (mode == Mode::kManual)
    status |= autodrive_msgs_msg_IntersectionState_Constants_MANUAL_CONTROL_ENABLED;
  if (mode == Mode::kFixed)
    status |= autodrive_msgs_msg_IntersectionState_Constants_FIXED_TIME_OPERATION;
  if (mode == Mode::kActuated)
    status |= autodrive_msgs_msg_IntersectionState_Constants_TRAFFIC_DEPENDENT_OPERATION;
  if (c.stage() == Stage::kStartupFlash)
    status |= autodrive_msgs_msg_IntersectionState_Constants_STANDBY_OPERATION;
  if (mode == Mode::kDark) status |= autodrive_msgs_msg_IntersectionState_Constants_OFF;
  if (c.preemption_active())
    status |= autodrive_msgs_msg_IntersectionState_Constants_PREEMPT_ACTIVE;
  if (c.priority_active())
    status |= autodrive_msgs_msg_IntersectionState_Constants_SIGNAL_PRIORITY_ACTIVE;
  return status;
}

dds::Qos NonBlocking(const dds::Qos& qos) { return qos.NonBlocking(); }

void LogWriteFailure(std::string_view topic, std::uint64_t failures, const DdsError& e) {
  if (failures <= 5 || failures % 100 == 0)
    spdlog::error("writing {} failed ({} failures so far): {}", topic, failures, e.what());
}

}  // namespace

/// A big message's writer and its own thread (SPaT, the device table). Two messages: the loop
/// fills one while the other may be in the sender's hands; a hand-over waits only if the sender
/// has not yet taken the previous message, which would mean it is a whole period behind (its
/// writes never block: `Qos::NonBlocking`). Nothing here allocates once both messages have
/// their shape.
template <typename T>
class LoopSender {
 public:
  LoopSender(const dds::Participant& p, const dds::TopicSpec<T>& spec)
      : writer_(p, spec.name, NonBlocking(spec.qos)), thread_([this] { Run(); }) {}
  LoopSender(const LoopSender&) = delete;
  LoopSender& operator=(const LoopSender&) = delete;
  ~LoopSender() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    changed_.notify_all();
    thread_.join();
  }

  /// The message to fill next (the sender has neither it nor anything not yet taken).
  T& Next() {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return !queued_ && sending_ != fill_; });
    return buffers_[fill_].get();
  }
  /// Hands the message from `Next` to the sender.
  void Send() {
    {
      std::lock_guard lock(mutex_);
      queued_ = fill_;
      fill_ ^= 1U;
    }
    changed_.notify_all();
  }
  /// Waits until the sender has written everything handed over.
  void WaitIdle() {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return !queued_ && !sending_; });
  }
  /// Both messages, for reshaping (after `WaitIdle`, from the thread that hands over).
  std::array<dds::Message<T>, 2>& buffers() { return buffers_; }
  [[nodiscard]] std::uint64_t failures() const { return failures_.load(); }

 private:
  void Run() {
    std::unique_lock lock(mutex_);
    for (;;) {
      changed_.wait(lock, [&] { return stop_ || queued_.has_value(); });
      if (!queued_) return;  // stopping, and everything handed over is written
      sending_ = queued_;
      queued_.reset();
      lock.unlock();
      changed_.notify_all();  // a hand-over may be waiting for the queue to empty
      try {
        writer_.Write(buffers_[*sending_].get());
      } catch (const DdsError& e) {
        LogWriteFailure(writer_.topic_name(), ++failures_, e);
      }
      lock.lock();
      sending_.reset();
      changed_.notify_all();
    }
  }

  dds::Writer<T> writer_;
  std::array<dds::Message<T>, 2> buffers_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::size_t fill_ = 0;                // the loop's message (guarded by mutex_)
  std::optional<std::size_t> queued_;   // handed over, not yet taken
  std::optional<std::size_t> sending_;  // being written by the sender
  bool stop_ = false;
  std::atomic<std::uint64_t> failures_{0};
  std::thread thread_;  // last: starts once everything above exists
};

MapMessages BuildMapMessages(const City& city, std::uint32_t revision) {
  SignalGroupAssignment groups;
  for (const auto& model : city.intersections) {
    auto& list = groups[model.id];
    for (const auto& g : model.groups) list.push_back({g.id, g.name, g.movements, g.heads});
  }
  // A district's SCM describes its own intersections only.
  const maps::District* district = city.districts.Find(city.district);
  const std::span<const IntersectionId> only =
      district == nullptr ? std::span<const IntersectionId>{} : district->intersections;
  MapMessages out{BuildMapData(city.map, city.config.name, groups, revision, only),
                  BuildSignRegistry(city.map, city.config.name, revision),
                  {}};
  // V2I requests name lanes by their MAP ids: remember which map lane each one is.
  std::map<std::string, LaneId> by_name;
  for (const auto& lane : city.map.lanes) by_name.emplace(lane.name, lane.id);
  for (const auto& x : dds::Elements(out.map->intersections)) {
    for (const auto& lane : dds::Elements(x.lanes)) {
      const auto it = by_name.find(lane.map_lane_id ? lane.map_lane_id : "");
      if (it != by_name.end())
        out.lanes.insert_or_assign({x.intersection_id, lane.lane_id}, it->second);
    }
  }
  return out;
}

ScmPublishers::ScmPublishers(const dds::Participant& p, std::string city, std::uint64_t session)
    : city_(std::move(city)),
      session_(session),
      map_writer_(p, dds::topics::Map().name, NonBlocking(dds::topics::Map().qos)),
      signs_writer_(p, dds::topics::Signs().name, NonBlocking(dds::topics::Signs().qos)),
      fleet_writer_(p, dds::topics::Fleet().name, NonBlocking(dds::topics::Fleet().qos)),
      event_writer_(p, dds::topics::Events().name, NonBlocking(dds::topics::Events().qos)),
      heartbeat_writer_(p, dds::topics::Heartbeat().name,
                        NonBlocking(dds::topics::Heartbeat().qos)),
      request_status_writer_(p, dds::topics::SignalRequestStatus().name,
                             NonBlocking(dds::topics::SignalRequestStatus().qos)),
      device_command_writer_(p, dds::topics::DeviceCommands().name,
                             NonBlocking(dds::topics::DeviceCommands().qos)),
      spat_(std::make_unique<LoopSender<msg::Spat>>(p, dds::topics::Spat())),
      device_table_(std::make_unique<LoopSender<msg::DeviceTable>>(p, dds::topics::DeviceTable())) {
  dds::SetString(heartbeat_->sender, "scm");
  dds::SetString(heartbeat_->city, city_);
  heartbeat_->session_id = session_;
}

template <typename T>
bool ScmPublishers::TryWrite(dds::Writer<T>& writer, const T& sample) {
  try {
    writer.Write(sample);
    return true;
  } catch (const DdsError& e) {
    LogWriteFailure(writer.topic_name(), ++counters_.write_failures, e);
    return false;
  }
}

ScmPublishers::~ScmPublishers() = default;

void ScmPublishers::WaitIdle() {
  spat_->WaitIdle();
  device_table_->WaitIdle();
}

PublisherCounters ScmPublishers::counters() const {
  PublisherCounters c = counters_;
  c.write_failures += spat_->failures() + device_table_->failures();
  return c;
}

void ScmPublishers::Reset(const CityRuntime& runtime, std::string city) {
  city_ = std::move(city);
  dds::UpdateString(heartbeat_->city, city_);
  spat_->WaitIdle();
  const auto& xs = runtime.intersections();
  std::size_t max_groups = 0;
  for (auto& spat : spat_->buffers()) {
    spat.Clear();
    dds::SetString(spat->header.frame_id, "map");
    dds::SetString(spat->city, city_);
    dds::SetLengthKeepingCapacity(spat->intersections, static_cast<std::uint32_t>(xs.size()));
    for (std::size_t i = 0; i < xs.size(); ++i) {
      auto& s = dds::Elements(spat->intersections)[i];
      s.intersection_id = xs[i].model->id.value();
      dds::SetString(s.name, xs[i].model->name);
      const auto n = static_cast<std::uint32_t>(xs[i].model->groups.size());
      dds::SetLengthKeepingCapacity(s.signal_groups, n);
      for (std::uint32_t g = 0; g < n; ++g) {
        dds::Elements(s.signal_groups)[g].signal_group = xs[i].model->groups[g].id.value();
      }
      max_groups = std::max<std::size_t>(max_groups, n);
    }
  }
  signals_.reserve(max_groups);
}

void ScmPublishers::PublishDeviceTable(const DeviceTable& table, Time now) {
  msg::DeviceTable& m = device_table_->Next();
  m.header.stamp = dds::ToMsg(now);
  dds::UpdateString(m.header.frame_id, "map");
  dds::UpdateString(m.city, city_);
  m.session_id = session_;
  m.revision = table.revision();
  const auto& rows = table.rows();
  dds::SetLengthKeepingCapacity(m.devices, static_cast<std::uint32_t>(rows.size()));
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const DeviceRow& row = rows[i];
    auto& e = dds::Elements(m.devices)[i];
    dds::UpdateString(e.device_id, row.device_id);
    dds::UpdateString(e.host, row.host);
    e.kind = row.kind;
    e.backend = row.backend;
    e.health = row.health;
    e.mode = row.mode;
    e.displayed_state = row.displayed_state;
    dds::UpdateString(e.detail, row.detail);
    e.last_report = row.reported ? dds::ToMsg(row.last_report) : msg::Time{};
    e.reported = row.reported;
    e.lost = row.lost;
  }
  device_table_->Send();
  ++counters_.device_tables;
}

void ScmPublishers::StartSpat(const ClockReading& now) {
  spat_fill_ = &spat_->Next();
  spat_now_ = now;
  spat_filled_ = 0;
  spat_fill_->header.stamp = dds::ToMsg(now.wire);
}

bool ScmPublishers::FillSpat(const CityRuntime& runtime, std::size_t count) {
  AUTODRIVE_CHECK(spat_fill_ != nullptr, "FillSpat before StartSpat");
  const ClockReading& now = spat_now_;
  const auto& xs = runtime.intersections();
  auto states = dds::Elements(spat_fill_->intersections);
  AUTODRIVE_CHECK(states.size() == xs.size(), "SPaT not reset for this city");
  const std::size_t end = std::min(xs.size(), spat_filled_ + count);
  for (std::size_t i = spat_filled_; i < end; ++i) {
    const auto& x = xs[i];
    const IntersectionController& c = *x.controller;
    auto& s = states[i];
    s.revision = x.revision;
    s.status = StatusBits(c);
    s.timestamp = spat_fill_->header.stamp;
    dds::UpdateString(s.plan, c.plan().name);
    c.SignalsInto(now.mono, signals_);
    auto groups = dds::Elements(s.signal_groups);
    for (std::size_t g = 0; g < signals_.size(); ++g) {
      const GroupSignal& sig = signals_[g];
      auto& o = groups[g];
      o.event_state = EventState(sig.aspect);
      o.min_end_time = dds::ToMsg(now.ToWire(sig.min_end));
      o.has_max_end_time = sig.max_end.has_value();
      o.max_end_time = sig.max_end ? dds::ToMsg(now.ToWire(*sig.max_end)) : msg::Time{};
      o.has_likely_time = sig.likely_end.has_value();
      o.likely_time = sig.likely_end ? dds::ToMsg(now.ToWire(*sig.likely_end)) : msg::Time{};
      o.likely_time_confidence = sig.likely_confidence;
      o.has_next_time = sig.next_green.has_value();
      o.next_time = sig.next_green ? dds::ToMsg(now.ToWire(*sig.next_green)) : msg::Time{};
    }
  }
  spat_filled_ = end;
  return end == xs.size();
}

void ScmPublishers::SendSpat() {
  AUTODRIVE_CHECK(spat_fill_ != nullptr, "SendSpat before StartSpat");
  spat_->Send();
  spat_fill_ = nullptr;
  ++counters_.spat;
}

void ScmPublishers::PublishFleet(const FleetRegistry& fleet, Time now) {
  fleet.StateInto(now, fleet_);
  TryWrite(fleet_writer_, fleet_.get());
}

void ScmPublishers::PublishHeartbeat(Time now, ScmState state) {
  heartbeat_->header.stamp = dds::ToMsg(now);
  heartbeat_->sequence_number = ++heartbeat_seq_;
  heartbeat_->period_ms = 100;
  heartbeat_->state = ToWire(state);
  TryWrite(heartbeat_writer_, heartbeat_.get());
}

void ScmPublishers::PublishEvent(const Event& e, Time now, std::uint64_t event_id) {
  dds::Message<msg::Event> m;
  m->header.stamp = dds::ToMsg(now);
  m->event_id = event_id;
  m->severity = ToWire(e.severity);
  dds::SetString(m->source, "scm");
  dds::SetString(m->code, e.code);
  dds::SetString(m->message, e.message);
  m->intersection_id = e.intersection.value();
  dds::SetString(m->device_id, e.device);
  m->active = e.active;
  TryWrite(event_writer_, m.get());
}

void ScmPublishers::PublishMap(MapMessages& map, Time now) {
  map.map->header.stamp = dds::ToMsg(now);
  map.signs->header.stamp = dds::ToMsg(now);
  TryWrite(map_writer_, map.map.get());
  TryWrite(signs_writer_, map.signs.get());
}

void ScmPublishers::PublishRequestStatus(const RequestUpdate& u, std::uint32_t intersection_id,
                                         std::uint32_t signal_group, const ClockReading& now) {
  dds::Message<msg::SignalRequestStatus> s;
  s->header.stamp = dds::ToMsg(now.wire);
  dds::SetString(s->vehicle_id, u.vehicle);
  s->request_id = u.request_id;
  s->intersection_id = intersection_id;
  s->status = ToWire(u.status);
  s->signal_group = signal_group;
  s->has_expected_green = u.expected_green.has_value();
  if (u.expected_green) s->expected_green = dds::ToMsg(now.ToWire(*u.expected_green));
  dds::SetString(s->reason, u.reason);
  TryWrite(request_status_writer_, s.get());
}

std::optional<std::uint64_t> ScmPublishers::ResetMonitor(const IntersectionModel& x,
                                                         std::string_view issued_by,
                                                         std::uint64_t request_id, Time now) {
  dds::Message<msg::DeviceCommand> m;
  m->header.stamp = dds::ToMsg(now);
  dds::SetString(m->city, city_);
  m->scm_session = session_;
  m->command_id = ++device_command_id_;
  dds::SetString(m->device_id, "mmu_" + x.name);
  m->intersection_id = x.id.value();
  m->command = autodrive_msgs_msg_DeviceCommand_Constants_RESET_MONITOR;
  dds::SetString(m->issued_by, issued_by);
  m->request_id = request_id;
  if (!TryWrite(device_command_writer_, m.get())) return std::nullopt;
  return m->command_id;
}

// --- Lights -----------------------------------------------------------------------------------

SignalCommandWriters::SignalCommandWriters(const dds::Participant& participant)
    : participant_(participant) {}

std::shared_ptr<SignalCommandWriters::Writer> SignalCommandWriters::Acquire(SignalHeadId id) {
  std::lock_guard lock(mutex_);
  std::weak_ptr<Writer>& slot = writers_[id];
  if (auto held = slot.lock()) return held;
  const auto spec = dds::topics::SignalCommand(id);
  auto writer = std::make_shared<Writer>(participant_, spec.name, spec.qos.NonBlocking());
  slot = writer;
  ++created_;
  return writer;
}

std::size_t SignalCommandWriters::created() const {
  std::lock_guard lock(mutex_);
  return created_;
}

LightCommander::LightCommander(SignalCommandWriters& writers, const CityRuntime& runtime)
    : sent_(runtime.heads().size()) {
  writers_.reserve(runtime.heads().size());
  for (const HeadSlot& h : runtime.heads()) writers_.push_back(writers.Acquire(h.id));
}

void LightCommander::Forget() {
  for (auto& s : sent_) s = SentCommand{};
}

std::size_t LightCommander::Sync(const CityRuntime& runtime, const DeviceSupervisor& supervisor,
                                 MonoTime now) {
  std::size_t written = 0;
  for (std::size_t h = 0; h < writers_.size(); ++h) {
    const Aspect want = runtime.AspectOfHead(h);
    SentCommand& s = sent_[h];
    const bool changed = s.aspect != want;
    const HeadHealth& health = supervisor.head(h);
    // Not shown yet, or shown only by the light's own fail-safe flash (a flashing red sent
    // before the light had this SCM's heartbeat does not count for it): sent again.
    const bool unshown = health.displayed != s.aspect;
    const bool unechoed = !changed && health.seen && (unshown || !health.following) &&
                          now - s.at >= (unshown ? kResendPeriod : kFollowResendPeriod);
    if (!changed && !unechoed) continue;
    try {
      writers_[h]->Write(msg::Int32{ToWire(want)});
    } catch (const DdsError& e) {
      ++counters_.failures;
      if (counters_.failures <= 5 || counters_.failures % 100 == 0) {
        spdlog::error("commanding {} failed ({} failures so far): {}", runtime.heads()[h].name,
                      counters_.failures, e.what());
      }
      continue;  // not recorded as sent: retried at the next pass
    }
    ++counters_.writes;
    if (unechoed) ++counters_.resends;
    s.aspect = want;
    s.at = now;
    ++written;
  }
  return written;
}

}  // namespace autodrive::scm
