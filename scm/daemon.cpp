#include "scm/daemon.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <ctime>
#include <random>

#include "autodrive_msgs/msg/DeviceStatus.h"

#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/dds/discovery.h"
#include "common/dds/identity.h"
#include "common/dds/loop_waitset.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/error.h"
#include "common/systemd.h"
#include "scm/city_bundle.h"
#include "scm/config_loader.h"
#include "scm/io/device_inbox.h"
#include "scm/io/publishers.h"
#include "scm/io/reply_outbox.h"
#include "scm/io/v2i.h"
#include "scm/operator/control_plane.h"
#include "scm/operator/operator_commands.h"

namespace autodrive::scm {

namespace {

using std::chrono::milliseconds;

/// The local day at system time `now` (the SCM host's TZ).
DayClock DayAt(Time now) {
  const auto since_epoch = now.time_since_epoch();
  const std::time_t t = std::chrono::duration_cast<std::chrono::seconds>(since_epoch).count();
  std::tm tm{};
  localtime_r(&t, &tm);
  const Duration sub = since_epoch - std::chrono::seconds(t);
  return DayClock::At(std::chrono::seconds(tm.tm_hour * 3600 + tm.tm_min * 60 + tm.tm_sec) + sub);
}

// A pass that begins this long after its deadline is a stall of the loop (the tick is 20 ms;
// a busy machine delays a wake-up by a few ms); from kStallEvent on it is also an event.
constexpr Duration kStallThreshold = std::chrono::milliseconds(100);
constexpr Duration kStallEvent = std::chrono::milliseconds(250);
constexpr Duration kStallEventPeriod = std::chrono::minutes(10);
// Topics of operators the city does not allow that are still answered (with a refusal).
constexpr std::size_t kMaxStrangerOperators = 32;

// When a request waits between two slices of SPaT (ScmOptions::spat_slice), up to this many are
// answered first.
constexpr std::size_t kRequestsBeforeSpat = 4;

constexpr std::string_view kOperatorTopicPrefix = "rt/autodrive/scm/operator/";
constexpr std::string_view kOperatorTopicSuffix = "/request";

ControlPlaneParams ControlParamsOf(const City& city, const std::vector<std::string>& extra) {
  ControlPlaneParams p;
  p.operators = AllowedOperators(city.config, extra);
  p.rate_per_s = city.config.operators.rate_per_s;
  p.burst = city.config.operators.burst;
  return p;
}

}  // namespace

/// Where the daemon's operator requests come from: the shared read-only topic (no operator) or
/// one operator's topic.
struct OperatorInbox {
  std::string operator_name;
  std::unique_ptr<dds::Reader<msg::OperatorRequest>> reader;
};

struct Scm::Impl final : EventSink, ConfigService {
  Impl(const ScmOptions& o, Clock& c, dds::Participant& p);
  ~Impl() override;

  // EventSink: log, publish, queue for the database.
  void Emit(Event event) override;
  // ConfigService.
  void Validate(std::string yaml, std::string label, Responder respond) override;
  void Apply(std::string yaml, std::string label, std::string by, Responder respond) override;

