#pragma once
/// @file
/// The SCM's database behind a writer thread: the control loop hands it work through a bounded
/// queue and never waits for SQLite (an fsync takes milliseconds; a busy disk, much longer).
/// Results (query answers, a saved configuration's id) come back to the loop as completions it
/// runs on its own thread.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/time.h"
#include "scm/store/store.h"

namespace autodrive::scm {

/// How long the event log and the configuration history are kept (docs/scm.md, "Persistence").
struct RetentionPolicy {
  Duration max_event_age = std::chrono::hours(24 * 90);  ///< events older than this go
  std::int64_t max_events = 1'000'000;                   ///< and all but the newest this many
  std::size_t max_configs = 100;  ///< applied configurations kept (plus the start-up record)
  /// High-resolution records kept at most (older than `max_event_age` go too): about two months
  /// of a lab's four intersections, an hour and a half of a 32 x 32 grid city.
  std::int64_t max_hires = 5'000'000;
};

/// What the writer thread did so far.
struct PersistenceStats {
  std::uint64_t events_written = 0;
  std::uint64_t events_dropped = 0;  ///< the queue was full: the loop never waits
  std::uint64_t events_pruned = 0;
  std::uint64_t configs_pruned = 0;
  std::uint64_t states_written = 0;
  std::uint64_t hires_written = 0;
  std::uint64_t hires_dropped = 0;  ///< the queue was full
  std::uint64_t hires_pruned = 0;
  std::uint64_t failures = 0;    ///< SQLite errors (logged)
  std::int64_t event_count = 0;  ///< events in the log
  std::int64_t size_bytes = 0;   ///< database size after the last prune
  std::size_t queued = 0;        ///< jobs waiting now
};

/// Owns the `Store` and a writer thread. Every method is for the loop's thread except where
/// said; none blocks on SQLite (except `Flush` and the destructor, which wait for the queue).
/// Not copyable or movable.
class Persistence {
 public:
  /// Events the queue holds at most; further events are dropped and counted.
  static constexpr std::size_t kMaxQueuedEvents = 8192;
  /// High-resolution records the queue holds at most; further ones are dropped and counted.
  static constexpr std::size_t kMaxQueuedHires = 65536;

  /// Takes the store. `wake` is called from the writer thread when a completion is ready for
  /// the loop (`RunCompletions`); it must be quick and thread-safe (a waitset's `Wake`).
  Persistence(Store store, std::function<void()> wake);
  Persistence(const Persistence&) = delete;
  Persistence& operator=(const Persistence&) = delete;
  /// Writes what is queued, then stops the thread.
  ~Persistence();

  /// Queues an event for the log. Returns false (and counts it) when the queue is full.
  bool AppendEvent(EventRecord event);
  /// Queues high-resolution records for the log; those that do not fit are dropped and counted.
  void AppendHires(const std::vector<HiresRecord>& records);
  /// Runs `query` on the writer thread, then `done(records or error)` on the loop.
  void QueryHires(HiresQuery query,
                  std::function<void(std::vector<HiresRecord> records, std::string error)> done);
  /// Saves an intersection's operator state. Coalesced per intersection (the newest wins) and
  /// never dropped; durable once written (synchronous=FULL).
  void SaveIntersectionState(IntersectionStateRecord state);
  /// Records an applied configuration (durable), then calls `done(id or error)` on the loop.
  void SaveAppliedConfig(
      std::string path, std::string yaml, std::string applied_by, Time at,
      std::function<void(std::optional<std::int64_t> id, std::string error)> done);
  /// Runs `query` on the writer thread, then `done(events or error)` on the loop.
  void QueryEvents(EventQuery query,
                   std::function<void(std::vector<EventRecord> events, std::string error)> done);
  /// Prunes the event log (by `now` minus the age, and by count) and the configuration history.
  void Prune(Time now, const RetentionPolicy& policy);

  /// Runs the completions that are ready, on the calling (loop) thread. Cheap when none are.
  void RunCompletions();
  /// Blocks until everything queued so far is written and its completions are ready (tests,
  /// shutdown).
  void Flush();
  /// Counters (thread-safe).
  [[nodiscard]] PersistenceStats stats() const;
  /// The store, for start-up reads before the loop runs and for tests; its methods are
  /// thread-safe but may block.
  [[nodiscard]] Store& store() { return store_; }

 private:
  using Job = std::function<void()>;
  void Post(Job job);
  void Complete(std::function<void()> completion);
  void Run(const std::stop_token& stop);

  Store store_;
  std::function<void()> wake_;
  mutable std::mutex mutex_;
  std::condition_variable_any cv_;
  std::condition_variable idle_cv_;
  std::deque<EventRecord> events_;
  /// Swapped whole with the writer's buffer (both keep their capacity: queueing allocates
  /// nothing once warm).
  std::vector<HiresRecord> hires_;
  std::map<std::uint32_t, IntersectionStateRecord> states_;
  std::deque<Job> jobs_;
  bool busy_ = false;
  std::vector<std::function<void()>> completions_;
  std::atomic<bool> has_completions_{false};
  PersistenceStats stats_;
  std::jthread thread_;  // last: started after everything it uses
};

}  // namespace autodrive::scm
