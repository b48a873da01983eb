#include "infrastructure/device_host.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <map>
#include <random>

#include "common/dds/conversions.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "infrastructure/serial_backend.h"
#include "infrastructure/simulated_backend.h"

namespace autodrive::infrastructure {
namespace {

// Our enums carry the wire values of the IDL constants.
static_assert(static_cast<int>(Health::kOk) == autodrive_msgs_msg_DeviceStatus_Constants_OK);
static_assert(static_cast<int>(Health::kDegraded) ==
              autodrive_msgs_msg_DeviceStatus_Constants_DEGRADED);
static_assert(static_cast<int>(Health::kFault) == autodrive_msgs_msg_DeviceStatus_Constants_FAULT);
static_assert(static_cast<int>(Health::kOffline) ==
              autodrive_msgs_msg_DeviceStatus_Constants_OFFLINE);
static_assert(static_cast<int>(Mode::kNormal) == autodrive_msgs_msg_DeviceStatus_Constants_NORMAL);
static_assert(static_cast<int>(Mode::kFlash) == autodrive_msgs_msg_DeviceStatus_Constants_FLASH);
static_assert(static_cast<int>(Mode::kDark) == autodrive_msgs_msg_DeviceStatus_Constants_DARK);
static_assert(static_cast<int>(Severity::kWarning) == autodrive_msgs_msg_Event_Constants_WARNING);
static_assert(static_cast<int>(Severity::kAlarm) == autodrive_msgs_msg_Event_Constants_ALARM);
static_assert(static_cast<int>(Severity::kCritical) == autodrive_msgs_msg_Event_Constants_CRITICAL);
static_assert(static_cast<int>(ScmState::kRunning) ==
              autodrive_msgs_msg_Heartbeat_Constants_RUNNING);
static_assert(static_cast<int>(ScmState::kStopping) ==
              autodrive_msgs_msg_Heartbeat_Constants_STOPPING);

constexpr std::string_view kScmSender = "scm";
constexpr std::string_view kResetCommand = "reset";

// What a DeviceStatus says, apart from time and heartbeat sequence: publish when it changes.
struct StatusKey {
  Health health = Health::kOk;
  Mode mode = Mode::kNormal;
  std::int32_t displayed = 0;
  std::string detail;
  bool operator==(const StatusKey&) const = default;
};

std::uint8_t BackendWire(BackendKind kind) {
  return kind == BackendKind::kPhysical ? autodrive_msgs_msg_DeviceStatus_Constants_PHYSICAL
                                        : autodrive_msgs_msg_DeviceStatus_Constants_SIMULATED;
}

void LogEvent(Severity severity, const std::string& code, const std::string& message, bool active) {
  const auto level = severity >= Severity::kAlarm     ? spdlog::level::err
                     : severity == Severity::kWarning ? spdlog::level::warn
                                                      : spdlog::level::info;
  spdlog::log(level, "event {}{}: {}", code, active ? "" : " (cleared)", message);
}

}  // namespace

struct DeviceHost::Head {
  HeadPlan plan;
  TrafficLightDevice device;
  std::unique_ptr<LampBackend> backend;
  std::unique_ptr<dds::Reader<msg::Int32>> commands;
  std::unique_ptr<dds::Writer<msg::Int32>> state;
  std::unique_ptr<dds::Writer<msg::DeviceStatus>> status;
  std::optional<Lamps> lamps;  // as the backend reports them; nothing while offline
  std::optional<std::int32_t> published_state;
  std::optional<StatusKey> published_status;
  MonoTime next_status{};
};

struct DeviceHost::Monitor {
  ConflictMonitor monitor;
  std::vector<Head*> heads;
  BackendKind backend = BackendKind::kSimulated;
  std::unique_ptr<dds::Writer<msg::DeviceStatus>> status;
  std::optional<StatusKey> published_status;
  MonoTime next_status{};
};

struct DeviceHost::Dds {
  const dds::Participant& participant;
  dds::Reader<msg::Heartbeat> heartbeats;
  dds::Writer<msg::Heartbeat> heartbeat;
  dds::Writer<msg::Event> events;
  std::unique_ptr<dds::Reader<msg::OperatorRequest>> operator_requests;
  std::uint64_t write_failures_logged = 0;