  std::unique_ptr<City> LoadStartupCity();
  /// What an operator's configuration must satisfy here (`ConfigRefusal` against the running
  /// city and `--operator`), as copies for the loader's thread.
  [[nodiscard]] ConfigLoader::Policy ConfigPolicy() const;
  /// Raises an alarm when the running city allows no operator to change state.
  void WarnIfLockedOut();
  void Install(std::unique_ptr<CityBundle> bundle, const ClockReading& now);
  void OpenInboxes(const City& city);
  void WatchStrangers();
  void NewSession(const ClockReading& now);
  /// Gives supervision the reports the receiving thread took since the last pass.
  void TakeDeviceStatuses();
  /// Notices a pass that starts late (a stall of the loop or the process): logs it and tells
  /// supervision, which then re-checks before it latches anything on the devices' silence.
  void NoteStall(const ClockReading& now);
  /// True once SPaT's deadline has come: requests then wait for the next pass (the waitset
  /// wakes it at once) so that a flood, or a slow machine, never holds SPaT back.
  [[nodiscard]] bool SpatDue() const { return clock.Read().mono >= next_spat; }
  /// Whether one more request may be handled in this pass: before SPaT's deadline, or one of
  /// the few that SPaT's filling gave way to (`PublishSpatUnlessAsked`).
  [[nodiscard]] bool MayHandleRequest() const;
  /// Counts a request handled past SPaT's deadline against those SPaT gave way to.
  void CountRequestPastSpat();
  /// Whether an operator or V2I request is waiting (not taken).
  [[nodiscard]] bool RequestWaiting() const;
  /// Fills SPaT in slices; when a request is waiting between two slices, and SPaT has not
  /// already given way once for this deadline, it stops (returns false) so that the next pass
  /// answers a few requests first and then fills SPaT afresh without stopping. A request thus
  /// waits for a slice, not for the whole city's SPaT. True when SPaT was handed to its sender.
  bool PublishSpatUnlessAsked(const CityBundle& c, const ClockReading& now);
  void HandleOperatorRequests(const ClockReading& now, const DayClock& day);
  void HandleSignalRequests(const ClockReading& now, const DayClock& day);
  void Housekeeping(const ClockReading& now);
  void Pass();
  [[nodiscard]] MonoTime NextDeadline() const;

  ScmOptions options;
  Clock& clock;
  dds::Participant& participant;
  std::uint64_t session = 0;  // heartbeat session id (random per start)
  std::uint64_t clock_session = 0;
  std::atomic<bool> stop{false};
  ClockReading current;  // the reading of the pass under way (event times)
  MapResolution resolution;

  dds::LoopWaitSet waitset;
  std::unique_ptr<Persistence> persistence;
  std::unique_ptr<SignalCommandWriters> signal_writers;  // outlives every city (and the loader)
  std::unique_ptr<ConfigLoader> loader;
  std::unique_ptr<ScmPublishers> publishers;
  std::unique_ptr<ControlPlane> control;
  std::unique_ptr<CityBundle> bundle;
  std::unique_ptr<CityBundle> pending_apply;  // built, being recorded before it is swapped in
  V2iService v2i;
  DaemonFigures figures;
  ScmCounters counters;
  std::uint32_t map_revision = 0;
  std::uint64_t event_seq = 0;

  std::vector<OperatorInbox> inboxes;  // [0]: the shared read-only topic
  std::size_t stranger_inboxes = 0;
  std::unique_ptr<dds::PublicationWatcher> publications;
  std::unique_ptr<dds::Reader<msg::SignalRequest>> signal_requests;
  std::unique_ptr<DeviceStatusInbox> device_statuses;
  std::vector<ReceivedReport> reports;  // drained from device_statuses, reused each pass
  dds::Message<msg::OperatorRequest> request_sample;
  dds::SampleInfo request_info;
  // The participants of the requests' writers (a thousand clients at once fit).
  dds::WriterParticipants requesters{2048};
  std::unique_ptr<ReplyOutbox> replies;
  dds::Message<msg::SignalRequest> signal_sample;

