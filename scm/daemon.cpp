#include "scm/daemon.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <deque>
#include <random>
#include <set>

#include "autodrive_msgs/msg/DeviceStatus.h"
#include "autodrive_msgs/msg/Event.h"
#include "autodrive_msgs/msg/Heartbeat.h"
#include "autodrive_msgs/msg/IntersectionState.h"
#include "autodrive_msgs/msg/OperatorReply.h"
#include "autodrive_msgs/msg/SignalGroupState.h"
#include "autodrive_msgs/msg/SignalRequest.h"

#include "common/dds/conversions.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "scm/fleet.h"
#include "scm/map_data.h"
#include "scm/operator.h"
#include "scm/store.h"

namespace autodrive::scm {

namespace {

using std::chrono::milliseconds;

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

DayClock DayAt(Time now) {
  const std::time_t t =
      std::chrono::duration_cast<std::chrono::seconds>(now.time_since_epoch()).count();
  std::tm tm{};
  localtime_r(&t, &tm);
  const Duration sub = now.time_since_epoch() - std::chrono::seconds(t);
  return DayClock::At(std::chrono::seconds(tm.tm_hour * 3600 + tm.tm_min * 60 + tm.tm_sec) + sub);
}

/// One traffic light head as the SCM supervises it.
struct Head {
  SignalHeadId id{0};
  std::size_t intersection = 0;  ///< index into `Impl::xs`
  std::size_t group = 0;
  std::string name;  ///< "signal_<i>"
  std::unique_ptr<dds::Writer<msg::Int32>> writer;
  std::optional<Aspect> commanded;
  MonoTime commanded_at{};
  bool seen = false;
  MonoTime last_status{};
  std::uint8_t health = 0;
  std::uint8_t mode = 0;
  std::optional<Aspect> displayed;
  std::string detail;
  std::optional<MonoTime> mismatch_since;
  bool lost = false;
  bool faulty = false;
};

/// One intersection at run time.
struct Runtime {
  const IntersectionModel* model = nullptr;
  std::optional<IntersectionController> controller;
  std::optional<ConflictMonitor> monitor;
  std::vector<std::size_t> heads;  ///< indices into `Impl::heads`
  std::uint32_t revision = 0;
  std::vector<Aspect> last_aspects;
  std::string saved_mode;
  std::string saved_plan;
  std::string fault;  ///< why it is latched by device supervision, for reset refusals
};

}  // namespace

struct Scm::Impl {
  Impl(const ScmOptions& o, Clock& c) : options(o), clock(c), store(o.db_path) {}

  ScmOptions options;
  Clock& clock;
  Store store;
  std::unique_ptr<City> city;
  std::unique_ptr<FleetRegistry> fleet;
  std::vector<Runtime> xs;
  std::vector<Head> heads;
  std::map<SignalHeadId, std::size_t> head_index;
  std::atomic<bool> stop{false};
  ScmCounters counters;
  std::uint64_t session = 0;
  std::uint64_t heartbeat_seq = 0;
  std::uint64_t event_seq = 0;
  MonoTime started{};
  MonoTime next_spat{};
  std::uint32_t map_revision = 0;
  /// (intersection id, MAP lane id) -> the map's lane.
  std::map<std::pair<std::uint32_t, std::uint32_t>, LaneId> map_lanes;

  // DDS. Readers' listeners queue samples; the loop takes them.
  std::unique_ptr<dds::Participant> participant;
  std::unique_ptr<dds::Writer<msg::Spat>> spat_writer;
  std::unique_ptr<dds::Writer<msg::MapData>> map_writer;
  std::unique_ptr<dds::Writer<msg::SignRegistry>> signs_writer;
  std::unique_ptr<dds::Writer<msg::FleetState>> fleet_writer;
  std::unique_ptr<dds::Writer<msg::Event>> event_writer;
  std::unique_ptr<dds::Writer<msg::Heartbeat>> heartbeat_writer;
  std::unique_ptr<dds::Writer<msg::SignalRequestStatus>> request_status_writer;
  std::unique_ptr<dds::Writer<msg::OperatorReply>> reply_writer;
  std::unique_ptr<dds::Reader<msg::OperatorRequest>> operator_reader;
  std::unique_ptr<dds::Reader<msg::SignalRequest>> request_reader;
  std::unique_ptr<dds::Reader<msg::DeviceStatus>> device_reader;
  std::vector<std::unique_ptr<dds::Reader<msg::Point>>> ips_readers;
  std::map<VehicleId, std::pair<Eigen::Vector2d, double>> last_ips;  ///< position, yaw

