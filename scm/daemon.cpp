#include "scm/daemon.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <mutex>
#include <random>
#include <vector>

#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/dds/loop_waitset.h"
#include "common/error.h"
#include "common/systemd.h"
#include "scm/city_bundle.h"
#include "scm/config_loader.h"
#include "scm/core/process_watch.h"
#include "scm/io/inbox.h"
#include "scm/io/publishers.h"
#include "scm/io/reply_outbox.h"
#include "scm/io/v2i.h"
#include "scm/operator/control_plane.h"
#include "scm/operator/operator_commands.h"
#include "scm/pass_scheduler.h"

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

PassScheduleParams ScheduleOf(const ScmOptions& o) {
  PassScheduleParams p;
  p.tick = o.tick;
  p.spat_period = o.spat_period;
  p.prune_period = o.prune_period;
  return p;
}

ControlPlaneParams ControlParamsOf(const City& city, const std::vector<std::string>& extra) {
  ControlPlaneParams p;
  p.operators = AllowedOperators(city.config, extra);
  p.rate_per_s = city.config.operators.rate_per_s;
  p.burst = city.config.operators.burst;
  return p;
}

}  // namespace

struct Scm::Impl final : EventSink, ConfigService {
  Impl(const ScmOptions& o, Clock& c, dds::Participant& p);
  ~Impl() override;

  // EventSink: log, publish, queue for the database.
  void Emit(Event event) override;
  void EmitAt(Event event, Time at) override;
  // ConfigService.
  void Validate(std::string yaml, std::string label, Responder respond) override;
  void Apply(std::string yaml, std::string label, std::string by, Responder respond) override;

  std::unique_ptr<City> LoadStartupCity(const MapResolution& resolution);
  /// What an operator's configuration must satisfy here (`ConfigRefusal` against the running
  /// city and `--operator`), as copies for the loader's thread.
  [[nodiscard]] ConfigLoader::Policy ConfigPolicy() const;
  /// Raises an alarm when the running city allows no operator to change state.
  void WarnIfLockedOut();
  void Install(std::unique_ptr<CityBundle> bundle, const ClockReading& now);
  void NewSession(const ClockReading& now);
  /// Gives supervision the reports the receiving thread took since the last pass.
  void TakeDeviceStatuses();
  /// Hands the controllers' high-resolution events to the writer thread.
  void TakeHires(CityBundle& c, const ClockReading& now);
  /// Gives the process watch the launchers' tables that came since the last pass.
  void TakeProcessTables(const ClockReading& now);
  /// Notices a pass that starts late (a stall of the loop or the process): logs it and tells
  /// supervision, which then re-checks before it latches anything on the devices' silence.
  void NoteStall(const ClockReading& now);
  /// Whether one more request may be handled in this pass, on the clock read now (not the
  /// pass's reading): once SPaT's deadline has come, requests wait for the next pass (the
  /// waitset wakes it at once) so that a flood, or a slow machine, never holds SPaT back,
  /// except the few SPaT's filling gave way to (`PublishSpatUnlessAsked`).
  [[nodiscard]] bool MayHandleRequest() const;
  /// Counts a request handled past SPaT's deadline against those SPaT gave way to.
  void CountRequestPastSpat();
  /// Fills SPaT in slices; when a request is waiting between two slices, and SPaT has not
  /// already given way once for this deadline, it stops (returns false) so that the next pass
  /// answers a few requests first and then fills SPaT afresh without stopping. A request thus
  /// waits for a slice, not for the whole city's SPaT. True when SPaT was handed to its sender.
  bool PublishSpatUnlessAsked(const CityBundle& c, const ClockReading& now);
  /// The launchers' timeline, on which the process watch judges their silence: they report
  /// on the wall clock whatever the SCM runs on, so under a simulated clock (which may run
  /// many times faster or stand still in lockstep) it is this computer's steady clock.
  [[nodiscard]] MonoTime LauncherTime(const ClockReading& now) const;
  void HandleOperatorRequests(const ClockReading& now, const DayClock& day);
  void HandleOperatorRequest(const ScmInbox::OperatorRequestIn& in, const ClockReading& now,
                             const DayClock& day);
  void HandleSignalRequests(const ClockReading& now, const DayClock& day);
  void Housekeeping(const ClockReading& now);
  void Pass();
  [[nodiscard]] OtherDeadlines Deadlines() const;
  [[nodiscard]] MonoTime NextDeadline() const;

