#include "infrastructure/device_host.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <deque>
#include <map>
#include <random>
#include <unordered_map>
#include <utility>

#include "common/dds/conversions.h"
#include "common/dds/identity.h"
#include "common/dds/loop_waitset.h"
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

static_assert(static_cast<int>(ScmState::kStarting) ==
              autodrive_msgs_msg_Heartbeat_Constants_STARTING);
static_assert(static_cast<int>(Severity::kInfo) == autodrive_msgs_msg_Event_Constants_INFO);

// The one device command there is; the only place its wire value is used.
constexpr std::uint8_t kResetMonitorWire = autodrive_msgs_msg_DeviceCommand_Constants_RESET_MONITOR;

constexpr std::string_view kScmSender = "scm";
// Text from the network goes into logs and events cut to this length.
constexpr std::size_t kExcerpt = 64;

// What a DeviceStatus says, apart from time and heartbeat sequence: publish when it changes.
struct StatusKey {
  Health health = Health::kOk;
  Mode mode = Mode::kNormal;
  std::int32_t displayed = 0;
  std::string detail;
  std::uint64_t last_command_id = 0;
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

// `text` (from the network) quoted and cut to `kExcerpt` characters.
std::string Quoted(std::string_view text) {
  if (text.size() <= kExcerpt) return "'" + std::string(text) + "'";
  return "'" + std::string(text.substr(0, kExcerpt)) + "...'";
}

// "green", or "9 (not an aspect)".
std::string CommandText(std::int32_t wire) {
  if (const auto aspect = AspectFromWire(wire)) return std::string(ToString(*aspect));
  return std::to_string(wire) + " (not an aspect)";
}

std::string Hex(std::uint64_t value) { return fmt::format("{:#x}", value); }

// Lets a report of one kind out at most once per period of the control timeline, and counts
// the ones it held back. Time going back (a new clock session: `Restart`) never blocks it.
class ReportLimiter {
 public:
  // True when a report may go out at `now`.
  bool Allow(MonoTime now, Duration period) {
    if (last_ && now >= *last_ && now - *last_ < period) {
      ++held_back_;
      return false;
    }
    last_ = now;
    return true;
  }
  // The reports held back since the last one that went out.
  std::uint64_t TakeHeldBack() { return std::exchange(held_back_, 0); }
  void Restart() { last_.reset(); }

 private:
  std::optional<MonoTime> last_;
  std::uint64_t held_back_ = 0;
};

// A writer on the host's loop, which must never block: the catalogue's QoS, non-blocking.
template <typename T>
std::unique_ptr<dds::Writer<T>> LoopWriter(const dds::Participant& participant,
                                           const dds::TopicSpec<T>& spec) {
  return std::make_unique<dds::Writer<T>>(participant, spec.name, spec.qos.NonBlocking());
}

}  // namespace

struct DeviceHost::Head {
  Head(const HeadPlan& p, const DeviceParams& params, MonoTime now)
      : plan(p), device(params, now), next_status(now) {}

  // A command kept while no SCM is followed and current.
  struct Held {
    dds::ParticipantKey writer;
    std::int32_t value = 0;
    std::uint64_t order = 0;  // arrival order, host-wide
  };

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
  // What the loop did with the device last: it drives the lamps again when the device's
  // revision moved, at `next_drive` (a flash edge, a heartbeat time-out), or when the backend
  // has I/O of its own; it builds the status again when the revision moved or one is due.
  std::uint64_t driven_revision = ~std::uint64_t{0};
  MonoTime next_drive = MonoTime::min();
  std::uint64_t status_revision = ~std::uint64_t{0};
  bool driven = false;            // in this pass: its monitor looks at it
  bool commands_waiting = false;  // its reader woke the loop's waitset
  std::vector<Held> held;         // at most kMaxHeldWriters, one per writer participant
  std::uint64_t foreign_commands = 0;
  ReportLimiter foreign_reports;
};

struct DeviceHost::Monitor {
  Monitor(ConflictMonitor m, std::vector<Head*> h, BackendKind b, MonoTime now)
      : monitor(std::move(m)),
        heads(std::move(h)),
        backend(b),
        next_status(now),
        watching("watching " + std::to_string(monitor.heads().size()) + " heads, " +
                 std::to_string(monitor.conflicts().size()) + " conflicting pairs") {}

  ConflictMonitor monitor;
  std::vector<Head*> heads;
  BackendKind backend = BackendKind::kSimulated;
  std::unique_ptr<dds::Writer<msg::DeviceStatus>> status;
  std::optional<StatusKey> published_status;
  MonoTime next_status{};
  std::string watching;  // its status detail while not latched
  // The last device command carried out, and the SCM that sent it.
  std::uint64_t last_command_id = 0;
  std::optional<ScmId> last_command_scm;
};