  void Emit(Severity severity, std::string_view code, const std::string& message,
            IntersectionId intersection = IntersectionId(0), std::string_view device = "",
            std::string_view actor = "scm", bool active = false);
  void LoadConfiguration();
  void SetUpCity(const ClockReading& now, bool restore);
  void PublishMapAndSigns(const ClockReading& now);
  void SaveState(Runtime& x);
  void Supervise(const ClockReading& now);
  void RunControllers(const ClockReading& now);
  void PublishSpat(const ClockReading& now);
  void PublishHeartbeat(const ClockReading& now, std::uint8_t state);
  void HandleOperator(const ClockReading& now);
  void HandleSignalRequests(const ClockReading& now);
  void Reply(const msg::OperatorRequest& request, const OperatorResult& result,
             const ClockReading& now);
  OperatorResult Execute(const OperatorCommand& command, const ClockReading& now);
  Runtime* FindIntersection(const std::string& name);
  std::string Describe(const Runtime& x) const;
};

void Scm::Impl::Emit(Severity severity, std::string_view code, const std::string& message,
                     IntersectionId intersection, std::string_view device, std::string_view actor,
                     bool active) {
  const Time now = clock.Now();
  EventRecord record;
  record.time = now;
  record.severity = severity;
  record.source = "scm";
  record.code = std::string(code);
  record.message = message;
  record.intersection = intersection;
  record.device_id = std::string(device);
  record.actor = std::string(actor);
  record.active = active;
  try {
    record.id = store.AppendEvent(record);
  } catch (const std::exception& e) {
    spdlog::error("event log: cannot store event {}: {}", code, e.what());
  }
  const auto level = severity >= Severity::kAlarm     ? spdlog::level::err
                     : severity == Severity::kWarning ? spdlog::level::warn
                                                      : spdlog::level::info;
  spdlog::log(level, "event {} [{}] {}{}", code, ToString(severity), message,
              actor == "scm" ? "" : fmt::format(" (by {})", actor));
  dds::Message<msg::Event> m;
  m->header.stamp = dds::ToMsg(now);
  m->event_id = ++event_seq;
  m->severity = static_cast<std::uint8_t>(severity);
  dds::SetString(m->source, "scm");
  dds::SetString(m->code, code);
  dds::SetString(m->message, message);
  m->intersection_id = intersection.value();
  dds::SetString(m->device_id, device);
  m->active = active;
  if (event_writer) event_writer->Write(m);
}

void Scm::Impl::LoadConfiguration() {
  // The file, unless an operator applied a configuration since the file was last started
  // with unchanged: then the applied one (it is what was running).
  const std::string text = config::internal::ReadFile(options.config_path);
  const std::string hash = ContentHash(text);
  const auto history = store.ConfigHistory(1000);  // newest first
  std::optional<std::int64_t> applied;
  for (const auto& h : history) {
    if (h.applied_by == "scm") {
      if (h.hash == hash && applied) {
        const auto cfg = store.ConfigById(*applied);
        city = std::make_unique<City>(
            LoadCityString(cfg->yaml, cfg->path, std::filesystem::path(cfg->path).parent_path()));
        city->config_path = cfg->path;
        spdlog::info("using the configuration applied by {} (the file {} is unchanged since)",
                     cfg->applied_by, options.config_path.string());
        return;
      }
      break;
    }
    if (!applied) applied = h.id;
  }
  city = std::make_unique<City>(LoadCity(options.config_path));
  store.SaveAppliedConfig(options.config_path.string(), text, "scm", clock.Now());
}

void Scm::Impl::SetUpCity(const ClockReading& now, bool restore) {
  std::map<IntersectionId, IntersectionStateRecord> saved;
  if (restore) {
    for (const auto& s : store.LoadIntersectionStates()) saved[s.intersection] = s;
  }
  xs.clear();
  heads.clear();
  head_index.clear();
  fleet = std::make_unique<FleetRegistry>(
      city->map, FleetRegistryParams{city->fleet_staleness, 0.05, kPi / 3});
  for (const auto& model : city->intersections) {
    Runtime x;
    x.model = &model;
    Mode mode = Mode::kAuto;
    std::optional<std::size_t> plan;
    if (const auto it = saved.find(model.id); it != saved.end()) {
      mode = ModeFromString(it->second.mode).value_or(Mode::kAuto);
      if (it->second.operator_chosen) plan = model.PlanIndex(it->second.plan);
      spdlog::info("{}: restoring mode {} and plan {}", model.name, ToString(mode),
                   plan ? model.plans[*plan].name : std::string("(schedule)"));
    }
    x.controller.emplace(model, now.mono, mode, plan);
    x.monitor.emplace(model, now.mono);
    x.last_aspects = x.controller->aspects();
    x.saved_mode = std::string(ToString(mode));
    x.saved_plan = plan ? model.plans[*plan].name : "auto";
    for (std::size_t g = 0; g < model.groups.size(); ++g) {
      for (SignalHeadId h : model.groups[g].heads) {
        Head head;
        head.id = h;
        head.intersection = xs.size();
        head.group = g;
        head.name = SignalHeadName(h);
        head.writer =
            std::make_unique<dds::Writer<msg::Int32>>(*participant, dds::topics::SignalCommand(h));
        head_index[h] = heads.size();
        x.heads.push_back(heads.size());
        heads.push_back(std::move(head));
      }
    }
    xs.push_back(std::move(x));
  }
  ips_readers.clear();
  for (const auto& name : city->config.fleet.vehicles) {
    const VehicleId v = ParseVehicleName(name);
    auto reader = std::make_unique<dds::Reader<msg::Point>>(*participant, dds::topics::Ips(v));
    ips_readers.push_back(std::move(reader));
  }
  PublishMapAndSigns(now);
}

void Scm::Impl::PublishMapAndSigns(const ClockReading& now) {
  ++map_revision;
  SignalGroupAssignment groups;
  for (const auto& model : city->intersections) {
    auto& list = groups[model.id];
    for (const auto& g : model.groups) list.push_back({g.id, g.name, g.movements, g.heads});
  }
  auto map = BuildMapData(city->map, city->config.name, groups, map_revision);
  // V2I requests name lanes by their MAP ids: remember which map lane each one is.
  std::map<std::string, LaneId> by_name;
  for (const auto& lane : city->map.lanes) by_name.emplace(lane.name, lane.id);
  map_lanes.clear();
  for (const auto& x : dds::Elements(map->intersections)) {
    for (const auto& lane : dds::Elements(x.lanes)) {
      const auto it = by_name.find(lane.map_lane_id ? lane.map_lane_id : "");
      if (it != by_name.end())
        map_lanes.insert_or_assign({x.intersection_id, lane.lane_id}, it->second);
    }
  }
  map->header.stamp = dds::ToMsg(now.wire);
  map_writer->Write(map);
  auto signs = BuildSignRegistry(city->map, city->config.name, map_revision);
  signs->header.stamp = dds::ToMsg(now.wire);
  signs_writer->Write(signs);
}

void Scm::Impl::SaveState(Runtime& x) {
  const auto& c = *x.controller;
  const std::string mode(ToString(c.requested_mode()));
  const std::string plan = c.operator_plan() ? x.model->plans[*c.operator_plan()].name : "auto";
  if (mode == x.saved_mode && plan == x.saved_plan) return;
  try {
    store.SaveIntersectionState({x.model->id, mode, plan, true, clock.Now()});
    x.saved_mode = mode;
    x.saved_plan = plan;
  } catch (const std::exception& e) {
    spdlog::error("cannot save the state of {}: {}", x.model->name, e.what());
  }
}

void Scm::Impl::Supervise(const ClockReading& now) {
  // Device status from the lights (and the infrastructure's own monitors).
  for (auto& m : device_reader->TakeAll()) {
    const std::string id = m->device_id ? m->device_id : "";
    if (id.starts_with("mmu_")) {
      for (auto& x : xs) {
        if (id == "mmu_" + x.model->name &&
            m->health == autodrive_msgs_msg_DeviceStatus_Constants_FAULT &&
            !x.controller->latched()) {
          x.fault = "the infrastructure's conflict monitor latched flash";
          x.controller->FailSafe(now.mono, x.fault);
          Emit(Severity::kCritical, "mmu_flash",
               fmt::format("{}: the infrastructure's conflict monitor latched flash: {}",
                           x.model->name, m->detail ? m->detail : ""),
               x.model->id, id, "scm", true);
        }
      }
      continue;
    }
    SignalHeadId head_id(0);
    try {
      head_id = ParseSignalHeadName(id);
    } catch (const InputError&) {
      continue;  // another kind of device
    }
    const auto it = head_index.find(head_id);
    if (it == head_index.end()) continue;
    Head& h = heads[it->second];
    if (!h.seen) spdlog::info("{} reports ({})", h.name, m->detail ? m->detail : "");
    h.seen = true;
    h.last_status = now.mono;
    h.health = m->health;
    h.mode = m->mode;
    h.displayed = AspectFromWire(m->displayed_state);
    h.detail = m->detail ? m->detail : "";
    if (h.lost) {
      h.lost = false;
      Emit(Severity::kInfo, "device_back", fmt::format("{} reports again", h.name),
           xs[h.intersection].model->id, h.name, "scm", false);
    }
  }
  // Lost, faulty and mismatched lights put their intersection in fail-safe flash.
  for (auto& x : xs) {
    bool all_seen = true;
    std::vector<std::string> lost;
    for (std::size_t hi : x.heads) {
      Head& h = heads[hi];
      if (!h.seen) {
        all_seen = false;
        continue;
      }
      if (now.mono - h.last_status > city->device_timeout) {
        if (!h.lost) {
          h.lost = true;
          Emit(Severity::kAlarm, "device_lost",
               fmt::format("{} lost: no status for {:.2f} s", h.name,
                           ToSeconds(now.mono - h.last_status)),
               x.model->id, h.name, "scm", true);
        }
        lost.push_back(h.name);
      }
      const bool fault = h.health == autodrive_msgs_msg_DeviceStatus_Constants_FAULT ||
                         h.health == autodrive_msgs_msg_DeviceStatus_Constants_OFFLINE;
      if (fault && !h.faulty && !h.lost) {
        h.faulty = true;
        Emit(Severity::kAlarm, "device_fault",
             fmt::format("{} reports a fault: {}", h.name, h.detail), x.model->id, h.name, "scm",
             true);
        if (!x.controller->latched()) {
          x.fault = fmt::format("{} has a fault", h.name);
          x.controller->FailSafe(now.mono, x.fault);
        }
      } else if (!fault && h.faulty) {
        h.faulty = false;
      }
      // What it shows against what it was told, once it has had time to follow.
      if (h.commanded && h.displayed && !h.lost && *h.displayed != *h.commanded &&
          !x.controller->latched()) {
        if (!h.mismatch_since) h.mismatch_since = now.mono;
        if (now.mono - *h.mismatch_since > city->device_mismatch) {
          x.fault = fmt::format("{} shows {} but was commanded {}", h.name, ToString(*h.displayed),
                                ToString(*h.commanded));
          x.controller->FailSafe(now.mono, x.fault);
          Emit(Severity::kAlarm, "device_mismatch", x.fault, x.model->id, h.name, "scm", true);
        }
      } else {
        h.mismatch_since.reset();
      }
    }
    x.controller->SetDevicesReady(all_seen || !city->config.devices.wait_for_lights);
    if (!lost.empty() && !x.controller->latched()) {
      std::string names;
      for (const auto& n : lost) names += (names.empty() ? "" : ", ") + n;
      x.fault = "devices lost: " + names;
      x.controller->FailSafe(now.mono, x.fault);
      Emit(Severity::kCritical, "failsafe_flash",
           fmt::format("{} in fail-safe flash: {}", x.model->name, x.fault), x.model->id, "", "scm",
           true);
    }
  }
}

void Scm::Impl::RunControllers(const ClockReading& now) {
  const DayClock day = DayAt(now.wire);
  for (auto& x : xs) {
    auto& c = *x.controller;
    std::vector<bool> calls(x.model->groups.size(), false);
    for (const auto& d : c.plan().detectors) {
      if (!calls[d.group] &&
          fleet->Occupied({d.lane, d.from_stop_line_m, d.to_stop_line_m}, now.wire)) {
        calls[d.group] = true;
      }
    }
    const bool was_latched = c.latched();
    c.Step(now.mono, calls, day);
    auto aspects = c.aspects();
    if (const auto v = x.monitor->Check(now.mono, aspects)) {
      ++counters.monitor_violations;
      c.FailSafe(now.mono, "conflict monitor: " + v->message);
      aspects = c.aspects();
      Emit(Severity::kCritical, "monitor_" + v->rule, v->message, x.model->id, "", "scm", true);
    }
    x.monitor->Record(now.mono, aspects);
    if (c.latched() && !was_latched) {
      spdlog::error("{}: fail-safe flash latched: {}", x.model->name, c.latch_reason());
    }
    if (aspects != x.last_aspects) {
      ++x.revision;
      x.last_aspects = aspects;
    }
    for (std::size_t hi : x.heads) {
      Head& h = heads[hi];
      const Aspect a = aspects[h.group];
      if (h.commanded != a) {
        h.commanded = a;
        h.commanded_at = now.mono;
        h.mismatch_since.reset();
        msg::Int32 m{ToWire(a)};
        h.writer->Write(m);
      }
    }
    for (const auto& u : c.TakeRequestUpdates()) {
      dds::Message<msg::SignalRequestStatus> m;
      m->header.stamp = dds::ToMsg(now.wire);
      dds::SetString(m->vehicle_id, u.vehicle);
      m->request_id = u.request_id;
      m->intersection_id = x.model->id.value();
      m->status = u.status;
      m->signal_group = u.group ? x.model->groups[*u.group].id.value() : 0;
      dds::SetString(m->reason, u.reason);
      request_status_writer->Write(m);
    }
  }
}

void Scm::Impl::PublishSpat(const ClockReading& now) {
  dds::Message<msg::Spat> m;
  m->header.stamp = dds::ToMsg(now.wire);
  dds::SetString(m->header.frame_id, "map");
  dds::SetString(m->city, city->config.name);
  dds::ResizeSequence(m->intersections, static_cast<std::uint32_t>(xs.size()));
  auto states = dds::Elements(m->intersections);
  for (std::size_t i = 0; i < xs.size(); ++i) {
    const auto& x = xs[i];
    const auto& c = *x.controller;
    auto& s = states[i];
    s.intersection_id = x.model->id.value();
    dds::SetString(s.name, x.model->name);
    s.revision = x.revision;
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
    s.status = status;
    s.timestamp = dds::ToMsg(now.wire);
    dds::SetString(s.plan, c.plan().name);
    const auto signals = c.Signals(now.mono);
    dds::ResizeSequence(s.signal_groups, static_cast<std::uint32_t>(signals.size()));
    auto gs = dds::Elements(s.signal_groups);
    for (std::size_t g = 0; g < signals.size(); ++g) {
      const auto& sig = signals[g];
      auto& o = gs[g];
      o.signal_group = x.model->groups[g].id.value();
      o.event_state = EventState(sig.aspect);
      o.min_end_time = dds::ToMsg(now.ToWire(sig.min_end));
      o.has_max_end_time = sig.max_end.has_value();
      if (sig.max_end) o.max_end_time = dds::ToMsg(now.ToWire(*sig.max_end));
      o.has_likely_time = sig.likely_end.has_value();
      if (sig.likely_end) o.likely_time = dds::ToMsg(now.ToWire(*sig.likely_end));
      o.likely_time_confidence = sig.likely_confidence;
      o.has_next_time = sig.next_green.has_value();
      if (sig.next_green) o.next_time = dds::ToMsg(now.ToWire(*sig.next_green));
    }
  }
  spat_writer->Write(m);
  ++counters.spat_published;
  fleet->DropStale(now.wire);
  auto fleet_state = fleet->State(now.wire);
  fleet_writer->Write(fleet_state);
}

void Scm::Impl::PublishHeartbeat(const ClockReading& now, std::uint8_t state) {
  dds::Message<msg::Heartbeat> m;
  m->header.stamp = dds::ToMsg(now.wire);
  dds::SetString(m->sender, "scm");
  m->session_id = session;
  m->sequence_number = ++heartbeat_seq;
  m->period_ms = static_cast<std::uint32_t>(
      std::chrono::duration_cast<milliseconds>(options.spat_period).count());
  m->state = state;
  heartbeat_writer->Write(m);
}

Runtime* Scm::Impl::FindIntersection(const std::string& name) {
  for (auto& x : xs) {
    if (x.model->name == name || std::to_string(x.model->id.value()) == name) return &x;
  }
  return nullptr;
}

std::string Scm::Impl::Describe(const Runtime& x) const {
  const auto& c = *x.controller;
  return fmt::format("id={} mode={} requested={} plan={}{} stage={}{}", x.model->id.value(),
                     ToString(c.effective_mode()), ToString(c.requested_mode()), c.plan().name,
                     c.operator_plan() ? " (operator)" : " (schedule)", ToString(c.stage()),
                     c.latched() ? " latched=\"" + c.latch_reason() + "\"" : "");
}

OperatorResult Scm::Impl::Execute(const OperatorCommand& cmd, const ClockReading& now) {
  using R = OperatorResult;
  auto need_x = [&](Runtime*& x) -> std::optional<R> {
    if (cmd.intersection.empty()) return R::Invalid(cmd.name + " needs an intersection");
    x = FindIntersection(cmd.intersection);
    if (x == nullptr) {
      std::string names;
      for (const auto& r : xs) names += (names.empty() ? "" : ", ") + r.model->name;
      return R::Invalid(
          fmt::format("unknown intersection \"{}\" (signalised: {})", cmd.intersection, names));
    }
    return std::nullopt;
  };
  Runtime* x = nullptr;
  if (cmd.name == "status") {
    R r = R::Ok(fmt::format("city {}: {} signalised intersections, {} lights, up {:.0f} s",
                            city->config.name, xs.size(), heads.size(),
                            ToSeconds(now.mono - started)));
    r.values.emplace_back("city", city->config.name);
    r.values.emplace_back("config", city->config_path.string());
    r.values.emplace_back("clock", ToString(clock.kind()));
    r.values.emplace_back("uptime_s", fmt::format("{:.1f}", ToSeconds(now.mono - started)));
    std::size_t lost = 0;
    for (const auto& h : heads) lost += h.lost ? 1 : 0;
    r.values.emplace_back("lights", std::to_string(heads.size()));
    r.values.emplace_back("lights_lost", std::to_string(lost));
    r.values.emplace_back("events", std::to_string(store.EventCount()));
    r.values.emplace_back("spat_published", std::to_string(counters.spat_published));
    r.values.emplace_back("malformed_requests", std::to_string(counters.malformed_requests));
    return r;
  }
  if (cmd.name == "intersections") {
    R r = R::Ok(fmt::format("{} signalised intersections", xs.size()));
    for (const auto& rx : xs) r.values.emplace_back(rx.model->name, Describe(rx));
    return r;
  }
  if (cmd.name == "show") {
    if (auto bad = need_x(x)) return *bad;
    R r = R::Ok(x->model->name + ": " + Describe(*x));
    const auto signals = x->controller->Signals(now.mono);
    for (std::size_t g = 0; g < signals.size(); ++g) {
      const auto& s = signals[g];
      std::string heads_text;
      for (auto h : x->model->groups[g].heads) {
        const Head& head = heads[head_index.at(h)];
        heads_text += fmt::format(" {}={}{}", head.name,
                                  head.displayed ? ToString(*head.displayed) : "unseen",
                                  head.lost ? "(lost)" : "");
      }
      r.values.emplace_back(
          fmt::format("group {} {}", x->model->groups[g].id.value(), x->model->groups[g].name),
          fmt::format("{} since {:.1f} s, min end in {:.1f} s{};{}", ToString(s.aspect),
                      ToSeconds(now.mono - s.since), ToSeconds(s.min_end - now.mono),
                      s.likely_end
                          ? fmt::format(", likely in {:.1f} s", ToSeconds(*s.likely_end - now.mono))
                          : "",
                      heads_text));
    }
    return r;
  }
  if (cmd.name == "mode" || cmd.name == "plan" || cmd.name == "advance" || cmd.name == "reset") {
    if (auto bad = need_x(x)) return *bad;
    auto& c = *x->controller;
    CommandResult res;
    if (cmd.name == "mode") {
      const auto mode = ModeFromString(cmd.Arg("mode"));
      if (!mode) {
        return R::Invalid(fmt::format(
            "unknown mode \"{}\" (auto, fixed, actuated, manual, flash, dark)", cmd.Arg("mode")));
      }
      res = c.SetMode(*mode, now.mono);
    } else if (cmd.name == "plan") {
      if (cmd.Arg("plan").empty()) return R::Invalid("plan needs a plan name (or auto)");
      res = c.SetPlan(cmd.Arg("plan"), now.mono);
    } else if (cmd.name == "advance") {
      res = c.Advance(now.mono);
    } else {
      // A reset does not clear a cause that is still there.
      for (std::size_t hi : x->heads) {
        const Head& h = heads[hi];
        if (h.lost) return R::Rejected(fmt::format("{} is still lost; reset refused", h.name));
        if (h.faulty)
          return R::Rejected(
              fmt::format("{} still reports a fault ({}); reset refused", h.name, h.detail));
      }
      const std::string reason = c.latch_reason();
      res = c.Reset(now.mono);
      if (res.ok) {
        x->fault.clear();
        for (std::size_t hi : x->heads) heads[hi].mismatch_since.reset();
        Emit(Severity::kInfo, "failsafe_reset",
             fmt::format("{}: fail-safe flash reset by an operator (was: {})", x->model->name,
                         reason),
             x->model->id, "", cmd.client, false);
      }
    }
    if (!res.ok) return R::Rejected(res.message);
    Emit(Severity::kInfo, "operator_" + cmd.name,
         fmt::format("{} {}: {}", cmd.name, x->model->name, res.message), x->model->id, "",
         cmd.client, false);
    SaveState(*x);
    return R::Ok(res.message);
  }
  if (cmd.name == "events") {
    EventQuery q;
    q.limit = 100;
    if (!cmd.Arg("since").empty()) {
      try {
        q.since = TimeFromSeconds(std::stod(cmd.Arg("since")));
      } catch (const std::exception&) {
        return R::Invalid(
            fmt::format("since must be seconds since the epoch, got \"{}\"", cmd.Arg("since")));
      }
    }
    if (!cmd.Arg("limit").empty()) {
      try {
        q.limit = static_cast<std::size_t>(std::stoul(cmd.Arg("limit")));
      } catch (const std::exception&) {
        return R::Invalid(fmt::format("limit must be a number, got \"{}\"", cmd.Arg("limit")));
      }
      if (q.limit == 0 || q.limit > 10000) return R::Invalid("limit must be in 1..10000");
    }
    const auto events = store.Events(q);
    R r = R::Ok(fmt::format("{} events", events.size()));
    for (const auto& e : events) {
      r.values.emplace_back(
          std::to_string(e.id),
          fmt::format("{:.3f} {} {} {}{}{}", ToSeconds(e.time), ToString(e.severity), e.code,
                      e.message, e.actor.empty() || e.actor == "scm" ? "" : " (by " + e.actor + ")",
                      e.active ? " [active]" : ""));
    }
    return r;
  }
  if (cmd.name == "config_validate" || cmd.name == "config_apply") {
    const std::string path = cmd.Arg("path").empty() ? "<operator>" : cmd.Arg("path");
    std::unique_ptr<City> next;
    try {
      next = std::make_unique<City>(
          LoadCityString(cmd.Arg("yaml"), path, std::filesystem::path(path).parent_path()));
      next->config_path = path;
    } catch (const InputError& e) {
      return R::Rejected(e.what());
    }
    if (cmd.name == "config_validate") {
      return R::Ok(fmt::format("{} is valid: city {}, {} signalised intersections", path,
                               next->config.name, next->intersections.size()));
    }
    store.SaveAppliedConfig(path, cmd.Arg("yaml"), cmd.client, now.wire);
    Emit(Severity::kWarning, "config_applied",
         fmt::format("configuration {} applied (city {}); every intersection restarts through "
                     "the start-up sequence",
                     path, next->config.name),
         IntersectionId(0), "", cmd.client, false);
    city = std::move(next);
    SetUpCity(now, true);
    return R::Ok(
        fmt::format("applied {}: city {}, {} signalised intersections; restarting them "
                    "through flash and all red",
                    path, city->config.name, xs.size()));
  }
  return R::Invalid(fmt::format("unknown command \"{}\" ({})", cmd.name, OperatorCommandNames()));
}

void Scm::Impl::Reply(const msg::OperatorRequest& request, const OperatorResult& result,
                      const ClockReading& now) {
  dds::Message<msg::OperatorReply> m;
  m->header.stamp = dds::ToMsg(now.wire);
  dds::SetString(m->client_id, request.client_id ? request.client_id : "");
  m->request_id = request.request_id;
  m->result = result.result;
  dds::SetString(m->message, result.message);
  dds::ResizeSequence(m->values, static_cast<std::uint32_t>(result.values.size()));
  auto values = dds::Elements(m->values);
  for (std::size_t i = 0; i < result.values.size(); ++i) {
    dds::SetString(values[i].key, result.values[i].first);
    dds::SetString(values[i].value, result.values[i].second);
  }
  reply_writer->Write(m);
}

void Scm::Impl::HandleOperator(const ClockReading& now) {
  for (auto& m : operator_reader->TakeAll()) {
    ++counters.operator_requests;
    OperatorResult result;
    try {
      const OperatorCommand cmd = ParseOperatorRequest(*m);
      result = Execute(cmd, now);
    } catch (const InputError& e) {
      ++counters.malformed_requests;
      spdlog::warn("malformed operator request from {}: {}", m->client_id ? m->client_id : "?",
                   e.what());
      result = OperatorResult::Invalid(e.what());
    } catch (const std::exception& e) {
      spdlog::error("operator request failed: {}", e.what());
      result = OperatorResult::Failed(e.what());
    }
    Reply(*m, result, now);
  }
}

void Scm::Impl::HandleSignalRequests(const ClockReading& now) {
  for (auto& m : request_reader->TakeAll()) {
    ++counters.signal_requests;
    const std::string vehicle = m->vehicle_id ? m->vehicle_id : "";
    RequestUpdate u{
        vehicle,      m->request_id, autodrive_msgs_msg_SignalRequestStatus_Constants_REJECTED,
        std::nullopt, std::nullopt,  ""};
    Runtime* x = nullptr;
    for (auto& r : xs) {
      if (r.model->id.value() == m->intersection_id) x = &r;
    }
    if (x == nullptr) {
      u.reason = fmt::format("intersection {} is not signalised here", m->intersection_id);
    } else if (m->request_type == autodrive_msgs_msg_SignalRequest_Constants_CANCEL) {
      u = x->controller->Cancel(vehicle, m->request_id, now.mono);
    } else {
      // The movement from the MAP's in lane to its out lane (any, when out is 0).
      std::optional<std::size_t> group;
      const auto in = map_lanes.find({m->intersection_id, m->in_lane_id});
      const auto out = map_lanes.find({m->intersection_id, m->out_lane_id});
      for (MovementId mv : city->map.intersection(x->model->id).movements) {
        const auto& move = city->map.movement(mv);
        if (in != map_lanes.end() && move.from == in->second &&
            (m->out_lane_id == 0 || (out != map_lanes.end() && move.to == out->second))) {
          group = x->model->GroupOfMovement(mv);
          break;
        }
      }
      const bool emergency =
          m->vehicle_role == autodrive_msgs_msg_SignalRequest_Constants_EMERGENCY;
      if (!group) {
        u.reason = fmt::format("no movement from lane {} to lane {} at {}", m->in_lane_id,
                               m->out_lane_id, x->model->name);
      } else if (m->request_type == autodrive_msgs_msg_SignalRequest_Constants_PREEMPTION &&
                 !emergency) {
        u.reason = "pre-emption is for emergency vehicles";
      } else if (m->request_type != autodrive_msgs_msg_SignalRequest_Constants_PRIORITY &&
                 m->request_type != autodrive_msgs_msg_SignalRequest_Constants_PREEMPTION &&
                 m->request_type != autodrive_msgs_msg_SignalRequest_Constants_UPDATE) {
        ++counters.malformed_requests;
        u.reason = fmt::format("unknown request type {}", m->request_type);
      } else {
        MonoTime eta = now.FromWire(dds::FromMsg(m->eta));
        if (eta < now.mono) eta = now.mono;
        const Duration d =
            std::clamp(dds::FromMsg(m->duration), Duration{0}, Duration(std::chrono::minutes(5)));
        ServiceRequest r{
            vehicle,
            m->request_id,
            m->request_type == autodrive_msgs_msg_SignalRequest_Constants_PREEMPTION ||
                (m->request_type == autodrive_msgs_msg_SignalRequest_Constants_UPDATE && emergency),
            *group,
            eta + d,
            d};
        u = x->controller->Request(r, now.mono);
      }
    }
    Emit(Severity::kInfo, "signal_request",
         fmt::format("{} request {} at intersection {}: status {} {}", vehicle, m->request_id,
                     m->intersection_id, u.status, u.reason),
         IntersectionId(m->intersection_id), "", vehicle, false);
    dds::Message<msg::SignalRequestStatus> s;
    s->header.stamp = dds::ToMsg(now.wire);
    dds::SetString(s->vehicle_id, vehicle);
    s->request_id = m->request_id;
    s->intersection_id = m->intersection_id;
    s->status = u.status;
    s->signal_group = (x && u.group) ? x->model->groups[*u.group].id.value() : 0;
    s->has_expected_green = u.expected_green.has_value();
    if (u.expected_green) s->expected_green = dds::ToMsg(now.ToWire(*u.expected_green));
    dds::SetString(s->reason, u.reason);
    request_status_writer->Write(s);
  }
}

Scm::Scm(const ScmOptions& options, Clock& clock) : impl_(std::make_unique<Impl>(options, clock)) {
  auto& d = *impl_;
  d.session = std::random_device{}();
  d.session = (d.session << 32) ^ static_cast<std::uint64_t>(::getpid());
  d.LoadConfiguration();
  d.participant = std::make_unique<dds::Participant>(options.participant);
  namespace t = dds::topics;
  d.spat_writer = std::make_unique<dds::Writer<msg::Spat>>(*d.participant, t::Spat());
  d.map_writer = std::make_unique<dds::Writer<msg::MapData>>(*d.participant, t::Map());
  d.signs_writer = std::make_unique<dds::Writer<msg::SignRegistry>>(*d.participant, t::Signs());
  d.fleet_writer = std::make_unique<dds::Writer<msg::FleetState>>(*d.participant, t::Fleet());
  d.event_writer = std::make_unique<dds::Writer<msg::Event>>(*d.participant, t::Events());
  d.heartbeat_writer =
      std::make_unique<dds::Writer<msg::Heartbeat>>(*d.participant, t::Heartbeat());
  d.request_status_writer = std::make_unique<dds::Writer<msg::SignalRequestStatus>>(
      *d.participant, t::SignalRequestStatus());
  d.reply_writer =
      std::make_unique<dds::Writer<msg::OperatorReply>>(*d.participant, t::OperatorReplies());
  d.operator_reader =
      std::make_unique<dds::Reader<msg::OperatorRequest>>(*d.participant, t::OperatorRequests());
  d.request_reader =
      std::make_unique<dds::Reader<msg::SignalRequest>>(*d.participant, t::SignalRequests());
  // Every light has its own keep-last-1 writer on this keyless topic: the reader keeps more, or
  // one light's status would push out another's between two ticks.
  const auto devices = t::Devices();
  d.device_reader = std::make_unique<dds::Reader<msg::DeviceStatus>>(*d.participant, devices.name,
                                                                     dds::Qos::LatchedState(1024));
  const ClockReading now = clock.Read();
  d.started = now.mono;
  d.next_spat = now.mono;
  d.SetUpCity(now, true);
  d.Emit(Severity::kInfo, "scm_started",
         fmt::format("SCM started: city {}, {} signalised intersections, {} lights, {} clock",
                     d.city->config.name, d.xs.size(), d.heads.size(), ToString(clock.kind())));
}

Scm::~Scm() = default;

const City& Scm::city() const { return *impl_->city; }
ScmCounters Scm::counters() const { return impl_->counters; }

void Scm::Tick(const ClockReading& now) {
  auto& d = *impl_;
  ++d.counters.ticks;
  // Vehicle positions from the devkit's ips topics (heading from the motion).
  for (std::size_t i = 0; i < d.ips_readers.size(); ++i) {
    const VehicleId v = ParseVehicleName(d.city->config.fleet.vehicles[i]);
    for (auto& p : d.ips_readers[i]->TakeAll()) {
      if (!std::isfinite(p->x) || !std::isfinite(p->y)) {
        ++d.counters.malformed_requests;
        continue;
      }
      const Eigen::Vector2d pos(p->x, p->y);
      auto& last = d.last_ips[v];
      if ((pos - last.first).norm() > 0.01) {
        last.second = std::atan2(pos.y() - last.first.y(), pos.x() - last.first.x());
      }
      last.first = pos;
      VehicleObservation o;
      o.vehicle = v;
      o.source = PoseSource::kSimGroundTruth;
      o.observed = now.wire;
      o.X_MV = RigidTransform2(pos, last.second).ToRigidTransform3();
      try {
        d.fleet->Observe(o);
      } catch (const InputError& e) {
        spdlog::warn("bad observation of {}: {}", VehicleName(v), e.what());
      }
    }
  }
  d.HandleOperator(now);
  d.HandleSignalRequests(now);
  d.Supervise(now);
  d.RunControllers(now);
  if (now.mono >= d.next_spat) {
    d.PublishSpat(now);
    d.PublishHeartbeat(now, autodrive_msgs_msg_Heartbeat_Constants_RUNNING);
    d.next_spat += d.options.spat_period;
    if (d.next_spat < now.mono) d.next_spat = now.mono + d.options.spat_period;
  }
}

void Scm::Run() {
  auto& d = *impl_;
  Ticker ticker(d.clock, d.options.tick);
  while (!d.stop.load() && ticker.WaitNext()) {
    try {
      Tick(d.clock.Read());
    } catch (const std::exception& e) {
      // A bug or a broken database must not stop the signals: log, count, carry on.
      spdlog::error("tick failed: {}", e.what());
    }
  }
  PublishStopping();
}

void Scm::PublishStopping() {
  auto& d = *impl_;
  const ClockReading now = d.clock.Read();
  d.PublishHeartbeat(now, autodrive_msgs_msg_Heartbeat_Constants_STOPPING);
  d.Emit(Severity::kWarning, "scm_stopped", "SCM stopping: the lights flash on their own");
}

void Scm::Stop() {
  impl_->stop.store(true);
  impl_->clock.Interrupt();
}

}  // namespace autodrive::scm
