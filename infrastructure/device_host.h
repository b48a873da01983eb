#pragma once
/// @file
/// The device host: the DDS side of `autodrive-infra`. It hosts the configured heads (a
/// `TrafficLightDevice` with its `LampBackend` each) and a `ConflictMonitor` per signalised
/// intersection among them, feeds them the SCM's heartbeat, the light commands and the SCM's
/// device commands (monitor resets), and publishes lamp states, DeviceStatus, events and its
/// own heartbeat.

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/dds/identity.h"
#include "common/dds/participant.h"
#include "common/time.h"
#include "infrastructure/config.h"
#include "infrastructure/conflict_monitor.h"
#include "infrastructure/device.h"
#include "infrastructure/lamps.h"

namespace autodrive::infrastructure {

/// Makes the backend of one head.
using BackendFactory = std::function<std::unique_ptr<LampBackend>(const HeadPlan&)>;

/// The standard backends: a `SimulatedBackend`, or a `SerialBackend` on the head's port with
/// the configured flash period.
[[nodiscard]] std::unique_ptr<LampBackend> MakeBackend(const HeadPlan& head,
                                                       const InfraConfig& config);

/// Counts of what the host received and did, for logs and tests.
struct HostCounters {
  std::uint64_t scm_heartbeats = 0;          ///< heartbeat samples from sender "scm", any city
  std::uint64_t foreign_scm_heartbeats = 0;  ///< of those, from an SCM of another city: ignored
  std::uint64_t malformed_heartbeats = 0;    ///< of those, with a state that is not one: ignored
  std::uint64_t scm_changes = 0;       ///< times the followed SCM (session or participant) changed,
                                       ///< the first one included
  std::uint64_t commands = 0;          ///< light command samples taken, all heads, any writer
  std::uint64_t foreign_commands = 0;  ///< of those, ignored: not written by the SCM's
                                       ///< participant
  std::uint64_t held_commands = 0;     ///< of those, kept until an SCM is followed and current
  std::uint64_t held_dropped = 0;      ///< held commands pushed out by the bound
  std::uint64_t device_commands = 0;   ///< DeviceCommand samples taken
  std::uint64_t device_commands_done = 0;      ///< carried out (acknowledged in DeviceStatus)
  std::uint64_t device_commands_ignored = 0;   ///< refused: city, session, writer, intersection,
                                               ///< command
  std::uint64_t device_commands_not_ours = 0;  ///< for a device another host runs
  std::uint64_t device_commands_repeated = 0;  ///< already carried out (same or older id)
  std::uint64_t monitor_resets = 0;            ///< device commands that cleared a latched monitor
  std::uint64_t unidentified_samples = 0;      ///< samples whose writer's participant is unknown
  std::uint64_t clock_restarts = 0;            ///< new sessions of the clock (simulator restarts)
  std::uint64_t dropped_on_cut_link = 0;  ///< of the SCM's heartbeats, light and device commands
                                          ///< taken, those dropped on the twin's cut link
  std::uint64_t sim_faults = 0;           ///< faults injected into simulated heads here (SimFault)
  std::uint64_t sim_faults_refused = 0;   ///< SimFault samples for a head here that is physical,
                                          ///< or with an action or lamp that is not one
  std::uint64_t events_published = 0;     ///< events written
  std::uint64_t publish_failures = 0;     ///< writes that failed (logged, never fatal)
  std::uint64_t heads_driven = 0;  ///< times a head's lamps were shown and polled: the work of
                                   ///< the passes, which skip heads with nothing new
};

/// Hosts the heads of one `autodrive-infra` process on DDS. Single-threaded: `Step` takes what
/// its readers hold (no listener threads), so everything happens on the caller's thread; `Run`
/// is the loop that calls it. Not copyable or movable (it owns readers and writers).
///
/// Topics: reads `/autodrive/signal_<i>/command` per head, the SCM's heartbeat
/// (`/autodrive/scm/heartbeat`), and device commands (`/autodrive/scm/device_command`); writes
/// `/autodrive/signal_<i>/state` per head (the lamps at that instant, 0..3, on change),
/// DeviceStatus per head and per monitor (one writer each, every status period and on change),
/// events, and its own heartbeat on the device hosts' topic (`/autodrive/infra/heartbeat`,
/// sender "infra/<name>", every status period). Every writer is non-blocking: a write that would
/// wait for slow readers fails at once and is counted. When it hosts a simulated head it also
/// reads the twin's fault injection (`/autodrive/sim/fault`): a lamp of such a head burns out,
/// sticks on or is repaired, the head is unplugged or plugged in, as the simulated backend does
/// it, each with an event ("sim_fault"); faults for a physical head are refused and reported.
/// A cut link (LINK_CUT for this host's name, until LINK_RESTORE) is the network between the
/// host and the SCM failing: what the SCM sends (heartbeats, light and device commands) is
/// dropped, and the host's statuses, events and heartbeat are not sent; the lamps go on (their
/// states are the light the cars see) and the heads fall back to their own flash.
///
/// Whom it obeys (docs/infrastructure.md): it follows the heartbeat of sender "scm" whose city
/// is its own (others are ignored, counted and reported once per session: "foreign_scm"), and
/// knows that SCM by its heartbeat's session and its heartbeat writer's DDS participant. A light
/// command counts only when its writer belongs to that participant; others are ignored, counted
/// and reported ("foreign_command", rate-limited). While no SCM is followed and current (at
/// start-up, or while its heartbeat is missing), commands are held (the latest per head per
/// writer participant, bounded) and the followed SCM's are applied when its heartbeat comes. A
/// device command is carried out only when it is for this host's city, written by the followed
/// SCM's participant, for that SCM's session, and names a monitor of this host with its
/// intersection id; others are ignored, counted and reported ("device_command_ignored",
/// rate-limited), except those for another host's device, which are only counted. Within one
/// pass, heartbeats come first, then device commands, then light commands.
class DeviceHost {
 public:
  /// The longest the loop waits between two passes when a head has I/O of its own (a serial
  /// backend, `LampBackend::NeedsPoll`): such backends are polled at least this often (in real
  /// time, even while a simulation is paused). Data and the devices' own deadlines (flash
  /// edges, heartbeat time-outs, statuses) wake it sooner.
  static constexpr Duration kTickPeriod = std::chrono::milliseconds(20);
  /// The longest the loop waits when no head needs polling: data and the deadlines wake it;
  /// this only bounds a wait in real time.
  static constexpr Duration kIdleWait = std::chrono::milliseconds(500);
  /// Reports of one kind ("foreign_command" per head, "device_command_ignored") go out at most
  /// once per this much control time; the ones held back are counted in the next.
  static constexpr Duration kReportPeriod = std::chrono::seconds(10);
  /// Commands held per head while no SCM is followed: at most from this many writer
  /// participants (the oldest is dropped to make room).
  static constexpr std::size_t kMaxHeldWriters = 8;
  /// Other cities' SCM sessions remembered so that each is reported once.
  static constexpr std::size_t kMaxForeignSessions = 32;