struct DeviceHost::Dds {
  const dds::Participant& participant;
  dds::Reader<msg::Heartbeat> heartbeats;
  std::unique_ptr<dds::Writer<msg::Heartbeat>> heartbeat;
  std::unique_ptr<dds::Writer<msg::Event>> events;
  std::unique_ptr<dds::Reader<msg::DeviceCommand>> device_commands;  // when monitors run here
  std::unique_ptr<dds::Reader<msg::SimFault>> sim_faults;  // when a simulated head runs here
  dds::WriterParticipants writers;                         // who wrote each sample (bounded cache)

  explicit Dds(const dds::Participant& p)
      : participant(p),
        heartbeats(p, dds::topics::Heartbeat()),
        heartbeat(LoopWriter(p, dds::topics::InfraHeartbeat())),
        events(LoopWriter(p, dds::topics::Events())) {}
};

struct DeviceHost::Reports {
  ReportLimiter device_commands;
  ReportLimiter unidentified;
  std::deque<std::uint64_t> foreign_sessions;  // other cities' SCM sessions already reported
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
    : config_(config),
      plan_(std::move(plan)),
      source_("infra/" + config.name),
      reports_(std::make_unique<Reports>()),
      clock_session_(now.session) {
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
    auto head = std::make_unique<Head>(h, params, now.mono);
    head->backend = make_backend(h);
    AUTODRIVE_CHECK(head->backend != nullptr, "no backend for head " << h.id.value());
    head->held.reserve(kMaxHeldWriters);
    head->commands =
        std::make_unique<dds::Reader<msg::Int32>>(participant, dds::topics::SignalCommand(h.id));
    head->state = LoopWriter(participant, dds::topics::SignalState(h.id));
    head->status = LoopWriter(participant, dds::topics::Devices());
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
      auto m = std::make_unique<Monitor>(
          ConflictMonitor(plan_.map, x, ids, config_.monitor.conflict_persistence_s), heads,
          backend, now.mono);
      m->status = LoopWriter(participant, dds::topics::Devices());
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
      dds_->device_commands = std::make_unique<dds::Reader<msg::DeviceCommand>>(
          participant, dds::topics::DeviceCommands());
    }
  }
  if (std::ranges::any_of(
          heads_, [](const auto& h) { return h->backend->kind() == BackendKind::kSimulated; })) {
    dds_->sim_faults =
        std::make_unique<dds::Reader<msg::SimFault>>(participant, dds::topics::SimFaults());
  }
  spdlog::info("{} serves city {}: it follows only the heartbeat of that city's SCM", source_,
               config_.city);
}

DeviceHost::~DeviceHost() = default;

DeviceHost::Head& DeviceHost::FindHead(SignalHeadId head) const {
  for (const auto& h : heads_) {
    if (h->plan.id == head) return *h;
  }
  throw InputError("signal head " + std::to_string(head.value()) + " is not hosted by " + source_);
}