  explicit Dds(const dds::Participant& p)
      : participant(p),
        heartbeats(p, dds::topics::Heartbeat()),
        heartbeat(p, dds::topics::Heartbeat()),
        events(p, dds::topics::Events()) {}
};

namespace {

// Writes, and on failure logs (the first few and then every 100th) and counts; never throws.
template <typename T>
bool TryWrite(dds::Writer<T>& writer, const dds::Message<T>& message, HostCounters& counters) {
  try {
    writer.Write(message);
    return true;
  } catch (const DdsError& e) {
    ++counters.publish_failures;
    if (counters.publish_failures <= 5 || counters.publish_failures % 100 == 0) {
      spdlog::error("writing {} failed ({} failures so far): {}", writer.topic_name(),
                    counters.publish_failures, e.what());
    }
    return false;
  }
}

}  // namespace

std::unique_ptr<LampBackend> MakeBackend(const HeadPlan& head, const InfraConfig& config) {
  if (head.backend == BackendType::kSerial) {
    AUTODRIVE_CHECK(head.serial.has_value(), "head " << head.id.value());
    SerialBackendOptions options;
    options.port = head.serial->port;
    options.baud = head.serial->baud;
    options.flash_period = config.flash_period_s;
    return std::make_unique<SerialBackend>(options);
  }
  return std::make_unique<SimulatedBackend>();
}

DeviceHost::DeviceHost(const InfraConfig& config, HostPlan plan,
                       const dds::Participant& participant, const ClockReading& now,
                       BackendFactory make_backend)
    : config_(config), plan_(std::move(plan)), source_("infra/" + config.name) {
  if (!make_backend) {
    make_backend = [this](const HeadPlan& h) { return MakeBackend(h, config_); };
  }
  dds_ = std::make_unique<Dds>(participant);
  std::random_device entropy;
  session_id_ = (static_cast<std::uint64_t>(entropy()) << 32) ^ entropy();

  DeviceParams params;
  params.scm_heartbeat_timeout = config_.scm_heartbeat_timeout_s;
  params.flash_period = config_.flash_period_s;
  for (const HeadPlan& h : plan_.heads) {
    params.id = h.id;
    auto head = std::unique_ptr<Head>(new Head{h,
                                               TrafficLightDevice(params, now.mono),
                                               nullptr,
                                               nullptr,
                                               nullptr,
                                               nullptr,
                                               {},
                                               {},
                                               {},
                                               now.mono});
    head->backend = make_backend(h);
    AUTODRIVE_CHECK(head->backend != nullptr, "no backend for head " << h.id.value());
    head->commands =
        std::make_unique<dds::Reader<msg::Int32>>(participant, dds::topics::SignalCommand(h.id));
    head->state =
        std::make_unique<dds::Writer<msg::Int32>>(participant, dds::topics::SignalState(h.id));
    head->status =
        std::make_unique<dds::Writer<msg::DeviceStatus>>(participant, dds::topics::Devices());
    spdlog::info("{}: {} at intersection {} ({})", head->device.name(), head->backend->Describe(),
                 plan_.map.intersection(h.intersection).name, h.intersection.value());
    heads_.push_back(std::move(head));
  }

  if (config_.monitor.enabled) {
    std::map<IntersectionId, std::vector<Head*>> by_intersection;
    for (auto& h : heads_) by_intersection[h->plan.intersection].push_back(h.get());
    for (const auto& [x, heads] : by_intersection) {
      std::vector<SignalHeadId> ids;
      BackendKind backend = BackendKind::kSimulated;
      for (const Head* h : heads) {
        ids.push_back(h->plan.id);
        if (h->backend->kind() == BackendKind::kPhysical) backend = BackendKind::kPhysical;
      }
      auto m = std::unique_ptr<Monitor>(
          new Monitor{ConflictMonitor(plan_.map, x, ids, config_.monitor.conflict_persistence_s),
                      heads,
                      backend,
                      nullptr,
                      {},
                      now.mono});
      m->status =
          std::make_unique<dds::Writer<msg::DeviceStatus>>(participant, dds::topics::Devices());
      const auto& all = plan_.map.intersection(x).signal_heads;
      if (all.size() != ids.size()) {
        spdlog::warn(
            "intersection {}: only {} of its {} signal heads are hosted here; its conflict "
            "monitor sees only those (host all heads of an intersection in one process)",
            m->monitor.intersection_name(), ids.size(), all.size());
      }
      spdlog::info("{}: watching {} heads, {} conflicting pairs (from the map's geometry)",
                   m->monitor.device_id(), ids.size(), m->monitor.conflicts().size());
      monitors_.push_back(std::move(m));
    }
    if (!monitors_.empty()) {
      dds_->operator_requests = std::make_unique<dds::Reader<msg::OperatorRequest>>(
          participant, dds::topics::OperatorRequests());
    }
  }
}

DeviceHost::~DeviceHost() = default;

DeviceHost::Head& DeviceHost::FindHead(SignalHeadId head) const {
  for (const auto& h : heads_) {
    if (h->plan.id == head) return *h;
  }
  throw InputError("signal head " + std::to_string(head.value()) + " is not hosted by " + source_);
}

const TrafficLightDevice& DeviceHost::device(SignalHeadId head) const {
  return FindHead(head).device;
}

LampBackend& DeviceHost::backend(SignalHeadId head) { return *FindHead(head).backend; }

const ConflictMonitor* DeviceHost::monitor(IntersectionId intersection) const {
  for (const auto& m : monitors_) {
    if (m->monitor.intersection() == intersection) return &m->monitor;
  }
  return nullptr;
}

std::vector<SignalHeadId> DeviceHost::heads() const {
  std::vector<SignalHeadId> ids;
  for (const auto& h : heads_) ids.push_back(h->plan.id);
  return ids;
}

void DeviceHost::Run(Clock& clock, Clock& pace) {
  Ticker ticker(pace, kTickPeriod);
  do {
    try {
      Step(clock.Read());
    } catch (const std::exception& e) {
      // The loop is the daemon's boundary: log and carry on with the next tick.
      spdlog::error("tick failed: {}", e.what());
    }
  } while (ticker.WaitNext());
  Stop(clock.Read());
}

void DeviceHost::Step(const ClockReading& now) {
  if (stopped_) return;
  TakeHeartbeats(now);
  TakeCommands(now);
  TakeOperatorRequests(now);
  for (auto& h : heads_) {
    h->device.Update(now.mono);
    DriveLamps(*h, now);
  }
  CheckMonitors(now);
  for (auto& h : heads_) {
    for (const DeviceEvent& e : h->device.TakeEvents()) {
      PublishEvent(now, e.severity, e.code, e.message, h->plan.intersection.value(),
                   h->device.name(), e.active);
    }
  }
  PublishStates();
  PublishStatuses(now, /*stopping=*/false);
  PublishHeartbeat(now, /*stopping=*/false);
}

void DeviceHost::TakeHeartbeats(const ClockReading& now) {
  dds::Message<msg::Heartbeat> m;
  while (dds_->heartbeats.TakeOne(m)) {
    if (dds::View(m->sender) != kScmSender) continue;  // device hosts, including us
    ++counters_.scm_heartbeats;
    if (m->state > autodrive_msgs_msg_Heartbeat_Constants_STOPPING) {
      ++counters_.malformed_heartbeats;
      if (counters_.malformed_heartbeats <= 5 || counters_.malformed_heartbeats % 100 == 0) {
        spdlog::warn("ignored an SCM heartbeat with unknown state {} ({} so far)", m->state,
                     counters_.malformed_heartbeats);
      }
      continue;
    }
    const ScmHeartbeat heartbeat{m->session_id, m->sequence_number,
                                 static_cast<ScmState>(m->state)};
    last_scm_sequence_ = m->sequence_number;
    for (auto& h : heads_) h->device.OnHeartbeat(heartbeat, now.mono);
  }
}

void DeviceHost::TakeCommands(const ClockReading& now) {
  dds::Message<msg::Int32> m;
  for (auto& h : heads_) {
    while (h->commands->TakeOne(m)) {
      ++counters_.commands;
      spdlog::debug("{}: command {}", h->device.name(), m->data);
      h->device.OnCommand(m->data, now.mono);
    }
  }
}

void DeviceHost::TakeOperatorRequests(const ClockReading& now) {
  if (!dds_->operator_requests) return;
  dds::Message<msg::OperatorRequest> m;
  while (dds_->operator_requests->TakeOne(m)) {
    if (dds::View(m->command) != kResetCommand) continue;  // the SCM's business
    for (auto& mon : monitors_) {
      if (m->intersection_id != 0 && m->intersection_id != mon->monitor.intersection().value()) {
        continue;
      }
      if (!mon->monitor.Reset()) continue;
      ++counters_.operator_resets;
      for (Head* h : mon->heads) h->device.ReleaseForce(now.mono);
      PublishEvent(now, Severity::kCritical, "mmu_conflict",
                   mon->monitor.device_id() + " reset by operator " +
                       std::string(dds::View(m->client_id)) + " (request " +
                       std::to_string(m->request_id) + "); heads wait for a new command",
                   mon->monitor.intersection().value(), mon->monitor.device_id(), false);
    }
  }
}

void DeviceHost::DriveLamps(Head& head, const ClockReading& now) {
  head.backend->Show(head.device.aspect(), head.device.LampsAt(now.mono));
  const LampFeedback feedback = head.backend->Poll();
  head.device.OnFeedback(feedback);
  if (feedback.online) {
    head.lamps = feedback.lamps;
  } else {
    head.lamps.reset();
  }
}

void DeviceHost::CheckMonitors(const ClockReading& now) {
  for (auto& mon : monitors_) {
    for (const Head* h : mon->heads) mon->monitor.Observe(h->plan.id, h->lamps, now.mono);
    const std::optional<MonitorLatch> latch = mon->monitor.Update(now.mono);
    if (!latch) continue;
    for (Head* h : mon->heads) {
      h->device.ForceFlash(mon->monitor.device_id() + " latched", now.mono);
      DriveLamps(*h, now);
    }
    PublishEvent(now, Severity::kCritical, "mmu_conflict",
                 mon->monitor.device_id() + " latched, intersection " +
                     mon->monitor.intersection_name() +
                     " flashes red until an operator reset: " + latch->message,
                 mon->monitor.intersection().value(), mon->monitor.device_id(), true);
  }
}

void DeviceHost::PublishEvent(const ClockReading& now, Severity severity, const std::string& code,
                              const std::string& message, std::uint32_t intersection_id,
                              const std::string& device_id, bool active) {
  LogEvent(severity, code, message, active);
  dds::Message<msg::Event> e;
  e->header.stamp = dds::ToMsg(now.wire);
  e->event_id = ++event_sequence_;
  e->severity = static_cast<std::uint8_t>(severity);
  dds::SetString(e->source, source_);
  dds::SetString(e->code, code);
  dds::SetString(e->message, message);
  e->intersection_id = intersection_id;
  dds::SetString(e->device_id, device_id);
  e->active = active;
  if (TryWrite(dds_->events, e, counters_)) ++counters_.events_published;
}

void DeviceHost::PublishStates() {
  for (auto& h : heads_) {
    if (!h->lamps) continue;  // offline: what it shows is unknown; keep the last state
    const std::int32_t state = StateWire(*h->lamps);
    if (h->published_state == state) continue;
    h->published_state = state;
    dds::Message<msg::Int32> m;
    m->data = state;
    TryWrite(*h->state, m, counters_);
  }
}

void DeviceHost::PublishStatuses(const ClockReading& now, bool stopping) {
  const auto publish = [&](dds::Writer<msg::DeviceStatus>& writer, const std::string& device_id,
                           BackendKind backend, const StatusKey& key,
                           std::optional<StatusKey>& published, MonoTime& next) {
    if (!stopping && published == key && now.mono < next) return;
    published = key;
    next = now.mono + config_.status_period_s;
    dds::Message<msg::DeviceStatus> s;
    s->header.stamp = dds::ToMsg(now.wire);
    dds::SetString(s->device_id, device_id);
    s->kind = autodrive_msgs_msg_DeviceStatus_Constants_TRAFFIC_LIGHT;
    s->backend = BackendWire(backend);
    s->health = static_cast<std::uint8_t>(key.health);
    s->mode = static_cast<std::uint8_t>(key.mode);
    s->displayed_state = key.displayed;
    s->scm_heartbeat_seen = last_scm_sequence_;
    dds::SetString(s->detail, key.detail);
    TryWrite(writer, s, counters_);
  };
  for (auto& h : heads_) {
    StatusKey key{h->device.health(), h->device.mode(), ToWire(h->device.aspect()),
                  h->device.detail()};
    if (stopping) {
      key = StatusKey{Health::kOffline, Mode::kFlash, ToWire(Aspect::kFlashingRed),
                      "device host " + source_ + " stopped"};
    }
    publish(*h->status, h->device.name(), h->backend->kind(), key, h->published_status,
            h->next_status);
  }
  for (auto& mon : monitors_) {
    const auto& m = mon->monitor;
    StatusKey key;
    if (m.latched()) {
      key = StatusKey{Health::kFault, Mode::kFlash, ToWire(Aspect::kFlashingRed),
                      "latched: " + m.latch()->message};
    } else {
      key = StatusKey{Health::kOk, Mode::kNormal, ToWire(Aspect::kOff),
                      "watching " + std::to_string(m.heads().size()) + " heads, " +
                          std::to_string(m.conflicts().size()) + " conflicting pairs"};
    }
    if (stopping) {
      key.health = Health::kOffline;
      key.detail = "device host " + source_ + " stopped";
    }
    publish(*mon->status, m.device_id(), mon->backend, key, mon->published_status,
            mon->next_status);
  }
}

void DeviceHost::PublishHeartbeat(const ClockReading& now, bool stopping) {
  if (!stopping && next_heartbeat_ && now.mono < *next_heartbeat_) return;
  next_heartbeat_ = now.mono + config_.status_period_s;
  dds::Message<msg::Heartbeat> m;
  m->header.stamp = dds::ToMsg(now.wire);
  dds::SetString(m->sender, source_);
  m->session_id = session_id_;
  m->sequence_number = heartbeat_sequence_++;
  m->period_ms = static_cast<std::uint32_t>(
      std::chrono::duration_cast<std::chrono::milliseconds>(config_.status_period_s).count());
  m->state = stopping ? autodrive_msgs_msg_Heartbeat_Constants_STOPPING
                      : autodrive_msgs_msg_Heartbeat_Constants_RUNNING;
  TryWrite(dds_->heartbeat, m, counters_);
}

void DeviceHost::Stop(const ClockReading& now) {
  if (stopped_) return;
  stopped_ = true;
  for (auto& h : heads_) {
    // A physical head's controller keeps flashing on its own once we are gone.
    h->backend->Show(Aspect::kFlashingRed, LampsFor(Aspect::kFlashingRed));
    (void)h->backend->Poll();
  }
  PublishStatuses(now, /*stopping=*/true);
  PublishHeartbeat(now, /*stopping=*/true);
  spdlog::info("{} stopped", source_);
}

}  // namespace autodrive::infrastructure
