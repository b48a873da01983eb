#pragma once
/// @file
/// The Smart City Manager daemon: runs the city's intersection controllers behind the conflict
/// monitor, supervises the traffic-light devices, publishes SPaT, MAP, signs, fleet state, light
/// commands, events and its heartbeat over DDS, answers operator requests and V2I signal
/// requests, and keeps its event log, configuration and modes in SQLite (docs/scm.md).

#include <atomic>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/dds/participant.h"
#include "common/time.h"
#include "scm/city.h"
#include "scm/conflict_monitor.h"
#include "scm/controller.h"

namespace autodrive::scm {

/// How the daemon runs.
struct ScmOptions {
  std::filesystem::path config_path;              ///< the city file
  std::string db_path = "autodrive-scm.db";       ///< the SQLite database (created when missing)
  dds::ParticipantOptions participant;            ///< domain, partition
  Duration tick = std::chrono::milliseconds(20);  ///< control loop period
  Duration spat_period = std::chrono::milliseconds(100);  ///< SPaT, fleet and heartbeat (10 Hz)
};

/// Counters the daemon keeps (status and tests).
struct ScmCounters {
  std::uint64_t ticks = 0;
  std::uint64_t spat_published = 0;
  std::uint64_t operator_requests = 0;
  std::uint64_t malformed_requests = 0;
  std::uint64_t signal_requests = 0;
  std::uint64_t monitor_violations = 0;
};

/// The daemon. Not copyable or movable. `Run` blocks until `Stop`; the other methods are for
/// the loop and tests and must be called from the loop's thread.
class Scm {
 public:
  /// Loads the city (from the database's operator-applied configuration when the file is
  /// unchanged since it was applied, else from the file), opens the database, joins DDS and
  /// publishes MAP and signs. Throws `ConfigError`/`InputError` on a bad file or database.
  Scm(const ScmOptions& options, Clock& clock);
  ~Scm();
  Scm(const Scm&) = delete;
  Scm& operator=(const Scm&) = delete;

  /// Runs the loop until `Stop` (or the clock is interrupted), then tells the devices the SCM
  /// is stopping.
  void Run();
  /// Ends `Run` from any thread (signal handlers included: it only sets a flag and interrupts
  /// the clock).
  void Stop();

  /// One pass of the loop at `now`: requests, devices, controllers, monitor, outputs.
  void Tick(const ClockReading& now);

  [[nodiscard]] const City& city() const;
  [[nodiscard]] ScmCounters counters() const;

 private:
  void PublishStopping();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace autodrive::scm
