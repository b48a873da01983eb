#pragma once
/// @file
/// The SCM's persistence: an SQLite database holding the event log, the city configurations
/// that were applied, and the per-intersection state to restore after a restart.
///
/// Durability: the database runs in WAL mode and every write is one transaction, so a daemon
/// killed at any moment (SIGKILL included) loses nothing it had committed and never leaves a
/// corrupt file; SQLite rolls back an interrupted transaction when the file is next opened.
/// Events are written with `synchronous=NORMAL` (a power cut may lose the last events committed
/// before it, never corrupt the file); applied configurations and intersection states are
/// written with `synchronous=FULL` (they survive a power cut once the call returns). See
/// store.cpp for why.

#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "common/ids.h"
#include "common/time.h"
#include "scm/core/events.h"

namespace autodrive::scm {

/// A failure of the database itself (disk full, I/O error, database locked for too long), with
/// SQLite's extended result code. Bad input (a missing directory, a file that is not an SCM
/// database, a newer schema) is an `InputError` instead.
class StoreError : public std::runtime_error {
 public:
  /// `what` names the operation and SQLite's message; `code` is SQLite's extended result code.
  StoreError(const std::string& what, int code) : std::runtime_error(what), code_(code) {}
  /// SQLite's extended result code (`SQLITE_*`).
  [[nodiscard]] int code() const { return code_; }

 private:
  int code_;
};

/// One entry of the event log.
struct EventRecord {
  std::int64_t id = 0;  ///< row id, 1, 2, 3, ... in append order; set by `Store::AppendEvent`
  Time time{};          ///< when it happened, in the system's clock
  Severity severity = Severity::kInfo;
  std::string source;              ///< who raised it, e.g. "scm/conflict_monitor"
  std::string code;                ///< stable machine-readable code, e.g. "conflict_green"
  std::string message;             ///< human-readable text
  IntersectionId intersection{0};  ///< 0 when not about an intersection
  std::string device_id;           ///< empty when not about a device
  std::string actor;               ///< who caused it: an operator client id, or "scm"
  bool active = false;             ///< alarms: true raised, false cleared
  bool operator==(const EventRecord&) const = default;
};

/// The newest event of one code about one device (`Store::LatestProcessEvents`).
struct LatestDeviceEvent {
  std::string code;
  std::string device_id;
  Time time{};
  bool operator==(const LatestDeviceEvent&) const = default;
};

/// Which events `Store::Events` returns, and in what order.
struct EventQuery {
  /// Only events with `time >= since`.
  std::optional<Time> since;
  /// Only events with `id > after_id` (to page through the log, or to poll for new ones).
  std::optional<std::int64_t> after_id;
  /// At most this many events.
  std::size_t limit = 1000;
  /// False: the oldest matching events, in append order. True: the newest matching events,
  /// newest first (a dashboard's "last 100").
  bool newest_first = false;
};

/// One event of an intersection's high-resolution log (docs/controller.md, "High-resolution
/// event log"): an Indiana enumeration code and its parameter.
struct HiresRecord {
  IntersectionId intersection{0};
  Time time{};
  std::uint16_t code = 0;
  std::uint16_t param = 0;
  bool operator==(const HiresRecord&) const = default;
};

/// Which records `Store::Hires` returns: those of one intersection (or all, with id 0) with
/// `since <= time < until`, in time order (and append order within a time).
struct HiresQuery {
  IntersectionId intersection{0};
  Time since{};
  Time until{};
  std::size_t limit = 100000;
};

/// A city configuration as it was applied.
struct AppliedConfig {
  std::int64_t id = 0;     ///< 1, 2, 3, ... in the order applied
  std::string path;        ///< the file it was read from
  std::string yaml;        ///< the full YAML text
  std::string hash;        ///< `ContentHash(yaml)`
  std::string applied_by;  ///< operator client id, or "scm" for the configuration at start-up
  Time applied_at{};
  bool operator==(const AppliedConfig&) const = default;
};

/// An entry of the configuration history: an `AppliedConfig` without its text.
struct AppliedConfigSummary {
  std::int64_t id = 0;
  std::string path;
  std::string hash;
  std::string applied_by;
  Time applied_at{};
  bool operator==(const AppliedConfigSummary&) const = default;
};

/// What to restore for one intersection after a restart.
/// An operator's phase control in force (docs/controller.md, "Phase controls"), kept so that a
/// restarted SCM puts it back for the time it has left.
struct PhaseControlRecord {
  std::string control;      ///< "omit", "hold", "force_off", "call", ...; not empty
  std::string plan;         ///< the plan's name
  std::uint32_t phase = 0;  ///< its phase number in that plan, 1..255
  Time until{};             ///< when it ends (wall time)
  bool operator==(const PhaseControlRecord&) const = default;
};

struct IntersectionStateRecord {
  IntersectionId intersection{0};
  std::string mode;              ///< e.g. "fixed", "actuated", "manual", "flash", "dark"; not empty
  std::string plan;              ///< the signal plan's name; may be empty
  bool operator_chosen = false;  ///< true when an operator chose this mode and plan
  Time updated_at{};             ///< when it was last saved
  std::vector<PhaseControlRecord> controls;  ///< the phase controls in force, saved with it
  bool operator==(const IntersectionStateRecord&) const = default;
};

/// A content hash of `text`: 64-bit FNV-1a (offset basis 0xcbf29ce484222325, prime
/// 0x100000001b3) over its bytes, as 16 lower-case hex digits. It tells whether two
/// configurations are the same text; it is not a cryptographic hash (it does not resist a
/// deliberate collision).
[[nodiscard]] std::string ContentHash(std::string_view text);

/// The SCM's database (see the file comment). Opened on a file, which it creates when
/// missing; `":memory:"` opens a private in-memory database (tests).
///
/// All methods are thread-safe (one connection behind a mutex). Move-only; a moved-from
/// Store may only be destroyed or assigned to.
class Store {
 public:
  /// The schema version this build writes and reads (`PRAGMA user_version`).
  static constexpr int kSchemaVersion = 1;
  /// Marks a file as an SCM database (`PRAGMA application_id`), "ADSC".
  static constexpr std::int32_t kApplicationId = 0x41445343;