  ScmOptions options;
  Clock& clock;
  dds::Participant& participant;
  std::uint64_t clock_session = 0;
  std::atomic<bool> stop{false};
  ClockReading current;                  // the reading of the pass under way (event times)
  std::vector<HiresRecord> hires_batch;  // reused by TakeHires

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

  // Incompatible QoS peers reported by the participant (on a DDS thread), raised as events by
  // the next pass.
  std::mutex incompatible_mutex;
  std::vector<dds::IncompatibleQos> incompatible;
  void RaiseIncompatibleQos();

  std::unique_ptr<ProcessWatch> processes;  // the launchers' processes: outlives every city
  std::unique_ptr<ScmInbox> inbox;          // created after replies, destroyed after them
  std::unique_ptr<ReplyOutbox> replies;
  PassScheduler schedule;
  StallWatch stalls;
};

Scm::Impl::Impl(const ScmOptions& o, Clock& c, dds::Participant& p)
    : options(o), clock(c), participant(p), waitset(p, c), schedule(ScheduleOf(o)) {
  std::random_device entropy;
  // The heartbeat's session id (random per start).
  const std::uint64_t session = (static_cast<std::uint64_t>(entropy()) << 32) ^ entropy() ^
                                static_cast<std::uint64_t>(::getpid());
  const auto root =
      options.config_root
          ? *options.config_root
          : std::filesystem::absolute(options.config_path).parent_path().parent_path();
  const MapResolution resolution{std::filesystem::absolute(options.config_path).parent_path(),
                                 root};
  persistence = std::make_unique<Persistence>(Store(options.db_path), [this] { waitset.Wake(); });
  participant.OnIncompatibleQos([this](const dds::IncompatibleQos& q) {
    {
      std::lock_guard lock(incompatible_mutex);
      incompatible.push_back(q);
    }
    waitset.Wake();
  });
  event_seq = static_cast<std::uint64_t>(persistence->store().LastEventId());
  signal_writers = std::make_unique<SignalCommandWriters>(participant);
  loader = std::make_unique<ConfigLoader>(participant, clock.kind(), *signal_writers,
                                          persistence->store(), resolution, options.district,
                                          [this] { waitset.Wake(); });
  auto city = LoadStartupCity(resolution);
  figures.clock = clock.kind();
  ProcessWatchParams watch;
  watch.city = city->config.name;
  processes = std::make_unique<ProcessWatch>(std::move(watch));
  // What the log holds already is not logged again (an SCM killed and back, say).
  for (const LatestDeviceEvent& e : persistence->store().LatestProcessEvents()) {
    processes->Logged(e.code, e.device_id, e.time);
  }
  publishers = std::make_unique<ScmPublishers>(participant, city->config.name, session);
  control = std::make_unique<ControlPlane>(ControlParamsOf(*city, options.operators));
  replies = std::make_unique<ReplyOutbox>(participant);
  inbox = std::make_unique<ScmInbox>(participant, clock, waitset);
  const ClockReading now = clock.Read();
  current = now;
  clock_session = now.session;
  figures.started = now.mono;
  auto first =
      std::make_unique<CityBundle>(std::move(city), participant, clock.kind(), *signal_writers,
                                   persistence->store().LoadIntersectionStates(), ++map_revision);
  Install(std::move(first), now);
  Emit(Event{Severity::kInfo, "scm_started",
             fmt::format("SCM started: city {}{}, {} signalised intersections, {} lights, {} clock",
                         bundle->city().config.name,
                         options.district.empty() ? "" : ", district " + options.district,
                         bundle->runtime->intersections().size(), bundle->runtime->heads().size(),
                         ToString(clock.kind())),
             IntersectionId(0), "", "scm", false});
  WarnIfLockedOut();
}

Scm::Impl::~Impl() {
  participant.OnIncompatibleQos({});
  // The loader may be building a bundle on the participant: stop it first.
  loader.reset();
}

void Scm::Impl::RaiseIncompatibleQos() {
  std::vector<dds::IncompatibleQos> reports;
  {
    std::lock_guard lock(incompatible_mutex);
    reports.swap(incompatible);
  }
  for (const dds::IncompatibleQos& q : reports) {
    // A peer that never matches: a ROS 2 node with the wrong QoS, which would otherwise
    // publish or listen in vain without a word from either side.
    Emit(Event{Severity::kWarning, "incompatible_qos", q.Message(), IntersectionId(0), "", "scm",
               false});
  }
}