  MonoTime planned_wake{};  // the deadline the loop waits for after a pass (NextDeadline)
  MonoTime last_stall_event{};
  std::uint64_t stalls_unreported = 0;  // long stalls since the last scm_stall event
  std::uint64_t device_malformed_seen = 0;
  MonoTime next_spat{};
  bool spat_gave_way = false;            // SPaT's filling stopped once for this deadline
  std::size_t requests_before_spat = 0;  // requests still allowed past SPaT's deadline
  MonoTime next_tick{};
  MonoTime next_housekeeping{};
  MonoTime next_prune{};
  std::optional<Duration> watchdog;
  std::chrono::steady_clock::time_point next_watchdog{};
};

Scm::Impl::Impl(const ScmOptions& o, Clock& c, dds::Participant& p)
    : options(o), clock(c), participant(p), waitset(p, c) {
  std::random_device entropy;
  session = (static_cast<std::uint64_t>(entropy()) << 32) ^ entropy() ^
            static_cast<std::uint64_t>(::getpid());
  const auto root =
      options.config_root
          ? *options.config_root
          : std::filesystem::absolute(options.config_path).parent_path().parent_path();
  resolution = MapResolution{std::filesystem::absolute(options.config_path).parent_path(), root};
  persistence = std::make_unique<Persistence>(Store(options.db_path), [this] { waitset.Wake(); });
  signal_writers = std::make_unique<SignalCommandWriters>(participant);
  loader = std::make_unique<ConfigLoader>(participant, *signal_writers, persistence->store(),
                                          resolution, [this] { waitset.Wake(); });
  auto city = LoadStartupCity();
  figures.clock = clock.kind();
  publishers = std::make_unique<ScmPublishers>(participant, city->config.name, session);
  control = std::make_unique<ControlPlane>(ControlParamsOf(*city, options.operators));
  replies = std::make_unique<ReplyOutbox>(participant);
  signal_requests =
      std::make_unique<dds::Reader<msg::SignalRequest>>(participant, dds::topics::SignalRequests());
  device_statuses = std::make_unique<DeviceStatusInbox>(participant, clock);
  waitset.Attach(*signal_requests);
  publications = std::make_unique<dds::PublicationWatcher>(participant);
  const ClockReading now = clock.Read();
  current = now;
  clock_session = now.session;
  figures.started = now.mono;
  auto first =
      std::make_unique<CityBundle>(std::move(city), participant, *signal_writers,
                                   persistence->store().LoadIntersectionStates(), ++map_revision);
  Install(std::move(first), now);
  watchdog = systemd::WatchdogPeriod();
  Emit(Event{Severity::kInfo, "scm_started",
             fmt::format("SCM started: city {}, {} signalised intersections, {} lights, {} clock",
                         bundle->city().config.name, bundle->runtime->intersections().size(),
                         bundle->runtime->heads().size(), ToString(clock.kind())),
             IntersectionId(0), "", "scm", false});
  WarnIfLockedOut();
}

Scm::Impl::~Impl() {
  // The loader may be building a bundle on the participant: stop it first.
  loader.reset();
}

std::unique_ptr<City> Scm::Impl::LoadStartupCity() {
  // The file, unless an operator applied a configuration since the file was last started
  // unchanged: then the applied one (it is what was running). Start-up reads are not on the
  // loop yet.
  const std::string text = config::ReadFile(options.config_path);
  const std::string hash = ContentHash(text);
  Store& store = persistence->store();
  const auto history = store.ConfigHistory(1000);  // newest first
  std::optional<std::int64_t> applied;
  for (const auto& h : history) {
    if (h.applied_by == "scm") {
      if (h.hash == hash && applied) {
        const auto cfg = store.ConfigById(*applied);
        auto city = std::make_unique<City>(LoadCityString(cfg->yaml, cfg->path, resolution));
        city->config_path = cfg->path;
        spdlog::info("using the configuration applied by {} (the file {} is unchanged since)",
                     cfg->applied_by, options.config_path.string());
        return city;
      }
      break;
    }
    if (!applied) applied = h.id;
  }
  auto city = std::make_unique<City>(LoadCity(options.config_path));
  store.SaveAppliedConfig(options.config_path.string(), text, "scm", clock.Now());
  return city;
}

ConfigLoader::Policy Scm::Impl::ConfigPolicy() const {
  return [running = bundle->city().config.name, extra = options.operators](const City& next) {
    return ConfigRefusal(next.config, running, extra);
  };
}

void Scm::Impl::WarnIfLockedOut() {
  if (!AllowedOperators(bundle->city().config, options.operators).empty()) return;
  Emit(Event{Severity::kAlarm, "no_operator",
             fmt::format("city {} allows no operator to change state (its file {} lists none under "
                         "operators: allowed:): no mode, plan, reset or configuration can be "
                         "applied. Restart autodrive-scm with --operator NAME to let an operator "
                         "in without editing the file (docs/scm.md, \"Operators\")",
                         bundle->city().config.name, figures.config_path),
             IntersectionId(0), "", "scm", true});
}

void Scm::Impl::OpenInboxes(const City& city) {
  inboxes.clear();
  stranger_inboxes = 0;
  inboxes.push_back(OperatorInbox{"", std::make_unique<dds::Reader<msg::OperatorRequest>>(
                                          participant, dds::topics::OperatorRequests())});
  for (const auto& name : AllowedOperators(city.config, options.operators)) {
    inboxes.push_back(OperatorInbox{name, std::make_unique<dds::Reader<msg::OperatorRequest>>(
                                              participant, dds::topics::OperatorRequests(name))});
  }
  for (const auto& inbox : inboxes) waitset.Attach(*inbox.reader);
}

void Scm::Impl::WatchStrangers() {
  // An operator the city does not allow still gets an answer (a refusal): read the operator
  // topics that writers appear on, up to a bound.
  for (const std::string& topic : publications->TakeTopics()) {
    // The shared topic (".../operator/request") has the prefix and the suffix overlapping:
    // only a topic longer than both names an operator.
    if (topic.size() <= kOperatorTopicPrefix.size() + kOperatorTopicSuffix.size() ||
        !topic.starts_with(kOperatorTopicPrefix) || !topic.ends_with(kOperatorTopicSuffix)) {
      continue;
    }
    const std::string name =
        topic.substr(kOperatorTopicPrefix.size(),
                     topic.size() - kOperatorTopicPrefix.size() - kOperatorTopicSuffix.size());
    if (std::ranges::any_of(inboxes, [&](const auto& i) { return i.operator_name == name; })) {
      continue;
    }
    if (stranger_inboxes >= kMaxStrangerOperators) continue;
    try {
      inboxes.push_back(OperatorInbox{name, std::make_unique<dds::Reader<msg::OperatorRequest>>(
                                                participant, dds::topics::OperatorRequests(name))});
      waitset.Attach(*inboxes.back().reader);
      ++stranger_inboxes;
      spdlog::warn(
          "a writer appeared for operator '{}', whom the city does not allow; its "
          "requests will be refused",
          name);
    } catch (const InputError&) {
      // Not an operator name we could ever allow: nothing to answer.
    }
  }
}

void Scm::Impl::Install(std::unique_ptr<CityBundle> next, const ClockReading& now) {
  next->Start(now.mono);
  // What runs: the file the SCM started with, or the configuration an operator applied since.
  figures.config_path = next->city().config_path.string();
  publishers->Reset(*next->runtime, next->city().config.name);
  publishers->PublishMap(next->map, now.wire);
  control->SetParams(ControlParamsOf(next->city(), options.operators));
  OpenInboxes(next->city());
  std::unique_ptr<CityBundle> old = std::move(bundle);
  bundle = std::move(next);
  if (old) loader->Dispose(std::move(old));  // deleting its DDS entities takes time
  next_spat = now.mono;
  next_tick = now.mono;
  next_housekeeping = now.mono;
  if (next_prune == MonoTime{}) next_prune = now.mono;
}

void Scm::Impl::Emit(Event e) {
  const Time now = current.wire;
  const std::uint64_t id = ++event_seq;
  ++counters.events;
  const auto level = e.severity >= Severity::kAlarm     ? spdlog::level::err
                     : e.severity == Severity::kWarning ? spdlog::level::warn
                                                        : spdlog::level::info;
  spdlog::log(level, "event {} [{}] {}{}", e.code, ToString(e.severity), e.message,
              e.actor == "scm" ? "" : fmt::format(" (by {})", e.actor));
  publishers->PublishEvent(e, now, id);
  EventRecord record;
  record.time = now;
  record.severity = e.severity;
  record.source = "scm";
  record.code = std::move(e.code);
  record.message = std::move(e.message);
  record.intersection = e.intersection;
  record.device_id = std::move(e.device);
  record.actor = std::move(e.actor);
  record.active = e.active;
  if (!persistence->AppendEvent(std::move(record))) ++counters.events_dropped;
}

void Scm::Impl::Validate(std::string yaml, std::string label, Responder respond) {
  if (loader->busy() || pending_apply) {
    respond(Reply::Rejected("another configuration is being loaded; try again in a moment"));
    return;
  }
  loader->Check(
      std::move(yaml), label, ConfigPolicy(),
      [respond = std::move(respond), label](std::unique_ptr<City> city, std::string error) {
        if (!city) {
          respond(Reply::Rejected(error));
          return;
        }
        respond(Reply::Ok(fmt::format("{} is valid: city {}, {} signalised intersections", label,
                                      city->config.name, city->intersections.size())));
      });
}

void Scm::Impl::Apply(std::string yaml, std::string label, std::string by, Responder respond) {
  if (loader->busy() || pending_apply) {
    respond(Reply::Rejected("another configuration is being loaded; try again in a moment"));
    return;
  }
  loader->Build(
      yaml, label, map_revision + 1, ConfigPolicy(),
      [this, yaml, label, by, respond = std::move(respond)](std::unique_ptr<CityBundle> built,
                                                            std::string error) mutable {
        if (!built) {
          // A failed apply leaves the running city untouched.
          respond(Reply::Rejected(error));
          return;
        }
        pending_apply = std::move(built);
        // Recorded (durably) before it runs: after a restart the SCM runs what was applied.
        persistence->SaveAppliedConfig(
            label, yaml, by, current.wire,
            [this, label, by, respond](std::optional<std::int64_t> id, std::string save_error) {
              std::unique_ptr<CityBundle> next = std::move(pending_apply);
              if (!id) {
                loader->Dispose(std::move(next));
                respond(
                    Reply::Failed("the configuration could not be recorded, so it was not "
                                  "applied: " +
                                  save_error));
                return;
              }
              const std::string name = next->city().config.name;
              const std::size_t n = next->runtime->intersections().size();
              ++map_revision;
              Emit(Event{Severity::kWarning, "config_applied",
                         fmt::format("configuration {} applied (city {}); every intersection "
                                     "restarts through the start-up sequence",
                                     label, name),
                         IntersectionId(0), "", by, false});
              Install(std::move(next), clock.Read());
              respond(
                  Reply::Ok(fmt::format("applied {}: city {}, {} signalised intersections; "
                                        "restarting them through flash and all red",
                                        label, name, n)));
            });
      });
}

void Scm::Impl::NewSession(const ClockReading& now) {
  // The simulation restarted (/clock went back): every timer of the old timeline is
  // meaningless. Restart like the daemon would, keeping the operators' modes and plans.
  clock_session = now.session;
  ++counters.clock_sessions;
  bundle->restore = bundle->runtime->OperatorStates(now.wire);
  bundle->Start(now.mono);
  bundle->fleet->DropStale(Time::max());
  v2i.Clear();
  next_spat = next_tick = next_housekeeping = next_prune = now.mono;
  Emit(Event{Severity::kWarning, "clock_session",
             fmt::format("the simulation restarted (clock session {}, time {}): every intersection "
                         "restarts through the start-up sequence",
                         now.session, ToString(now.wire)),
             IntersectionId(0), "", "scm", false});
}

void Scm::Impl::TakeDeviceStatuses() {
  const std::size_t n = device_statuses->Drain(reports);
  for (std::size_t i = 0; i < n; ++i) {
    const ReceivedReport& received = reports[i];
    const DeviceReportView r = received.View();
    // Judged on when the report arrived (the receiving thread's stamp), not on this pass.
    if (bundle->supervisor->Report(r, received.received, *bundle->runtime, *this)) {
      bundle->devices->Take(r, received.received);
    }
  }
  const std::uint64_t malformed = device_statuses->malformed() + device_statuses->dropped();
  figures.malformed_inputs += malformed - device_malformed_seen;
  device_malformed_seen = malformed;
}

void Scm::Impl::NoteStall(const ClockReading& now) {
  // A pass that starts well after the deadline it waited for: the loop (or the whole process,
  // or the machine) stalled. The devices' reports of that time may still be on their way in:
  // supervision waits a moment for them before it declares any device lost.
  if (planned_wake == MonoTime{} || now.mono <= planned_wake + kStallThreshold) return;
  const Duration stall = now.mono - planned_wake;
  ++figures.stalls;
  figures.longest_stall = std::max(figures.longest_stall, stall);
  bundle->supervisor->OnStall(now.mono);
  if (figures.stalls <= 20 || figures.stalls % 100 == 0) {
    spdlog::warn(
        "the SCM's loop stalled: this pass began {:.0f} ms after its deadline ({} "
        "stalls so far, the longest {:.0f} ms); devices get {:.0f} ms to be heard "
        "before any is declared lost",
        ToSeconds(stall) * 1000.0, figures.stalls, ToSeconds(figures.longest_stall) * 1000.0,
        ToSeconds(bundle->supervisor->stall_settle()) * 1000.0);
  }
  // An event for a long stall, at most one per kStallEventPeriod (a simulated clock far ahead
  // of a slow SCM would otherwise fill the event log).
  if (stall >= kStallEvent) ++stalls_unreported;
  if (stall >= kStallEvent &&
      (last_stall_event == MonoTime{} || now.mono - last_stall_event >= kStallEventPeriod)) {
    Emit(Event{
        Severity::kWarning, "scm_stall",
        fmt::format("the SCM's loop stalled for {:.0f} ms (SPaT, heartbeat and "
                    "supervision paused; {} stalls over {:.0f} ms since the last such "
                    "event); no device is declared lost before it has had {:.0f} ms to be "
                    "heard again",
                    ToSeconds(stall) * 1000.0, stalls_unreported, ToSeconds(kStallEvent) * 1000.0,
                    ToSeconds(bundle->supervisor->stall_settle()) * 1000.0),
        IntersectionId(0), "", "scm", false});
    last_stall_event = now.mono;
    stalls_unreported = 0;
  }
}

void Scm::Impl::HandleOperatorRequests(const ClockReading& now, const DayClock& day) {
  std::size_t handled = 0;
  // Commands answer here or through completions run at the start of a pass; nothing below
  // replaces the inboxes (a configuration is swapped in by a completion).
  for (std::size_t i = 0; i < inboxes.size() && handled < options.max_requests_per_pass; ++i) {
    auto* reader = inboxes[i].reader.get();
    const std::string& operator_name = inboxes[i].operator_name;
    while (handled < options.max_requests_per_pass && MayHandleRequest() &&
           reader->TakeOne(request_sample, &request_info)) {
      ++handled;
      CountRequestPastSpat();
      ++counters.operator_requests;
      // Whose participant asked: the reply waits until the reply writer has matched its reader.
      const std::optional<dds::ParticipantKey> requester =
          requesters.Find(reader->handle(), request_info.publication_handle);
      Admission a = control->Admit(*request_sample, operator_name, now.mono);
      if (a.kind == Admission::Kind::kRunning) continue;  // its answer is on the way
      if (a.kind == Admission::Kind::kAnswer) {
        if (a.reply.code != ReplyCode::kOk) ++counters.refused_requests;
        replies->Send(a.client, a.request_id, a.reply, requester, now.wire, now.mono);
        continue;
      }
      OperatorCommand cmd = std::move(a.command);
      if (!operator_name.empty()) cmd.actor = operator_name + " (" + cmd.client + ")";
      const std::string client = cmd.client;
      const std::uint64_t request_id = cmd.request_id;
      Responder respond = [this, client, request_id, requester](Reply reply) {
        control->Remember(client, request_id, reply, current.mono);
        replies->Send(client, request_id, reply, requester, current.wire, current.mono);
      };
      CommandContext ctx{*bundle->runtime,
                         *bundle->supervisor,
                         *publishers,
                         *bundle->lights,
                         *bundle->fleet,
                         *persistence,
                         *this,
                         *control,
                         figures,
                         *this,
                         day};
      if (auto reply = RunOperatorCommand(cmd, now, ctx, respond)) respond(std::move(*reply));
    }
  }
}

void Scm::Impl::HandleSignalRequests(const ClockReading& now, const DayClock& day) {
  std::size_t handled = 0;
  while (handled < options.max_requests_per_pass && MayHandleRequest() &&
         signal_requests->TakeOne(signal_sample)) {
    ++handled;
    CountRequestPastSpat();
    ++counters.signal_requests;
    ++figures.signal_requests;
    v2i.Handle(*signal_sample, now, day, *bundle, *publishers, *this);
  }
}

bool Scm::Impl::MayHandleRequest() const { return requests_before_spat > 0 || !SpatDue(); }

void Scm::Impl::CountRequestPastSpat() {
  if (requests_before_spat > 0 && SpatDue()) --requests_before_spat;
}

bool Scm::Impl::RequestWaiting() const {
  if (signal_requests->HasSamples()) return true;
  return std::any_of(inboxes.begin(), inboxes.end(),
                     [](const OperatorInbox& in) { return in.reader->HasSamples(); });
}

bool Scm::Impl::PublishSpatUnlessAsked(const CityBundle& c, const ClockReading& now) {
  publishers->StartSpat(now);
  while (!publishers->FillSpat(*c.runtime, std::max<std::size_t>(options.spat_slice, 1))) {
    if (!spat_gave_way && RequestWaiting()) {
      spat_gave_way = true;
      requests_before_spat = kRequestsBeforeSpat;
      return false;
    }
  }
  publishers->SendSpat();
  spat_gave_way = false;
  requests_before_spat = 0;
  return true;
}

void Scm::Impl::Housekeeping(const ClockReading& now) {
  next_housekeeping = now.mono + std::chrono::seconds(1);
  v2i.Flush(now.mono, *this);
  WatchStrangers();
  if (now.mono >= next_prune) {
    next_prune = now.mono + options.prune_period;
    persistence->Prune(now.wire, options.retention);
  }
}

void Scm::Impl::Pass() {
  const ClockReading now = clock.Read();
  current = now;
  ++counters.passes;
  ++figures.passes;
  if (now.session != clock_session) {
    NewSession(now);
  } else {
    NoteStall(now);
  }
  persistence->RunCompletions();
  loader->RunCompletions();
  const DayClock day = DayAt(now.wire);
  CityBundle& c = *bundle;  // a configuration applied by a completion above is in place
  for (auto& source : c.sources) {
    const std::uint64_t malformed = source->malformed();
    counters.fleet_observations += source->Poll(now, *c.fleet);
    figures.malformed_inputs += source->malformed() - malformed;
  }
  TakeDeviceStatuses();
  HandleOperatorRequests(now, day);
  replies->Flush(now.mono);
  figures.replies = replies->counters();
  figures.reply_write_refusals = replies->write_failures();
  HandleSignalRequests(now, day);
  c.supervisor->Check(now.mono, c.lights->sent(), *c.runtime, *this);
  const StepReport report = c.runtime->Step(now, day, c.fleet.get(), *this);
  counters.controller_steps += report.stepped;
  counters.monitor_violations += report.monitor_violations;
  figures.monitor_violations = counters.monitor_violations;
  v2i.PublishUpdates(c, *publishers, now);
  c.lights->Sync(*c.runtime, *c.supervisor, now.mono);
  if (now.mono >= next_spat && PublishSpatUnlessAsked(c, now)) {
    c.fleet->DropStale(now.wire);
    publishers->PublishFleet(*c.fleet, now.wire);
    publishers->PublishHeartbeat(now.wire, ScmState::kRunning);
    next_spat += options.spat_period;
    if (next_spat <= now.mono) {
      // Late by a period or more: skip the missed ones rather than bunch them.
      next_spat += ((now.mono - next_spat) / options.spat_period + 1) * options.spat_period;
    }
  }
  if (c.devices->Due(now.mono)) {
    c.devices->Refresh(now.mono);
    publishers->PublishDeviceTable(*c.devices, now.wire);
  }
  if (now.mono >= next_housekeeping) Housekeeping(now);
  while (next_tick <= now.mono) next_tick += options.tick;
  planned_wake = NextDeadline();
}

MonoTime Scm::Impl::NextDeadline() const {
  MonoTime next = std::min({next_spat, next_tick, next_housekeeping});
  // A controller due at or before the pass just run was stepped by it. One that is due again
  // at once asks to be stepped on every pass (a call on its green phase keeps its gap timer
  // running, `IntersectionController::next_wake`): the next tick does that. Waking for it at
  // once would spin the loop for as long as a car stands on a green phase's detector.
  if (const MonoTime wake = bundle->runtime->next_wake(); wake > current.mono) {
    next = std::min(next, wake);
  }
  next = std::min(next, bundle->supervisor->next_deadline());
  next = std::min(next, bundle->devices->next_deadline());
  return next;
}

// --- Scm --------------------------------------------------------------------------------------

Scm::Scm(const ScmOptions& options, Clock& clock, dds::Participant& participant)
    : impl_(std::make_unique<Impl>(options, clock, participant)) {}

Scm::~Scm() = default;

const City& Scm::city() const { return impl_->bundle->city(); }

const CityRuntime& Scm::runtime() const { return *impl_->bundle->runtime; }

ScmCounters Scm::counters() const {
  const Impl& d = *impl_;
  ScmCounters c = d.counters;
  c.spat_published = d.publishers->counters().spat;
  c.light_commands = d.bundle->lights->counters().writes;
  c.light_resends = d.bundle->lights->counters().resends;
  c.write_failures = d.publishers->counters().write_failures +
                     d.bundle->lights->counters().failures + d.replies->counters().dropped;
  c.foreign_devices =
      d.bundle->supervisor->counters().foreign_city + d.bundle->supervisor->counters().foreign_host;
  c.events_dropped += d.persistence->stats().events_dropped;
  return c;
}

void Scm::Pass() { impl_->Pass(); }

MonoTime Scm::next_deadline() const { return impl_->NextDeadline(); }

void Scm::FlushPersistence() {
  impl_->persistence->Flush();
  impl_->persistence->RunCompletions();
}

void Scm::Run() {
  Impl& d = *impl_;
  systemd::Notify("READY=1");
  systemd::Notify(fmt::format("STATUS=running city {}", d.bundle->city().config.name));
  while (!d.stop.load() && !d.clock.interrupted()) {
    try {
      d.Pass();
    } catch (const std::exception& e) {
      // A bug must not stop the signals: log, count, carry on.
      spdlog::error("pass failed: {}", e.what());
    }
    if (d.watchdog) {
      // The watchdog is told from the loop itself: a loop that hangs stops telling it.
      const auto now = std::chrono::steady_clock::now();
      if (now >= d.next_watchdog) {
        systemd::Notify("WATCHDOG=1");
        d.next_watchdog =
            now + std::chrono::duration_cast<std::chrono::steady_clock::duration>(*d.watchdog / 2);
      }
    }
    if (d.stop.load()) break;
    d.waitset.WaitUntil(d.NextDeadline());
  }
  systemd::Notify("STOPPING=1");
  const ClockReading now = d.clock.Read();
  d.current = now;
  d.publishers->PublishHeartbeat(now.wire, ScmState::kStopping);
  d.Emit(Event{Severity::kWarning, "scm_stopped", "SCM stopping: the lights flash on their own",
               IntersectionId(0), "", "scm", false});
  d.persistence->Flush();
}

void Scm::Stop() {
  impl_->stop.store(true);
  impl_->waitset.Wake();
}

}  // namespace autodrive::scm