  /// Opens (creating when missing) the database at `path`, or an in-memory one for
  /// `":memory:"`. Creates the schema in a new file.
  /// @throws InputError naming the path when its directory does not exist, when the file is
  ///   not an SQLite database or belongs to another application, or when its schema version is
  ///   newer than `kSchemaVersion` (a newer SCM wrote it: this one refuses rather than guess).
  /// @throws StoreError when SQLite fails otherwise (permissions, I/O, locked).
  explicit Store(const std::string& path);
  ~Store();
  Store(Store&&) noexcept;
  Store& operator=(Store&&) noexcept;
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  /// The path it was opened on.
  [[nodiscard]] const std::string& path() const;

  // ---- Event log --------------------------------------------------------------------------

  /// Appends `event` and returns its row id. With `event.id` 0 the id is the next one: 1 for
  /// the first event of the database, then one more each time; with `event.id` set (the SCM
  /// numbers its events as it raises them, from `LastEventId`, so that an event has the same
  /// id live and in the log) that id, which must be above every id used so far. Ids are never
  /// reused.
  /// @throws StoreError when the write fails (an id already used included); nothing is written
  ///   then.
  std::int64_t AppendEvent(const EventRecord& event);

  /// Appends `events` in one transaction (the writer thread's batches) and returns the row id
  /// of the last one (0 when `events` is empty). All or nothing.
  /// @throws StoreError when the write fails; nothing is written then.
  std::int64_t AppendEvents(const std::vector<EventRecord>& events);

  /// Deletes the events older than `before` (when given) and all but the newest `keep_newest`.
  /// Returns how many were deleted. Ids are never reused. Freed pages are reused by later
  /// events, so a pruned log keeps the file's size flat.
  /// @throws StoreError when the write fails.
  std::int64_t PruneEvents(std::optional<Time> before, std::int64_t keep_newest);