std::unique_ptr<City> Scm::Impl::LoadStartupCity(const MapResolution& resolution) {
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
        if (!options.district.empty()) NarrowToDistrict(*city, options.district);
        spdlog::info("using the configuration applied by {} (the file {} is unchanged since)",
                     cfg->applied_by, options.config_path.string());
        return city;
      }
      break;
    }
    if (!applied) applied = h.id;
  }
  auto city = std::make_unique<City>(LoadCity(options.config_path));
  if (!options.district.empty()) NarrowToDistrict(*city, options.district);
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

void Scm::Impl::Install(std::unique_ptr<CityBundle> next, const ClockReading& now) {
  next->Start(now);
  // What runs: the file the SCM started with, or the configuration an operator applied since.
  figures.config_path = next->city().config_path.string();
  publishers->Reset(*next->runtime, next->city().config.name);
  publishers->PublishMap(next->map, now.wire);
  control->SetParams(ControlParamsOf(next->city(), options.operators));
  inbox->OpenOperators(AllowedOperators(next->city().config, options.operators));
  std::unique_ptr<CityBundle> old = std::move(bundle);
  bundle = std::move(next);
  if (old) loader->Dispose(std::move(old));  // deleting its DDS entities takes time
  schedule.Start(now.mono);
}

void Scm::Impl::Emit(Event e) { EmitAt(std::move(e), current.wire); }

void Scm::Impl::EmitAt(Event e, Time now) {
  // Its id is its row in the event log: the same live and in the log, and never used twice,
  // also across restarts (the count goes on from the log's last id).
  const std::uint64_t id = ++event_seq;
  ++counters.events;
  const auto level = e.severity >= Severity::kAlarm     ? spdlog::level::err
                     : e.severity == Severity::kWarning ? spdlog::level::warn
                                                        : spdlog::level::info;
  spdlog::log(level, "event {} [{}] {}{}", e.code, ToString(e.severity), e.message,
              e.actor == "scm" ? "" : fmt::format(" (by {})", e.actor));
  publishers->PublishEvent(e, now, id);
  EventRecord record;
  record.id = static_cast<std::int64_t>(id);
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
  bundle->Start(now);
  bundle->fleet->DropStale(Time::max());
  v2i.Clear();
  schedule.Restart(now.mono);
  Emit(Event{Severity::kWarning, "clock_session",
             fmt::format("the simulation restarted (clock session {}, time {}): every intersection "
                         "restarts through the start-up sequence",
                         now.session, ToString(now.wire)),
             IntersectionId(0), "", "scm", false});
}

void Scm::Impl::TakeDeviceStatuses() {
  for (const ReceivedReport& received : inbox->TakeDeviceReports()) {
    const DeviceReportView r = received.View();
    // Judged on when the report arrived (the receiving thread's stamp), not on this pass.
    if (bundle->supervisor->Report(r, received.received, *bundle->runtime, *this)) {
      bundle->devices->Take(r, received.received);
    }
  }
  figures.malformed_inputs += inbox->TakeDeviceRefusals();
}

MonoTime Scm::Impl::LauncherTime(const ClockReading& now) const {
  if (clock.kind() == ClockKind::kWall) return now.mono;
  return MonoTime{std::chrono::steady_clock::now().time_since_epoch()};
}

void Scm::Impl::TakeProcessTables(const ClockReading& now) {
  const std::uint64_t refused = inbox->process_table_refusals();
  const MonoTime launcher_now = LauncherTime(now);
  while (const std::optional<ProcessTableView> table = inbox->TakeProcessTable()) {
    processes->Report(*table, launcher_now, *this);
  }
  figures.malformed_inputs += inbox->process_table_refusals() - refused;
}