  /// Builds the devices, backends (`make_backend`, default `MakeBackend`) and monitors of
  /// `plan`, and the readers and writers in `participant`, which must outlive the host.
  /// Throws `DdsError` when DDS refuses.
  DeviceHost(const InfraConfig& config, HostPlan plan, const dds::Participant& participant,
             const ClockReading& now, BackendFactory make_backend = {});
  DeviceHost(const DeviceHost&) = delete;
  DeviceHost& operator=(const DeviceHost&) = delete;
  ~DeviceHost();

  /// One pass at `now`: takes what arrived (from every reader), updates devices and monitors,
  /// drives the lamps, publishes. The work of a pass grows with what changed, not with the
  /// heads hosted: a head is driven only when its device changed, a deadline of its came, or
  /// its backend has I/O of its own (`LampBackend::NeedsPoll`); a monitor is checked only when
  /// one of its heads was driven or its latch is due; a status is built only when due or
  /// changed. A new clock session in `now` (the simulator restarted) first restarts the
  /// host's time base: heads back to start-up flash, monitors keep their latches but restart
  /// their timers, the followed SCM is forgotten until its next heartbeat. Never throws on bad
  /// input or failed writes (they are logged and counted). Does nothing after `Stop`.
  void Step(const ClockReading& now);
  /// The next instant of the control timeline at which a pass has something to do if no data
  /// arrives: a flash edge, a heartbeat time-out, a monitor reaching its persistence, a status
  /// or heartbeat due. After `Step(now)`, it is later than `now.mono`. A periodic status goes
  /// out with any pass in the last tenth of its period (so that thousands of heads' statuses
  /// share passes rather than each waking the loop); its period's end is the deadline.
  [[nodiscard]] MonoTime NextDeadline(const ClockReading& now) const;
  /// The loop: `Step`s with the time of `clock` (taking commands only from the heads whose
  /// readers the waitset saw with data), then waits on a `dds::LoopWaitSet` for data on all
  /// its readers (commands, heartbeats, device commands: a command is shown at once),
  /// `NextDeadline` on `clock`, or `kTickPeriod` of `pace`, whichever comes first; until `clock`
  /// or `pace` is interrupted, then `Stop`s. `pace` is a `WallClock` (the lamps' serial links
  /// need real time even while a simulation is paused); `clock` is the system's clock, the same
  /// `WallClock` on the real track or the `SimClock` of `/clock`, and all device logic and
  /// timestamps follow it. With a separate `clock`, `Run` sets its waker for the time it runs.
  void Run(Clock& clock, Clock& pace);
  /// Shutting down: heads go to flashing red (a physical head keeps flashing without us), a
  /// last DeviceStatus says OFFLINE, the heartbeat says STOPPING.
  void Stop(const ClockReading& now);

