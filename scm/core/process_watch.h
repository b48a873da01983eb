#pragma once
/// @file
/// Process supervision: what the SCM knows of the city's processes from the launchers' process
/// tables (`autodrive-city`, on /autodrive/scm/processes), and the rules that turn them into
/// events. A process that exits on its own raises the alarm `process_exited` (a warning when it
/// exited with code 0), stamped with the time it died; its return raises `process_restarted`,
/// which clears it. Each exit and each return is logged once, also across the SCM's own
/// restarts: the watch starts from what the event log already holds (`Logged`), so an SCM that
/// was itself killed logs its own death once it is back, from the launcher's last table, and
/// nothing twice. A launcher that falls silent without saying it stops raises `launcher_lost`.
/// No DDS: tables come in as views, with an explicit time, so the rules are tested in-process
/// on a simulated clock. The times are the launchers' timeline: the SCM's control timeline on
/// the wall clock, and this computer's steady clock when the SCM runs on a simulated clock
/// (the launchers report on the wall clock; a simulation run faster than real time would make
/// every launcher look lost). scm/daemon.cpp, `LauncherTime`.

#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "common/process.h"
#include "common/time.h"
#include "scm/core/events.h"

namespace autodrive::scm {

/// The event codes of process supervision (docs/scm.md, "Processes").
inline constexpr std::string_view kProcessExited = "process_exited";
inline constexpr std::string_view kProcessRestarted = "process_restarted";
inline constexpr std::string_view kLauncherLost = "launcher_lost";
inline constexpr std::string_view kLauncherBack = "launcher_back";

/// A process's state as its launcher says; the values are the wire's (ProcessEntry_Constants).
enum class ProcessPhase : std::uint8_t {
  kWaiting = 0,    ///< not started yet
  kStarting = 1,   ///< started, not ready yet
  kRunning = 2,    ///< ready
  kExited = 3,     ///< exited; started again at its `restart_at`
  kCrashLoop = 4,  ///< exited too often; started again at its `restart_at`
  kStopped = 5,    ///< stopped by the launcher, or exited with no restart due
};
/// The phase with wire value `value`, or nothing when it is none.
[[nodiscard]] std::optional<ProcessPhase> ProcessPhaseFromWire(std::uint8_t value);

/// What a launcher is doing; the values are the wire's (ProcessTable_Constants).
enum class LauncherPhase : std::uint8_t { kStarting = 0, kRunning = 1, kStopping = 2 };
/// The launcher phase with wire value `value`, or nothing when it is none.
[[nodiscard]] std::optional<LauncherPhase> LauncherPhaseFromWire(std::uint8_t value);

/// A process's last exit on its own (not a stop by its launcher).
struct ProcessExit {
  ExitStatus status;
  std::int32_t pid = 0;  ///< the pid it had (0: unknown)
  Time at{};             ///< when its launcher saw it end (the launcher's wall clock)
};

/// One row of a process table, as views into the sample (valid for the call only).
struct ProcessView {
  std::string_view name;
  ProcessPhase phase = ProcessPhase::kWaiting;
  std::int32_t pid = 0;                  ///< 0 when it does not run
  std::uint32_t starts = 0;              ///< times its launcher started it
  Time since{};                          ///< when it entered its phase
  std::uint32_t exits = 0;               ///< times it exited on its own
  std::optional<ProcessExit> last_exit;  ///< set when `exits` > 0
  Time restart_at{};                     ///< kExited, kCrashLoop: when it starts again
};

/// One launcher's table, as views into the sample (valid for the call only).
struct ProcessTableView {
  std::string_view city;
  std::string_view host;      ///< the launcher's host
  std::uint64_t session = 0;  ///< random per launcher start
  LauncherPhase phase = LauncherPhase::kRunning;
  Duration period = std::chrono::seconds(1);  ///< the launcher's promised period
  std::span<const ProcessView> processes;
};

/// The rules' parameters.
struct ProcessWatchParams {
  std::string city;  ///< our city's name: other cities' tables are ignored
  /// A launcher not heard for this many of its periods (at least `min_lost_after`) is lost.
  int lost_after_periods = 3;
  Duration min_lost_after = std::chrono::seconds(2);
  /// After the SCM's own stall, how long the reports sent meanwhile get to arrive before a
  /// launcher's silence counts again.
  Duration stall_settle = std::chrono::milliseconds(500);
};

/// Counts of tables and what was not obeyed.
struct ProcessWatchCounters {
  std::uint64_t tables = 0;
  std::uint64_t foreign_city = 0;   ///< tables of another city's launchers
  std::uint64_t over_capacity = 0;  ///< processes or launchers beyond the bounds, not watched
};

/// Watches the city's processes. Single-threaded (the loop's). Not copyable.
class ProcessWatch {
 public:
  /// Launchers and processes watched at most (the rest are counted, not watched).
  static constexpr std::size_t kMaxLaunchers = 64;
  static constexpr std::size_t kMaxProcesses = 1024;

  explicit ProcessWatch(ProcessWatchParams params);
  ProcessWatch(const ProcessWatch&) = delete;
  ProcessWatch& operator=(const ProcessWatch&) = delete;

  /// The device id of process `name` in events: "process/<name>".
  [[nodiscard]] static std::string DeviceId(std::string_view name);

  /// What the event log already holds: its newest event `code` (`kProcessExited` or
  /// `kProcessRestarted`) about `device` ("process/<name>") was at `at`. Exits and returns up
  /// to then are not logged again. Call before the first table (at start-up); other codes and
  /// devices are ignored.
  void Logged(std::string_view code, std::string_view device, Time at);
  /// Takes one table received at `now`: raises `process_exited` for each exit not logged yet
  /// (stamped when the process died), then `process_restarted` for each return not logged yet
  /// (stamped when it was back), and `launcher_back` for a lost launcher heard again.
  void Report(const ProcessTableView& table, MonoTime now, EventSink& events);
  /// At `now`: a launcher not heard for its time-out, that did not say it was stopping, is
  /// lost (`launcher_lost`).
  void Check(MonoTime now, EventSink& events);
  /// The SCM's own loop stalled and resumed at `resumed`: no launcher is declared lost before
  /// `resumed + stall_settle` (its tables of that time may still be on their way in).
  void OnStall(MonoTime resumed);
  /// The next instant at which a rule may fire with no new table.
  [[nodiscard]] MonoTime next_deadline() const;

  /// The launchers heard and not lost.
  [[nodiscard]] std::size_t launchers() const;
  [[nodiscard]] const ProcessWatchCounters& counters() const { return counters_; }

 private:
  /// What is logged of one process (of one launcher's host): its newest exit and return.
  struct Logs {
    Time exit{};
    Time restart{};
  };
  struct Launcher {
    std::uint64_t session = 0;
    MonoTime last_heard{};
    Duration lost_after{};
    LauncherPhase phase = LauncherPhase::kRunning;
    bool lost = false;
  };
  void ReportProcess(const ProcessTableView& table, const ProcessView& p, EventSink& events);
  /// The logs of process `name` on `host`, from what the event log held at start; null when
  /// no more processes can be watched.
  Logs* LogsOf(std::string_view host, std::string_view name);

  ProcessWatchParams params_;
  std::map<std::string, Logs, std::less<>> logged_;         ///< by device id, from the event log
  std::map<std::string, Logs, std::less<>> processes_;      ///< by "host\0name"
  std::map<std::string, Launcher, std::less<>> launchers_;  ///< by host
  std::string key_;  ///< scratch "host\0name": a table of known processes allocates nothing
  ProcessWatchCounters counters_;
  MonoTime settle_until_{};
};

}  // namespace autodrive::scm