void Scm::Impl::NoteStall(const ClockReading& now) {
  // A pass that starts well after the deadline it waited for: the loop (or the whole process,
  // or the machine) stalled. The devices' reports of that time may still be on their way in:
  // supervision waits a moment for them before it declares any device lost.
  const std::optional<Duration> late = schedule.Stall(now.mono);
  if (!late) return;
  const Duration stall = *late;
  ++figures.stalls;
  figures.longest_stall = std::max(figures.longest_stall, stall);
  bundle->supervisor->OnStall(now.mono);
  processes->OnStall(LauncherTime(now));
  if (figures.stalls <= 20 || figures.stalls % 100 == 0) {
    spdlog::warn(
        "the SCM's loop stalled: this pass began {:.0f} ms after its deadline ({} "
        "stalls so far, the longest {:.0f} ms); devices get {:.0f} ms to be heard "
        "before any is declared lost",
        ToSeconds(stall) * 1000.0, figures.stalls, ToSeconds(figures.longest_stall) * 1000.0,
        ToSeconds(bundle->supervisor->stall_settle()) * 1000.0);
  }
  // An event for a long stall, at most one per StallWatch::kEventPeriod.
  if (const std::optional<std::uint64_t> unreported = stalls.Note(stall, now.mono)) {
    Emit(Event{Severity::kWarning, "scm_stall",
               fmt::format("the SCM's loop stalled for {:.0f} ms (SPaT, heartbeat and "
                           "supervision paused; {} stalls over {:.0f} ms since the last such "
                           "event); no device is declared lost before it has had {:.0f} ms to be "
                           "heard again",
                           ToSeconds(stall) * 1000.0, *unreported,
                           ToSeconds(StallWatch::kEventThreshold) * 1000.0,
                           ToSeconds(bundle->supervisor->stall_settle()) * 1000.0),
               IntersectionId(0), "", "scm", false});
  }
}

void Scm::Impl::HandleOperatorRequests(const ClockReading& now, const DayClock& day) {
  // Commands answer here or through completions run at the start of a pass; nothing below
  // replaces the inbox's topics (a configuration is swapped in by a completion).
  inbox->RestartOperatorRound();
  for (std::size_t handled = 0; handled < options.max_requests_per_pass && MayHandleRequest();
       ++handled) {
    const std::optional<ScmInbox::OperatorRequestIn> in = inbox->TakeOperatorRequest();
    if (!in) break;
    CountRequestPastSpat();
    ++counters.operator_requests;
    HandleOperatorRequest(*in, now, day);
  }
}