  /// The device of a hosted head. Throws `InputError` when the head is not hosted here.
  [[nodiscard]] const TrafficLightDevice& device(SignalHeadId head) const;
  /// The backend of a hosted head (tests inject failures through it). Throws as `device`.
  [[nodiscard]] LampBackend& backend(SignalHeadId head);
  /// The monitor of an intersection, or null when none runs here.
  [[nodiscard]] const ConflictMonitor* monitor(IntersectionId intersection) const;
  /// The id of the last device command a monitor carried out for the followed SCM (what its
  /// DeviceStatus says in `last_command_id`): 0 before any, and again when another SCM is
  /// followed. Throws `InputError` when no monitor watches `intersection` here.
  [[nodiscard]] std::uint64_t last_command_id(IntersectionId intersection) const;
  /// The hosted heads, in id order.
  [[nodiscard]] std::vector<SignalHeadId> heads() const;
  /// What it received and did so far.
  [[nodiscard]] const HostCounters& counters() const { return counters_; }
  /// "infra/<name>".
  [[nodiscard]] const std::string& source() const { return source_; }
  /// The city it serves (config `city`).
  [[nodiscard]] const std::string& city() const { return config_.city; }

 private:
  struct Head;
  struct Monitor;
  struct Dds;
  struct Reports;
  // Who an SCM is: its heartbeat's session id and its heartbeat writer's participant.
  struct ScmId {
    std::uint64_t session = 0;
    dds::ParticipantKey participant;
    bool operator==(const ScmId&) const = default;
  };
  Head& FindHead(SignalHeadId head) const;
  Monitor& FindMonitor(IntersectionId intersection) const;
  // A pass: `Step`, taking the light commands of every head (`all_commands`) or only of those
  // whose readers the loop's waitset saw with data.
  void Pass(const ClockReading& now, bool all_commands);
  void RestartTimeBase(const ClockReading& now);
  [[nodiscard]] bool ScmCurrent(MonoTime now) const;
  void TakeHeartbeats(const ClockReading& now);
  void FollowScm(const ScmId& scm);
  void TakeDeviceCommands(const ClockReading& now);
  void TakeSimFaults(const ClockReading& now);
  void DropLinkTraffic();
  void CarryOut(Monitor& monitor, const ScmId& scm, std::uint64_t command_id,
                const std::string& issued_by, std::uint64_t request_id, const ClockReading& now);
  void ReportIgnoredDeviceCommand(const ClockReading& now, const std::string& reason);
  void TakeCommands(const ClockReading& now, bool all_commands);
  void HoldCommand(Head& head, const dds::ParticipantKey& writer, std::int32_t value);
  void ReportForeignCommand(Head& head, const dds::ParticipantKey& writer, std::int32_t value,
                            const ClockReading& now);
  void DriveLamps(Head& head, const ClockReading& now);
  void CheckMonitors(const ClockReading& now);
  void PublishEvent(const ClockReading& now, Severity severity, const std::string& code,
                    const std::string& message, std::uint32_t intersection_id,
                    const std::string& device_id, bool active);
  void PublishStates();
  void PublishStatuses(const ClockReading& now, bool stopping);
  void PublishHeartbeat(const ClockReading& now, bool stopping);

  InfraConfig config_;
  HostPlan plan_;
  std::string source_;
  std::vector<std::unique_ptr<Head>> heads_;
  std::vector<std::unique_ptr<Monitor>> monitors_;
  std::unique_ptr<Dds> dds_;
  std::unique_ptr<Reports> reports_;
  // The SCM followed now (nothing before its first heartbeat and after a clock restart), and
  // the last one followed (device commands' acknowledgements belong to it).
  std::optional<ScmId> scm_;
  std::optional<ScmId> last_scm_;
  bool scm_running_ = false;  // its last heartbeat said RUNNING
  MonoTime scm_last_running_{};
  std::uint64_t clock_session_ = 0;
  std::uint64_t session_id_ = 0;
  std::uint64_t heartbeat_sequence_ = 0;
  std::uint64_t event_sequence_ = 0;
  std::uint64_t held_sequence_ = 0;
  std::uint64_t last_scm_sequence_ = 0;
  std::optional<MonoTime> next_heartbeat_;
  bool stopped_ = false;
  bool link_cut_ = false;  // the twin's link with the SCM cut (SimFault LINK_CUT)
  HostCounters counters_;
};

}  // namespace autodrive::infrastructure