  /// The events matching `query` (see `EventQuery` for the order).
  /// @throws InputError when `query.limit` is 0 or above 1000000.
  [[nodiscard]] std::vector<EventRecord> Events(const EventQuery& query) const;

  /// The number of events in the log.
  [[nodiscard]] std::int64_t EventCount() const;

  /// The largest event id ever used (pruned events included), 0 for a new database: the SCM
  /// numbers its events from the next one.
  [[nodiscard]] std::int64_t LastEventId() const;

  /// For each process event code (`process_exited`, `process_restarted`: scm/core/
  /// process_watch.h) and device, the time of the newest such event: what the SCM's process
  /// watch has already logged when it starts. Read through an index of those events alone, not
  /// the whole log.
  [[nodiscard]] std::vector<LatestDeviceEvent> LatestProcessEvents() const;

  // ---- High-resolution log ----------------------------------------------------------------

  /// Appends `records` in one transaction. All or nothing.
  /// @throws StoreError when the write fails; nothing is written then.
  void AppendHires(const std::vector<HiresRecord>& records);

  /// The records matching `query`.
  /// @throws InputError when `query.limit` is 0 or above 1000000, or `until` is before `since`.
  [[nodiscard]] std::vector<HiresRecord> Hires(const HiresQuery& query) const;

  /// Deletes the records older than `before` (when given) and all but the newest
  /// `keep_newest`. Returns how many were deleted. @throws StoreError when the write fails.
  std::int64_t PruneHires(std::optional<Time> before, std::int64_t keep_newest);

  /// The number of records in the log.
  [[nodiscard]] std::int64_t HiresCount() const;

  // ---- Applied configuration --------------------------------------------------------------

  /// Records that the configuration `yaml`, read from `path`, was applied by `applied_by` at
  /// `applied_at`. Returns its id. Durable once it returns (`synchronous=FULL`).
  /// @throws StoreError when the write fails; nothing is written then.
  std::int64_t SaveAppliedConfig(std::string_view path, std::string_view yaml,
                                 std::string_view applied_by, Time applied_at);

  /// The configuration applied last, or nothing when none was.
  [[nodiscard]] std::optional<AppliedConfig> LatestConfig() const;

  /// The configuration with id `id`, or nothing when there is none.
  [[nodiscard]] std::optional<AppliedConfig> ConfigById(std::int64_t id) const;

  /// The configurations applied, newest first, at most `limit`.
  /// @throws InputError when `limit` is 0 or above 1000000.
  [[nodiscard]] std::vector<AppliedConfigSummary> ConfigHistory(std::size_t limit = 100) const;

  /// Deletes all but the newest `keep_newest` applied configurations, always keeping the newest
  /// one applied by "scm" (the start-up record that start-up decisions rely on). Returns how
  /// many were deleted.
  /// @throws InputError when `keep_newest` is 0. @throws StoreError when the write fails.
  std::int64_t PruneConfigs(std::size_t keep_newest);

  /// The number of applied configurations kept.
  [[nodiscard]] std::int64_t ConfigCount() const;

  // ---- Per-intersection state -------------------------------------------------------------

  /// Inserts or replaces the state of `state.intersection`. Durable once it returns.
  /// @throws InputError when the intersection id is 0 or the mode is empty.
  /// @throws StoreError when the write fails; nothing is written then.
  void SaveIntersectionState(const IntersectionStateRecord& state);

  /// Every saved intersection state, by intersection id.
  [[nodiscard]] std::vector<IntersectionStateRecord> LoadIntersectionStates() const;

  // ---- Maintenance ------------------------------------------------------------------------

  /// SQLite's `PRAGMA integrity_check`: "ok", or its list of problems one per line. Reads the
  /// whole file: for start-up checks, tools and tests, not for the daemon's loop.
  [[nodiscard]] std::string IntegrityCheck() const;

  /// The size of the database in bytes (pages in use and free), not counting the WAL file,
  /// which checkpoints keep below 64 MiB (`journal_size_limit`).
  [[nodiscard]] std::int64_t SizeBytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace autodrive::scm
