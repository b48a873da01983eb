#pragma once
/// @file
/// The logic of one traffic light head (`signal_<i>`): which commands it accepts, its local
/// fail-safe on a lost SCM heartbeat, its flashing cadence and its health. Pure: no DDS, no
/// I/O, no clock of its own; every call takes the current `MonoTime` from the process's `Clock`,
/// so the rules are tested on a `SimClock` (see docs/infrastructure.md, "Fail-safe rules").

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/aspect.h"
#include "common/ids.h"
#include "common/time.h"
#include "infrastructure/lamps.h"

namespace autodrive::infrastructure {

/// True when a head showing `from` may be commanded straight to `to`: the same aspect; any
/// aspect to off, flashing red or flashing yellow; red to green; green to yellow; yellow to
/// red; off or flashing to red. Everything else is refused (green to red, yellow to green, red
/// to yellow, off or flashing to green or yellow).
[[nodiscard]] bool IsLegalTransition(Aspect from, Aspect to);

/// Why `from -> to` is refused, e.g. "a green must end in yellow"; empty when it is legal.
[[nodiscard]] std::string_view RefusalRule(Aspect from, Aspect to);

/// DeviceStatus health; the values are the wire values (DeviceStatus_Constants), in order of
/// severity.
enum class Health : std::uint8_t { kOk = 0, kDegraded = 1, kFault = 2, kOffline = 3 };
/// DeviceStatus mode; the values are the wire values.
enum class Mode : std::uint8_t { kNormal = 0, kFlash = 1, kDark = 2 };
/// Event severity; the values are the wire values (Event_Constants).
enum class Severity : std::uint8_t {
  kDebug = 0,
  kInfo = 1,
  kWarning = 2,
  kAlarm = 3,
  kCritical = 4
};
/// "ok", "degraded", "fault", "offline".
[[nodiscard]] std::string_view ToString(Health health);
/// "normal", "flash", "dark".
[[nodiscard]] std::string_view ToString(Mode mode);

/// The state field of the SCM's heartbeat (Heartbeat_Constants).
enum class ScmState : std::uint8_t { kStarting = 0, kRunning = 1, kStopping = 2 };

/// What a device needs from one SCM heartbeat (sender "scm").
struct ScmHeartbeat {
  /// Which SCM: a change is a restart of the SCM. The host passes a number that changes
  /// whenever the SCM it follows changes (its session id or its DDS participant).
  std::uint64_t session_id = 0;
  std::uint64_t sequence_number = 0;  ///< increments per heartbeat
  ScmState state = ScmState::kRunning;
};

/// Something a device reports on the events topic. The host adds source, device id and time.
struct DeviceEvent {
  Severity severity = Severity::kInfo;
  std::string code;     ///< stable: "illegal_sequence", "illegal_command", "local_flash", ...
  std::string message;  ///< human-readable, names the device
  bool active = true;   ///< alarms: raised (true) or cleared (false)
};

/// The fixed parameters of a device.
struct DeviceParams {
  SignalHeadId id{0};
  /// Flash on our own when no RUNNING heartbeat of the SCM came for longer than this.
  Duration scm_heartbeat_timeout = std::chrono::seconds(1);
  /// One on+off cycle of a flashing aspect.
  Duration flash_period = std::chrono::seconds(1);
};

/// One traffic light head's logic.
///
/// Inputs: SCM heartbeats (`OnHeartbeat`), commanded aspects (`OnCommand`, the wire value of
/// `signal_<i>/command`), lamp feedback from its backend (`OnFeedback`), the conflict monitor
/// (`ForceFlash` / `ReleaseForce`) and the passing of time (`Update`). Outputs: the aspect it
/// displays (`aspect`) and the lamps to light at an instant (`LampsAt`), its mode, health and
/// detail for DeviceStatus, and events (`TakeEvents`).
///
/// Rules (docs/infrastructure.md): commands are accepted only along legal transitions
/// (`IsLegalTransition`); an illegal one is refused: the head keeps its aspect, health becomes
/// DEGRADED until a command is accepted, and an "illegal_sequence" WARNING event is raised. The
/// head shows flashing red on its own (mode FLASH) at start-up until it has both an SCM
/// heartbeat and a command, when the heartbeat is missing longer than the timeout, when the SCM
/// says it is stopping, and when the SCM restarts (new session). After a loss it stays in flash
/// until a command sample received while the heartbeat is back is legal from flashing red (red,
/// off or a flashing aspect): the command it last had does not take it back. While forced by
/// the conflict monitor it shows flashing red and ignores commands; after the release it waits
/// for a new command the same way.
///
/// Not thread-safe; copyable (a value of the state).
class TrafficLightDevice {
 public:
  /// A device that starts in flashing red, waiting for the SCM. `now` starts the flashing.
  TrafficLightDevice(const DeviceParams& params, MonoTime now);

