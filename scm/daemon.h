#pragma once
/// @file
/// The Smart City Manager daemon: composes the SCM's parts around one control loop.
///
/// The loop (one thread) waits on a `dds::LoopWaitSet` until an operator or V2I request
/// arrives, a controller or a device time-out is due, or the next tick (20 ms) or SPaT (100 ms)
/// comes. Each pass takes what arrived (devices, fleet, requests), applies the supervision
/// rules, steps the controllers that are due behind their conflict monitors, sends the lights
/// what changed, and publishes SPaT, fleet and heartbeat on their period. It never blocks:
/// the database is behind `Persistence`'s writer thread, configurations are loaded and built by
/// `ConfigLoader` off the loop and swapped in whole, every writer is non-blocking, and steady
/// state allocates nothing. See docs/scm.md.

#include <atomic>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/dds/participant.h"
#include "common/time.h"
#include "scm/core/city.h"
#include "scm/core/runtime.h"
#include "scm/store/persistence.h"

namespace autodrive::scm {

/// How the daemon runs.
struct ScmOptions {
  std::filesystem::path config_path;  ///< the city file
  /// The district of the city this SCM runs (`--district`; docs/districts.md), or empty for
  /// the whole city. Every configuration it loads or is sent is narrowed to it.
  std::string district;
  std::string db_path = "autodrive-scm.db";  ///< the SQLite database (created when missing)
  /// Configurations sent by operators may name maps only under this folder. Default: the
  /// parent of the city file's folder (`config/` for `config/cities/x.yaml`).
  std::optional<std::filesystem::path> config_root;
  /// Operators allowed to change state whatever the configuration says (`--operator`): the
  /// way back into a city whose configuration allows no one (docs/scm.md, "Operators").
  std::vector<std::string> operators;
  Duration tick = std::chrono::milliseconds(20);          ///< the loop's longest sleep
  Duration spat_period = std::chrono::milliseconds(100);  ///< SPaT, fleet and heartbeat
  Duration prune_period = std::chrono::minutes(10);       ///< event log retention, checked
  RetentionPolicy retention;
  /// Requests handled per pass at most (the rest wait for the next pass, a moment later). Each
  /// pass reads the clock and publishes what is due, so a flood delays SPaT by at most this
  /// many requests' handling (about 10 us each), not by the whole flood.
  std::size_t max_requests_per_pass = 32;
  /// SPaT is filled this many intersections at a time (about 0.1 ms on a lab PC for 128), and
  /// the loop looks for waiting requests in between; when one waits, a few are answered first.
  /// 0 is taken as 1.
  std::size_t spat_slice = 128;
};

/// Figures of the running daemon, for tests, benchmarks and `scmctl status`.
struct ScmCounters {
  std::uint64_t passes = 0;
  std::uint64_t controller_steps = 0;
  std::uint64_t spat_published = 0;
  std::uint64_t operator_requests = 0;
  std::uint64_t refused_requests = 0;  ///< invalid, rate-limited or not allowed
  std::uint64_t signal_requests = 0;
  std::uint64_t monitor_violations = 0;
  std::uint64_t light_commands = 0;
  std::uint64_t light_resends = 0;
  std::uint64_t write_failures = 0;
  std::uint64_t events = 0;
  std::uint64_t events_dropped = 0;
  std::uint64_t foreign_devices = 0;
  std::uint64_t clock_sessions = 0;  ///< new sessions of the control timeline seen
  /// Observations the fleet's sources recorded (lab vehicles and background traffic objects).
  std::uint64_t fleet_observations = 0;
};

/// The daemon. Not copyable or movable. `Run` blocks until `Stop`; `Pass` is for tests that
/// drive the daemon on a simulated clock.
class Scm {
 public:
  /// Loads the city (from the database's operator-applied configuration when the file is
  /// unchanged since it was applied, else from the file), opens the database, creates its
  /// readers and writers on `participant` (which must outlive it) and publishes MAP and signs.
  /// Throws `ConfigError`/`InputError` on a bad file or database.
  Scm(const ScmOptions& options, Clock& clock, dds::Participant& participant);
  ~Scm();
  Scm(const Scm&) = delete;
  Scm& operator=(const Scm&) = delete;

  /// Runs the loop until `Stop` (or the clock is interrupted), then tells the devices the SCM
  /// is stopping. Tells systemd READY, WATCHDOG and STOPPING when it runs under it.
  void Run();
  /// Ends `Run` from any thread (signal handlers included).
  void Stop();
  /// One pass of the loop at the clock's time.
  void Pass();
  /// The next instant the loop would wake at with no input (tests step a simulated clock to it).
  [[nodiscard]] MonoTime next_deadline() const;
  /// Waits until the sender threads wrote everything the passes so far handed them (SPaT, the
  /// device table): lockstep (`autodrive-scm --lockstep`) then waits for their
  /// acknowledgements.
  void WaitForSenders();
  /// Waits until queued database writes are done (tests).
  void FlushPersistence();

  [[nodiscard]] const City& city() const;
  /// The running intersections (tests look at what the controllers do, pass by pass).
  [[nodiscard]] const CityRuntime& runtime() const;
  [[nodiscard]] ScmCounters counters() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace autodrive::scm
