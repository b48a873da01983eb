#pragma once
/// @file
/// Runs a city's processes (a `LaunchPlan`): starts them in order, each once the one before is
/// ready; restarts one that exits as its policy says (the SCM at once), reports a crash loop
/// instead of hiding it; stops them in reverse order, so that the lights stop last and flash
/// on their own once the SCM has gone. Each process's output goes to its log file; the state
/// of every process is kept in the run folder's `status.json` for `autodrive-city status`.

#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "city/launcher/launch_config.h"

#include "common/dds/participant.h"
#include "common/error.h"
#include "common/process.h"

namespace autodrive::launcher {

/// A process did not start or did not become ready: its name, what happened and its log.
class LaunchError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class Phase {
  kWaiting,    ///< not started yet
  kStarting,   ///< started, not ready yet
  kRunning,    ///< ready
  kExited,     ///< exited; to be started again
  kCrashLoop,  ///< exited too often: started again only after the window
  kStopped,    ///< stopped by us, or exited with no restart due
};

[[nodiscard]] const char* PhaseName(Phase phase);

/// One process as the launcher runs it: `status.json`'s row and the process table's
/// (city/launcher/process_table.h).
struct ProcessState {
  std::string name;
  Phase phase = Phase::kWaiting;
  pid_t pid = -1;
  int starts = 0;
  std::optional<int> last_exit;  ///< exit code (128 + signal), a stop by the launcher included
  std::chrono::system_clock::time_point since{};  ///< when it entered its phase
  std::string log;
  /// Its exits on its own (not stopped by the launcher): how many, and the last one's status,
  /// pid and time.
  int exits = 0;
  std::optional<ExitStatus> exit;
  pid_t exit_pid = -1;
  std::chrono::system_clock::time_point exited_at{};
  /// kExited, kCrashLoop: when it is started again.
  std::chrono::system_clock::time_point restart_at{};
  /// For people: "killed by signal 9 (SIGKILL); restart 1 in 1.0 s", "running (restart 1)".
  std::string detail;
};

class Supervisor {
 public:
  /// `say` gets a line for each thing a person should know (started, ready, exited, restarted,
  /// crash loop, stopped). `participant` must outlive it; it watches the SCM's and the device
  /// hosts' heartbeats, /clock and the traffic topic for readiness, and writes the process
  /// table on `/autodrive/scm/processes` on every change and every second (under DDS Security,
  /// what the `launcher` role may read and write: docs/security.md). In a city of districts,
  /// `districts` holds a participant on each district's domain (which must outlive it too): the
  /// districts' SCMs and light hosts are heard there, and the table is written there as well.
  /// @throws LaunchError when a process is ready on a domain none of them is on.
  Supervisor(LaunchPlan plan, const dds::Participant& participant,
             std::function<void(const std::string&)> say,
             const std::vector<const dds::Participant*>& districts = {});
  Supervisor(const Supervisor&) = delete;
  Supervisor& operator=(const Supervisor&) = delete;
  /// Stops what still runs (`Down`).
  ~Supervisor();

  /// Starts every process in order, each once the one before is ready, until `stop`. Throws
  /// `LaunchError` when one exits before it is ready or is not ready in time (what started
  /// keeps running: `Down` stops it).
  void Up(const std::atomic<bool>& stop);
  /// Until `stop`: starts again what exits, as its policy says; a process that exits
  /// `crash_loop_exits` times within the window is reported and started again only once the
  /// window has passed since its first exit in it. Returns early once every process ended with
  /// none to be started again (a lockstep run whose simulator ended).
  void Supervise(const std::atomic<bool>& stop);
  /// Stops every process in reverse start order (SIGTERM, SIGKILL after the grace period).
  void Down();

  [[nodiscard]] std::vector<ProcessState> states() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace autodrive::launcher