  /// An SCM heartbeat (the caller filters sender "scm") received at `now`.
  void OnHeartbeat(const ScmHeartbeat& heartbeat, MonoTime now);
  /// A command sample received at `now`: the wire value of `signal_<i>/command`. A value that
  /// is not an aspect (0..5) is refused and counted (never throws).
  void OnCommand(std::int32_t wire_value, MonoTime now);
  /// Lets time pass: detects a missing heartbeat. Call every tick, before `LampsAt`.
  void Update(MonoTime now);
  /// What the backend reports; sets health FAULT (failed lamps) or OFFLINE.
  void OnFeedback(const LampFeedback& feedback);
  /// The conflict monitor latched: show flashing red and ignore commands until released.
  /// `reason` goes into the detail.
  void ForceFlash(const std::string& reason, MonoTime now);
  /// The conflict monitor was reset: stay in flash until a new legal command comes (as after a
  /// lost heartbeat). No effect when not forced. A command received in the same instant after
  /// the release (`OnCommand` called after this) is new and can end the flash; one received
  /// before it cannot.
  void ReleaseForce(MonoTime now);
  /// The time base restarted (a simulator restart: a new session of the simulated clock), and
  /// every instant remembered so far means nothing on the new timeline. The device goes back to
  /// its start-up state: flashing red from `now`, waiting for the SCM's heartbeat; the latest
  /// command it has counts as a latched one (it ends the flash once the heartbeat is there, if
  /// it is red, off or flashing). Raises an active "local_flash" event naming `reason`. A forced
  /// flash stays forced; lamp faults and the backend state are kept.
  void Restart(const std::string& reason, MonoTime now);
  /// The next instant after `now` at which the device changes on its own if nothing arrives:
  /// the next on/off edge of a flashing aspect, or the SCM's heartbeat timing out. The loop
  /// wakes at that instant (see `DeviceHost::Run`). `MonoTime::max()` when nothing is pending.
  [[nodiscard]] MonoTime NextChange(MonoTime now) const;

  /// The aspect displayed now (flashing red in fail-safe).
  [[nodiscard]] Aspect aspect() const { return shown_; }
  /// The lamps to light at `now`: a flashing aspect is on for the first half of each period,
  /// counted from when it started.
  [[nodiscard]] Lamps LampsAt(MonoTime now) const;
  /// NORMAL (showing what the SCM commands), FLASH (local fail-safe or forced by the monitor),
  /// DARK (commanded off).
  [[nodiscard]] Mode mode() const;
  /// The worst of: OFFLINE (backend), FAULT (failed lamps), DEGRADED (a refused command).
  [[nodiscard]] Health health() const;
  /// Why the device is not OK or not NORMAL, e.g. "lost SCM heartbeat; waiting for a new red,
  /// off or flashing command"; empty when all is well. Parts are joined by "; ".
  [[nodiscard]] std::string detail() const;
  /// The sequence number of the last SCM heartbeat seen (0 before any).
  [[nodiscard]] std::uint64_t last_scm_sequence() const { return last_scm_sequence_; }
  /// True while the SCM's heartbeat is current.
  [[nodiscard]] bool scm_alive() const { return alive_; }
  /// True while in local fail-safe flash (not counting a forced flash).
  [[nodiscard]] bool in_fail_safe() const { return fail_safe_.has_value(); }
  /// True while forced by the conflict monitor.
  [[nodiscard]] bool forced() const { return forced_.has_value(); }
  /// Commands refused because of an illegal transition.
  [[nodiscard]] std::uint64_t refused_commands() const { return refused_commands_; }
  /// Commands refused because the value was not an aspect.
  [[nodiscard]] std::uint64_t malformed_commands() const { return malformed_commands_; }
  /// The events raised since the last call, oldest first.
  [[nodiscard]] std::vector<DeviceEvent> TakeEvents();
  /// "signal_<i>".
  [[nodiscard]] const std::string& name() const { return name_; }
  /// The head's id.
  [[nodiscard]] SignalHeadId id() const { return params_.id; }
  /// A number that changes whenever anything the accessors above report may have changed
  /// (aspect, lamps, mode, health, detail, events), except the heartbeat's sequence number and
  /// the passing of time (`NextChange` says when that matters): a host of many heads skips
  /// those whose revision and deadlines did not move.
  [[nodiscard]] std::uint64_t revision() const { return revision_; }

 private:
  void Show(Aspect aspect, MonoTime now);
  void EnterFailSafe(const std::string& reason, MonoTime now);
  void TryLeaveFailSafe(MonoTime now);
  void Raise(Severity severity, std::string code, std::string message, bool active);

  DeviceParams params_;
  std::string name_;
  Aspect shown_ = Aspect::kFlashingRed;
  MonoTime flash_start_;

  // SCM liveness.
  bool alive_ = false;
  MonoTime last_running_{};
  std::optional<std::uint64_t> session_;
  std::uint64_t last_scm_sequence_ = 0;

  // Commands.
  std::optional<Aspect> command_;  // the latest valid command
  bool command_usable_ = false;    // it may end a fail-safe flash
  bool needs_fresh_command_ = false;

  std::optional<std::string> fail_safe_;  // reason for the local fail-safe flash
  std::optional<std::string> forced_;     // reason for the monitor's forced flash
  std::optional<std::string> refusal_;    // the last refused command, until one is accepted
  bool local_flash_raised_ = false;       // a "local_flash" event is active

  // Backend feedback.
  bool online_ = true;
  std::string offline_reason_;
  std::vector<LampFault> faults_;

  std::uint64_t refused_commands_ = 0;
  std::uint64_t malformed_commands_ = 0;
  std::vector<DeviceEvent> events_;
  std::uint64_t revision_ = 0;
};

}  // namespace autodrive::infrastructure