void Scm::Impl::HandleOperatorRequest(const ScmInbox::OperatorRequestIn& in,
                                      const ClockReading& now, const DayClock& day) {
  const std::optional<dds::ParticipantKey> requester = in.requester;
  Admission a = control->Admit(in.request, in.operator_name, now.mono);
  if (a.kind == Admission::Kind::kRunning) return;  // its answer is on the way
  if (a.kind == Admission::Kind::kAnswer) {
    if (a.reply.code != ReplyCode::kOk) ++counters.refused_requests;
    replies->Send(a.client, a.request_id, a.reply, requester, now.wire, now.mono);
    return;
  }
  OperatorCommand cmd = std::move(a.command);
  if (!in.operator_name.empty()) cmd.actor = in.operator_name + " (" + cmd.client + ")";
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

void Scm::Impl::HandleSignalRequests(const ClockReading& now, const DayClock& day) {
  std::size_t handled = 0;
  const msg::SignalRequest* request = nullptr;
  while (handled < options.max_requests_per_pass && MayHandleRequest() &&
         (request = inbox->TakeSignalRequest()) != nullptr) {
    ++handled;
    CountRequestPastSpat();
    ++counters.signal_requests;
    ++figures.signal_requests;
    v2i.Handle(*request, now, day, *bundle, *publishers, *this);
  }
}

bool Scm::Impl::MayHandleRequest() const { return schedule.MayHandleRequest(clock.Read().mono); }

void Scm::Impl::CountRequestPastSpat() { schedule.CountRequest(clock.Read().mono); }

bool Scm::Impl::PublishSpatUnlessAsked(const CityBundle& c, const ClockReading& now) {
  publishers->StartSpat(now);
  while (!publishers->FillSpat(*c.runtime, std::max<std::size_t>(options.spat_slice, 1))) {
    if (schedule.MayGiveWay() && inbox->RequestWaiting()) {
      schedule.GiveWay();
      return false;
    }
  }
  publishers->SendSpat();
  schedule.SpatSent(now.mono);
  return true;
}

void Scm::Impl::Housekeeping(const ClockReading& now) {
  const bool prune = schedule.Housekeep(now.mono);
  v2i.Flush(now.mono, *this);
  inbox->WatchStrangers();
  if (prune) persistence->Prune(now.wire, options.retention);
}

void Scm::Impl::Pass() {
  const auto began = std::chrono::steady_clock::now();
  const ClockReading now = clock.Read();
  current = now;
  // Lateness only means something on the wall clock (a simulated clock jumps to each deadline).
  const Duration late =
      clock.kind() == ClockKind::kWall ? schedule.Lateness(now.mono) : Duration{0};
  ++counters.passes;
  ++figures.passes;
  if (now.session != clock_session) {
    NewSession(now);
  } else {
    NoteStall(now);
  }
  persistence->RunCompletions();
  loader->RunCompletions();
  RaiseIncompatibleQos();
  const DayClock day = DayAt(now.wire);
  CityBundle& c = *bundle;  // a configuration applied by a completion above is in place
  for (auto& source : c.sources) {
    const std::uint64_t malformed = source->malformed();
    counters.fleet_observations += source->Poll(now, *c.fleet);
    figures.malformed_inputs += source->malformed() - malformed;
  }
  TakeDeviceStatuses();
  TakeProcessTables(now);
  HandleOperatorRequests(now, day);
  replies->Flush(now.mono);
  figures.replies = replies->counters();
  figures.reply_write_refusals = replies->write_failures();
  HandleSignalRequests(now, day);
  c.supervisor->Check(now.mono, c.lights->sent(), *c.runtime, *this);
  processes->Check(LauncherTime(now), *this);
  const StepReport report = c.runtime->Step(now, day, c.fleet.get(), *this);
  counters.controller_steps += report.stepped;
  counters.monitor_violations += report.monitor_violations;
  figures.monitor_violations = counters.monitor_violations;
  v2i.PublishUpdates(c, *publishers, now);
  TakeHires(c, now);
  c.lights->Sync(*c.runtime, *c.supervisor, now.mono);
  if (schedule.SpatDue(now.mono) && PublishSpatUnlessAsked(c, now)) {
    c.fleet->DropStale(now.wire);
    publishers->PublishFleet(*c.fleet, now.wire);
    publishers->PublishHeartbeat(now.wire, ScmState::kRunning);
  }
  if (c.devices->Due(now.mono)) {
    c.devices->Refresh(now.mono);
    publishers->PublishDeviceTable(*c.devices, now.wire);
  }
  if (schedule.HousekeepingDue(now.mono)) Housekeeping(now);
  schedule.EndPass(now.mono, Deadlines());
  figures.loop.Note(std::chrono::duration_cast<Duration>(std::chrono::steady_clock::now() - began),
                    late);
}

void Scm::Impl::TakeHires(CityBundle& c, const ClockReading& now) {
  hires_batch.clear();
  for (auto& x : c.runtime->intersections()) {
    IntersectionController& controller = *x.controller;
    if (!controller.has_hires_events()) continue;
    for (const HiresEvent& e : controller.hires_events()) {
      hires_batch.push_back({x.model->id, now.ToWire(e.at), e.code, e.param});
    }
    controller.ClearHiresEvents();
  }
  if (!hires_batch.empty()) persistence->AppendHires(hires_batch);
}

OtherDeadlines Scm::Impl::Deadlines() const {
  // The process watch's deadline on the launchers' timeline, put on the control timeline (a
  // simulation that runs fast only wakes the loop early).
  MonoTime watch = processes->next_deadline();
  if (clock.kind() != ClockKind::kWall && watch != MonoTime::max()) {
    const MonoTime launcher_now = LauncherTime(current);
    watch = current.mono + std::max(Duration{0}, watch - launcher_now);
  }
  return {bundle->runtime->next_wake(), std::min(bundle->supervisor->next_deadline(), watch),
          bundle->devices->next_deadline()};
}

MonoTime Scm::Impl::NextDeadline() const {
  return schedule.NextDeadline(current.mono, Deadlines());
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

void Scm::WaitForSenders() { impl_->publishers->WaitIdle(); }

void Scm::FlushPersistence() {
  impl_->persistence->Flush();
  impl_->persistence->RunCompletions();
}

void Scm::Run() {
  Impl& d = *impl_;
  systemd::Notify("READY=1");
  systemd::Notify(fmt::format("STATUS=running city {}", d.bundle->city().config.name));
  const std::optional<Duration> watchdog = systemd::WatchdogPeriod();
  std::chrono::steady_clock::time_point next_watchdog{};
  while (!d.stop.load() && !d.clock.interrupted()) {
    try {
      d.Pass();
    } catch (const std::exception& e) {
      // A bug must not stop the signals: log, count, carry on.
      spdlog::error("pass failed: {}", e.what());
    }
    if (watchdog) {
      // The watchdog is told from the loop itself: a loop that hangs stops telling it.
      const auto now = std::chrono::steady_clock::now();
      if (now >= next_watchdog) {
        systemd::Notify("WATCHDOG=1");
        next_watchdog =
            now + std::chrono::duration_cast<std::chrono::steady_clock::duration>(*watchdog / 2);
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