DeviceHost::Monitor& DeviceHost::FindMonitor(IntersectionId intersection) const {
  for (const auto& m : monitors_) {
    if (m->monitor.intersection() == intersection) return *m;
  }
  throw InputError("no conflict monitor watches intersection " +
                   std::to_string(intersection.value()) + " in " + source_);
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

std::uint64_t DeviceHost::last_command_id(IntersectionId intersection) const {
  const Monitor& m = FindMonitor(intersection);
  return m.last_command_scm && m.last_command_scm == last_scm_ ? m.last_command_id : 0;
}

std::vector<SignalHeadId> DeviceHost::heads() const {
  std::vector<SignalHeadId> ids;
  for (const auto& h : heads_) ids.push_back(h->plan.id);
  return ids;
}

void DeviceHost::Run(Clock& clock, Clock& pace) {
  // Waits on the pace (wall) clock: real time bounds every wait, so that the serial links are
  // served while a simulation is paused. A separate (simulated) clock wakes the same waitset
  // when /clock reaches the next deadline.
  dds::LoopWaitSet waitset(dds_->participant, pace);
  waitset.Attach(dds_->heartbeats);
  if (dds_->device_commands) waitset.Attach(*dds_->device_commands);
  if (dds_->sim_faults) waitset.Attach(*dds_->sim_faults);
  std::unordered_map<dds_entity_t, Head*> by_reader;
  by_reader.reserve(heads_.size());
  for (const auto& h : heads_) {
    waitset.Attach(*h->commands);
    by_reader.emplace(h->commands->handle(), h.get());
  }
  // The first pass, and one after a failure, takes every reader; the others only those that
  // woke the waitset (a reader left with data wakes it again at once).
  bool all_commands = true;
  // Backends with I/O of their own are served every tick; without them, data and deadlines
  // alone wake the loop.
  const bool polled = std::any_of(heads_.begin(), heads_.end(),
                                  [](const auto& h) { return h->backend->NeedsPoll(); });
  const Duration cap = polled ? kTickPeriod : kIdleWait;
  const bool separate = &clock != &pace;
  if (separate) clock.SetWaker([&waitset] { waitset.Wake(); });
  std::uint64_t failures = 0;
  const auto failed = [&](const char* what, const std::exception& e) {
    // The loop is the daemon's boundary: log (the first few, then every 100th) and carry on,
    // without spinning on a failure that repeats.
    if (++failures <= 5 || failures % 100 == 0) {
      spdlog::error("{} failed ({} failures so far): {}", what, failures, e.what());
    }
    (void)pace.SleepFor(kTickPeriod);
  };
  while (!clock.interrupted() && !pace.interrupted()) {
    const ClockReading now = clock.Read();
    MonoTime next = now.mono + cap;
    try {
      Pass(now, all_commands);
      all_commands = false;
      next = NextDeadline(now);
    } catch (const std::exception& e) {
      all_commands = true;
      failed("a pass", e);
    }
    try {
      if (separate) {
        clock.WakeAt(next);
        (void)waitset.WaitUntil(pace.Monotonic() + cap);
      } else {
        (void)waitset.WaitUntil(std::min(next, now.mono + cap));
      }
      for (const dds_attach_t reader : waitset.triggered()) {
        const auto it = by_reader.find(static_cast<dds_entity_t>(reader));
        if (it != by_reader.end()) it->second->commands_waiting = true;
      }
    } catch (const std::exception& e) {
      all_commands = true;
      failed("waiting", e);
    }
  }
  if (separate) clock.SetWaker({});
  Stop(clock.Read());
}

MonoTime DeviceHost::NextDeadline(const ClockReading& now) const {
  MonoTime next = MonoTime::max();
  for (const auto& h : heads_) {
    next = std::min({next, h->next_status, h->device.NextChange(now.mono)});
  }
  for (const auto& m : monitors_) {
    next = std::min(next, m->next_status);
    if (const auto latch = m->monitor.NextLatch()) next = std::min(next, *latch);
  }
  if (next_heartbeat_) next = std::min(next, *next_heartbeat_);
  // Everything due is done by the pass that just ran; never spin on a deadline in the past.
  return std::max(next, now.mono + std::chrono::milliseconds(1));
}

void DeviceHost::Step(const ClockReading& now) { Pass(now, /*all_commands=*/true); }

void DeviceHost::Pass(const ClockReading& now, bool all_commands) {
  if (stopped_) return;
  if (now.session != clock_session_) RestartTimeBase(now);
  // Heartbeats first (who the SCM is), then device commands (a reset releases the heads), then
  // light commands (a red taken in the same pass as the reset ends the heads' flash).
  // The twin's faults first: they may cut or restore the link with the SCM.
  TakeSimFaults(now);
  if (link_cut_) {
    DropLinkTraffic();
  } else {
    TakeHeartbeats(now);
    TakeDeviceCommands(now);
    TakeCommands(now, all_commands);
  }
  for (auto& h : heads_) {
    h->driven = false;
    h->device.Update(now.mono);
    if (h->device.revision() != h->driven_revision || now.mono >= h->next_drive ||
        h->backend->NeedsPoll()) {
      DriveLamps(*h, now);
    }
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

void DeviceHost::RestartTimeBase(const ClockReading& now) {
  ++counters_.clock_restarts;
  spdlog::warn(
      "the clock started session {} (was {}): the simulation restarted; heads go back to "
      "start-up flash and wait for the SCM, monitors keep their latches",
      now.session, clock_session_);
  clock_session_ = now.session;
  const std::string reason =
      "simulated clock restarted (session " + std::to_string(now.session) + ")";
  // Every instant remembered so far is on the old timeline: forget them all.
  scm_.reset();
  scm_running_ = false;
  next_heartbeat_.reset();
  reports_->device_commands.Restart();
  reports_->unidentified.Restart();
  for (auto& h : heads_) {
    h->device.Restart(reason, now.mono);
    h->next_status = now.mono;
    h->foreign_reports.Restart();
  }
  for (auto& m : monitors_) {
    m->monitor.RestartTimers();
    m->next_status = now.mono;
  }
}

bool DeviceHost::ScmCurrent(MonoTime now) const {
  return scm_.has_value() && scm_running_ &&
         now - scm_last_running_ <= config_.scm_heartbeat_timeout_s;
}

void DeviceHost::TakeHeartbeats(const ClockReading& now) {
  dds::Message<msg::Heartbeat> m;
  dds::SampleInfo info;
  while (dds_->heartbeats.TakeOne(m, &info)) {
    // Only the SCM writes this topic (device hosts have their own), and with DDS Security only
    // the SCM's identity can; without it, a sender that is not the SCM is still not followed.
    if (dds::View(m->sender) != kScmSender) continue;
    ++counters_.scm_heartbeats;
    const std::string_view city = dds::View(m->city);
    if (city != config_.city) {
      ++counters_.foreign_scm_heartbeats;
      auto& seen = reports_->foreign_sessions;
      if (std::find(seen.begin(), seen.end(), m->session_id) == seen.end()) {
        if (seen.size() >= kMaxForeignSessions) seen.pop_front();
        seen.push_back(m->session_id);
        PublishEvent(now, Severity::kWarning, "foreign_scm",
                     source_ + " ignores the heartbeat of the SCM of city " + Quoted(city) +
                         " (session " + Hex(m->session_id) + "): it serves city '" + config_.city +
                         "'",
                     0, "", true);
      }
      continue;
    }
    if (m->state > autodrive_msgs_msg_Heartbeat_Constants_STOPPING) {
      ++counters_.malformed_heartbeats;
      if (counters_.malformed_heartbeats <= 5 || counters_.malformed_heartbeats % 100 == 0) {
        spdlog::warn("ignored an SCM heartbeat with unknown state {} ({} so far)", m->state,
                     counters_.malformed_heartbeats);
      }
      continue;
    }
    const std::optional<dds::ParticipantKey> writer = dds_->writers.Find(dds_->heartbeats, info);
    if (!writer) {
      ++counters_.unidentified_samples;
      if (reports_->unidentified.Allow(now.mono, kReportPeriod)) {
        spdlog::warn("ignored an SCM heartbeat whose writer is no longer known ({} such samples)",
                     counters_.unidentified_samples);
      }
      continue;
    }
    FollowScm(ScmId{m->session_id, *writer});
    const auto state = static_cast<ScmState>(m->state);
    if (state == ScmState::kRunning) {
      scm_running_ = true;
      scm_last_running_ = now.mono;
    } else if (state == ScmState::kStopping) {
      scm_running_ = false;
    }
    last_scm_sequence_ = m->sequence_number;
    // The devices know the SCM by a number that changes whenever the SCM followed changes
    // (session or participant), so that each change applies the restart rules.
    const ScmHeartbeat heartbeat{counters_.scm_changes, m->sequence_number, state};
    for (auto& h : heads_) {
      // Its commands held until now come before its heartbeat, as a latched command at
      // start-up does; after a loss or a restart they are not new (the device's rules).
      const auto held = std::find_if(h->held.begin(), h->held.end(),
                                     [&](const Head::Held& c) { return c.writer == *writer; });
      if (held != h->held.end()) {
        h->device.Update(now.mono);  // a loss the host has seen, the device sees too
        h->device.OnCommand(held->value, now.mono);
        h->held.erase(held);
      }
      h->device.OnHeartbeat(heartbeat, now.mono);
    }
    if (ScmCurrent(now.mono)) {
      // Commands held from anyone else were not the SCM's.
      for (auto& h : heads_) {
        for (const auto& c : h->held) ReportForeignCommand(*h, c.writer, c.value, now);
        h->held.clear();  // keeps its capacity
      }
    }
  }
}

void DeviceHost::FollowScm(const ScmId& scm) {
  scm_ = scm;
  if (last_scm_ == scm) return;
  ++counters_.scm_changes;
  spdlog::info("{} follows the SCM of city {}: session {}, participant {}", source_, config_.city,
               Hex(scm.session), scm.participant.ToString());
  last_scm_ = scm;
}

void DeviceHost::TakeSimFaults(const ClockReading& now) {
  if (!dds_->sim_faults) return;
  dds::Message<msg::SimFault> m;
  while (dds_->sim_faults->TakeOne(m)) {
    if (m->action == autodrive_msgs_msg_SimFault_Constants_LINK_CUT ||
        m->action == autodrive_msgs_msg_SimFault_Constants_LINK_RESTORE) {
      if (dds::View(m->host) != config_.name) continue;  // another host's link
      const bool cut = m->action == autodrive_msgs_msg_SimFault_Constants_LINK_CUT;
      if (cut == link_cut_) continue;
      ++counters_.sim_faults;
      const std::string message =
          fmt::format("{}: the link with the SCM {} (a fault injected by '{}')", source_,
                      cut ? "is cut" : "is back", dds::View(m->header.frame_id));
      // Said while the link is up: before it is cut, once it is back.
      if (cut) PublishEvent(now, Severity::kWarning, "sim_fault", message, 0, "", false);
      link_cut_ = cut;
      if (!cut) PublishEvent(now, Severity::kWarning, "sim_fault", message, 0, "", false);
      continue;
    }
    const SignalHeadId id(m->head);
    const auto it = std::ranges::find_if(heads_, [&](const auto& h) { return h->plan.id == id; });
    if (it == heads_.end()) continue;  // another host's head
    Head& h = **it;
    const std::string sender(dds::View(m->header.frame_id));
    const std::string reason(dds::View(m->reason));
    auto* simulated = dynamic_cast<SimulatedBackend*>(h.backend.get());
    const std::optional<Lamp> lamp =
        m->lamp >= 1 && m->lamp <= 3 ? std::optional(kAllLamps[m->lamp - 1]) : std::nullopt;
    const auto lamp_name = [&] { return std::string(ToString(*lamp)); };
    std::string done;  // what was done; empty: refused
    if (simulated == nullptr) {
      // a physical head: refused below
    } else if (m->action == autodrive_msgs_msg_SimFault_Constants_FAIL_LAMP && lamp) {
      simulated->FailLamp(*lamp, reason.empty() ? "open_circuit" : reason);
      done = lamp_name() + " lamp burnt out";
    } else if (m->action == autodrive_msgs_msg_SimFault_Constants_STICK_LAMP && lamp) {
      simulated->StickLamp(*lamp);
      done = lamp_name() + " lamp stuck on";
    } else if (m->action == autodrive_msgs_msg_SimFault_Constants_REPAIR_LAMP && lamp) {
      simulated->RepairLamp(*lamp);
      done = lamp_name() + " lamp repaired";
    } else if (m->action == autodrive_msgs_msg_SimFault_Constants_UNPLUG_HEAD) {
      simulated->SetOffline(reason.empty() ? "unplugged" : reason);
      done = "unplugged";
    } else if (m->action == autodrive_msgs_msg_SimFault_Constants_PLUG_HEAD) {
      simulated->SetOffline(std::nullopt);
      done = "plugged in again";
    }
    if (done.empty()) {
      ++counters_.sim_faults_refused;
      const std::string why =
          simulated == nullptr
              ? "it is a physical head (only simulated heads take faults)"
              : fmt::format("action {} with lamp {} is not a fault", static_cast<int>(m->action),
                            static_cast<int>(m->lamp));
      spdlog::warn("{}: a fault for {} from '{}' refused: {}", source_, h.device.name(), sender,
                   why);
      PublishEvent(
          now, Severity::kWarning, "sim_fault_refused",
          fmt::format("{}: a fault injection from '{}' refused: {}", h.device.name(), sender, why),
          h.plan.intersection.value(), h.device.name(), false);
      continue;
    }
    ++counters_.sim_faults;
    spdlog::warn("{}: injected fault from '{}': {} {}", source_, sender, h.device.name(), done);
    PublishEvent(now, Severity::kWarning, "sim_fault",
                 fmt::format("{}: {} (a fault injected by '{}')", h.device.name(), done, sender),
                 h.plan.intersection.value(), h.device.name(), false);
  }
}

void DeviceHost::TakeDeviceCommands(const ClockReading& now) {
  if (!dds_->device_commands) return;
  dds::Message<msg::DeviceCommand> m;
  dds::SampleInfo info;
  while (dds_->device_commands->TakeOne(m, &info)) {
    ++counters_.device_commands;
    const std::string_view device_id = dds::View(m->device_id);
    const std::string_view city = dds::View(m->city);
    Monitor* target = nullptr;
    for (auto& mon : monitors_) {
      if (mon->monitor.device_id() == device_id) target = mon.get();
    }
    const bool names_a_head = std::any_of(
        heads_.begin(), heads_.end(), [&](const auto& h) { return h->device.name() == device_id; });
    if (city == config_.city && target == nullptr && !names_a_head) {
      // Another host's device: none of our business.
      ++counters_.device_commands_not_ours;
      spdlog::debug("device command {} for {}: not a device of {}", m->command_id,
                    Quoted(device_id), source_);
      continue;
    }
    const std::optional<dds::ParticipantKey> writer =
        dds_->writers.Find(*dds_->device_commands, info);
    std::string why;
    if (city != config_.city) {
      why = "it is for city " + Quoted(city) + ", this host serves '" + config_.city + "'";
    } else if (!writer) {
      ++counters_.unidentified_samples;
      why = "its writer is no longer known";
    } else if (!scm_) {
      why = "no SCM heartbeat of city '" + config_.city + "' followed yet";
    } else if (*writer != scm_->participant) {
      why = "it was written by participant " + writer->ToString() + ", not the SCM's (" +
            scm_->participant.ToString() + ")";
    } else if (m->scm_session != scm_->session) {
      why = "it is for SCM session " + Hex(m->scm_session) + ", the SCM followed has session " +
            Hex(scm_->session);
    } else if (target == nullptr) {
      why = std::string(device_id) + " takes no device commands";
    } else if (m->command != kResetMonitorWire) {
      why = "unknown command " + std::to_string(m->command);
    } else if (m->intersection_id == 0) {
      why = "intersection 0 names no intersection";
    } else if (m->intersection_id != target->monitor.intersection().value()) {
      why = target->monitor.device_id() + " watches intersection " +
            std::to_string(target->monitor.intersection().value()) + ", not " +
            std::to_string(m->intersection_id);
    } else if (target->last_command_scm == scm_ && m->command_id <= target->last_command_id) {
      // Sent again (the SCM did not see the acknowledgement yet): say it again.
      ++counters_.device_commands_repeated;
      spdlog::debug("{}: device command {} was already carried out (last {})",
                    target->monitor.device_id(), m->command_id, target->last_command_id);
      target->published_status.reset();
      continue;
    }
    if (!why.empty()) {
      ++counters_.device_commands_ignored;
      ReportIgnoredDeviceCommand(now, "ignored device command " + std::to_string(m->command_id) +
                                          " for " + Quoted(device_id) + " (intersection " +
                                          std::to_string(m->intersection_id) + ", operator " +
                                          Quoted(dds::View(m->issued_by)) + ", request " +
                                          std::to_string(m->request_id) + "): " + why);
      continue;
    }
    CarryOut(*target, *scm_, m->command_id,
             std::string(dds::View(m->issued_by)).substr(0, kExcerpt), m->request_id, now);
  }
}

void DeviceHost::CarryOut(Monitor& mon, const ScmId& scm, std::uint64_t command_id,
                          const std::string& issued_by, std::uint64_t request_id,
                          const ClockReading& now) {
  const bool was_latched = mon.monitor.Reset();
  mon.last_command_id = command_id;
  mon.last_command_scm = scm;
  ++counters_.device_commands_done;
  // The heads wait for a new command; one taken later in this pass is new.
  for (Head* h : mon.heads) h->device.ReleaseForce(now.mono);
  if (was_latched) {
    ++counters_.monitor_resets;
    PublishEvent(now, Severity::kCritical, "mmu_conflict",
                 mon.monitor.device_id() + " reset by the SCM (device command " +
                     std::to_string(command_id) + ", operator '" + issued_by + "', request " +
                     std::to_string(request_id) + "); heads wait for a new command",
                 mon.monitor.intersection().value(), mon.monitor.device_id(), false);
  } else {
    spdlog::info(
        "{}: reset by the SCM (device command {}, operator '{}', request {}): it was not "
        "latched",
        mon.monitor.device_id(), command_id, issued_by, request_id);
  }
}

void DeviceHost::ReportIgnoredDeviceCommand(const ClockReading& now, const std::string& reason) {
  if (!reports_->device_commands.Allow(now.mono, kReportPeriod)) return;
  const std::uint64_t held_back = reports_->device_commands.TakeHeldBack();
  PublishEvent(now, Severity::kWarning, "device_command_ignored",
               source_ + " " + reason + " (" + std::to_string(counters_.device_commands_ignored) +
                   " ignored so far" +
                   (held_back > 0 ? ", " + std::to_string(held_back) + " not reported" : "") + ")",
               0, "", true);
}

void DeviceHost::TakeCommands(const ClockReading& now, bool all_commands) {
  dds::Message<msg::Int32> m;
  dds::SampleInfo info;
  for (auto& h : heads_) {
    if (!all_commands && !h->commands_waiting) continue;
    h->commands_waiting = false;
    while (h->commands->TakeOne(m, &info)) {
      ++counters_.commands;
      const std::optional<dds::ParticipantKey> writer = dds_->writers.Find(*h->commands, info);
      if (!writer) {
        ++counters_.unidentified_samples;
        if (reports_->unidentified.Allow(now.mono, kReportPeriod)) {
          spdlog::warn("{}: ignored a command whose writer is no longer known ({} such samples)",
                       h->device.name(), counters_.unidentified_samples);
        }
        continue;
      }
      if (scm_ && *writer == scm_->participant) {
        spdlog::debug("{}: command {}", h->device.name(), m->data);
        h->device.OnCommand(m->data, now.mono);
      } else if (!ScmCurrent(now.mono)) {
        HoldCommand(*h, *writer, m->data);
      } else {
        ReportForeignCommand(*h, *writer, m->data, now);
      }
    }
  }
}

void DeviceHost::HoldCommand(Head& head, const dds::ParticipantKey& writer, std::int32_t value) {
  ++counters_.held_commands;
  const std::uint64_t order = ++held_sequence_;
  for (auto& c : head.held) {
    if (c.writer == writer) {
      c.value = value;
      c.order = order;
      return;
    }
  }
  if (head.held.size() < kMaxHeldWriters) {
    head.held.push_back(Head::Held{writer, value, order});
    return;
  }
  ++counters_.held_dropped;
  auto oldest = std::min_element(head.held.begin(), head.held.end(),
                                 [](const auto& a, const auto& b) { return a.order < b.order; });
  *oldest = Head::Held{writer, value, order};
}

void DeviceHost::ReportForeignCommand(Head& head, const dds::ParticipantKey& writer,
                                      std::int32_t value, const ClockReading& now) {
  ++counters_.foreign_commands;
  ++head.foreign_commands;
  if (!head.foreign_reports.Allow(now.mono, kReportPeriod)) return;
  const std::uint64_t held_back = head.foreign_reports.TakeHeldBack();
  PublishEvent(now, Severity::kWarning, "foreign_command",
               head.device.name() + " ignored command " + CommandText(value) +
                   " from participant " + writer.ToString() + ": only the SCM's participant (" +
                   (scm_ ? scm_->participant.ToString() : std::string("none yet")) +
                   ") commands it (" + std::to_string(head.foreign_commands) + " ignored so far" +
                   (held_back > 0 ? ", " + std::to_string(held_back) + " not reported" : "") + ")",
               head.plan.intersection.value(), head.device.name(), true);
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
  ++counters_.heads_driven;
  head.driven = true;
  head.driven_revision = head.device.revision();
  head.next_drive = head.device.NextChange(now.mono);
}

void DeviceHost::CheckMonitors(const ClockReading& now) {
  for (auto& mon : monitors_) {
    // Lamps not driven in this pass are as observed last; then only a latch can come, at its
    // instant.
    const bool observe =
        std::any_of(mon->heads.begin(), mon->heads.end(), [](const Head* h) { return h->driven; });
    if (!observe) {
      const std::optional<MonoTime> latch = mon->monitor.NextLatch();
      if (!latch || now.mono < *latch) continue;
    }
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
  if (link_cut_) return;  // the SCM would not hear it (the twin's link cut): logged only
  if (TryWrite(*dds_->events, e, counters_)) ++counters_.events_published;
}

void DeviceHost::DropLinkTraffic() {
  // What the SCM sent is lost on a cut link: taken and dropped, as the network would.
  // Counted as taken, and in `dropped_on_cut_link`.
  dds::Message<msg::Heartbeat> heartbeat;
  while (dds_->heartbeats.TakeOne(heartbeat)) {
    if (dds::View(heartbeat->sender) != kScmSender) continue;
    ++counters_.scm_heartbeats;
    ++counters_.dropped_on_cut_link;
  }
  if (dds_->device_commands) {
    dds::Message<msg::DeviceCommand> command;
    while (dds_->device_commands->TakeOne(command)) {
      ++counters_.device_commands;
      ++counters_.dropped_on_cut_link;
    }
  }
  dds::Message<msg::Int32> light;
  for (auto& h : heads_) {
    h->commands_waiting = false;
    while (h->commands->TakeOne(light)) {
      ++counters_.commands;
      ++counters_.dropped_on_cut_link;
    }
  }
}

void DeviceHost::PublishStates() {
  for (auto& h : heads_) {
    if (!h->lamps) continue;  // offline: what it shows is unknown; keep the last state
    const std::int32_t state = StateWire(*h->lamps);
    if (h->published_state == state) continue;
    dds::Message<msg::Int32> m;
    m->data = state;
    // A failed write is tried again at the next pass.
    if (TryWrite(*h->state, m, counters_)) h->published_state = state;
  }
}

void DeviceHost::PublishStatuses(const ClockReading& now, bool stopping) {
  if (link_cut_) return;  // the SCM would not hear them (the twin's link cut)
  // A periodic status goes out with any pass in the last tenth of its period.
  const Duration slack = config_.status_period_s / 10;
  const auto publish = [&](dds::Writer<msg::DeviceStatus>& writer, const std::string& device_id,
                           BackendKind backend, const StatusKey& key,
                           std::optional<StatusKey>& published, MonoTime& next) {
    if (!stopping && published == key && now.mono < next - slack) return;  // nothing new
    next = now.mono + config_.status_period_s;
    dds::Message<msg::DeviceStatus> s;
    s->header.stamp = dds::ToMsg(now.wire);
    dds::SetString(s->device_id, device_id);
    dds::SetString(s->city, config_.city);
    dds::SetString(s->host, source_);
    s->kind = autodrive_msgs_msg_DeviceStatus_Constants_TRAFFIC_LIGHT;
    s->backend = BackendWire(backend);
    s->health = static_cast<std::uint8_t>(key.health);
    s->mode = static_cast<std::uint8_t>(key.mode);
    s->displayed_state = key.displayed;
    s->scm_heartbeat_seen = last_scm_sequence_;
    dds::SetString(s->detail, key.detail);
    s->last_command_id = key.last_command_id;
    // A failed write leaves `published` as it was, so that a change is sent again next pass.
    if (TryWrite(writer, s, counters_)) published = key;
  };
  for (auto& h : heads_) {
    // Unchanged since its status was last built and not due: nothing to build (the detail is
    // a string).
    if (!stopping && h->device.revision() == h->status_revision &&
        now.mono < h->next_status - slack) {
      continue;
    }
    StatusKey key{h->device.health(), h->device.mode(), ToWire(h->device.aspect()),
                  h->device.detail(), 0};
    if (stopping) {
      key = StatusKey{Health::kOffline, Mode::kFlash, ToWire(Aspect::kFlashingRed),
                      "device host " + source_ + " stopped", 0};
    }
    publish(*h->status, h->device.name(), h->backend->kind(), key, h->published_status,
            h->next_status);
    // A failed write is tried again next pass (`published_status` is still the old key).
    if (h->published_status == key) h->status_revision = h->device.revision();
  }
  for (auto& mon : monitors_) {
    const auto& m = mon->monitor;
    const Health health = m.latched() ? Health::kFault : Health::kOk;
    const std::uint64_t command_id =
        mon->last_command_scm && mon->last_command_scm == last_scm_ ? mon->last_command_id : 0;
    // Nothing changed (a new latch needs a reset first, which changes the command id) and
    // not due: nothing to build.
    if (!stopping && now.mono < mon->next_status - slack && mon->published_status &&
        mon->published_status->health == health &&
        mon->published_status->last_command_id == command_id) {
      continue;
    }
    StatusKey key;
    if (m.latched()) {
      key = StatusKey{Health::kFault, Mode::kFlash, ToWire(Aspect::kFlashingRed),
                      "latched: " + m.latch()->message, 0};
    } else {
      key = StatusKey{Health::kOk, Mode::kNormal, ToWire(Aspect::kOff), mon->watching, 0};
    }
    key.last_command_id = command_id;
    if (stopping) {
      key.health = Health::kOffline;
      key.detail = "device host " + source_ + " stopped";
    }
    publish(*mon->status, m.device_id(), mon->backend, key, mon->published_status,
            mon->next_status);
  }
}

void DeviceHost::PublishHeartbeat(const ClockReading& now, bool stopping) {
  if (link_cut_) return;  // the SCM would not hear it (the twin's link cut)
  if (!stopping && next_heartbeat_ && now.mono < *next_heartbeat_) return;
  next_heartbeat_ = now.mono + config_.status_period_s;
  dds::Message<msg::Heartbeat> m;
  m->header.stamp = dds::ToMsg(now.wire);
  dds::SetString(m->sender, source_);
  dds::SetString(m->city, config_.city);
  m->session_id = session_id_;
  m->sequence_number = heartbeat_sequence_++;
  m->period_ms = static_cast<std::uint32_t>(
      std::chrono::duration_cast<std::chrono::milliseconds>(config_.status_period_s).count());
  m->state = stopping ? autodrive_msgs_msg_Heartbeat_Constants_STOPPING
                      : autodrive_msgs_msg_Heartbeat_Constants_RUNNING;
  TryWrite(*dds_->heartbeat, m, counters_);
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
