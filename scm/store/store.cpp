#include "scm/store/store.h"

#include <sqlite3.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <mutex>
#include <sstream>
#include <utility>

#include "common/error.h"

// Why two synchronous levels. In WAL mode a commit appends the transaction to the WAL file;
// with synchronous=NORMAL the WAL is fsync'ed only at checkpoints, with FULL at every commit.
// Either way a killed *process* loses nothing it committed (the data is in the kernel's page
// cache) and SQLite's atomic commit means the file is never corrupt. The difference is a power
// cut or kernel crash: NORMAL may then lose the last transactions (never corrupt the file). The
// event log is written often (several events a second when things go wrong), so an fsync per
// event would cost milliseconds on the daemon's loop for a guarantee nobody needs; events use
// NORMAL. Applied configurations and intersection states are rare operator decisions that the
// SCM must come back with after any restart, power cuts included (an operator who put an
// intersection into flash must find it in flash), so those transactions switch to FULL.

namespace autodrive::scm {
namespace {

constexpr int kBusyTimeoutMs = 5000;
constexpr std::size_t kMaxQueryLimit = 1'000'000;

// Schema version 1. Every table is STRICT (types enforced) and ids use AUTOINCREMENT so that
// they are never reused, even if old rows are pruned one day.
constexpr const char* kSchemaV1 = R"sql(
CREATE TABLE IF NOT EXISTS events (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  time_ns INTEGER NOT NULL,
  severity INTEGER NOT NULL CHECK (severity BETWEEN 0 AND 4),
  source TEXT NOT NULL,
  code TEXT NOT NULL,
  message TEXT NOT NULL,
  intersection_id INTEGER NOT NULL CHECK (intersection_id BETWEEN 0 AND 4294967295),
  device_id TEXT NOT NULL,
  actor TEXT NOT NULL,
  active INTEGER NOT NULL CHECK (active IN (0, 1))
) STRICT;
CREATE INDEX IF NOT EXISTS events_by_time ON events (time_ns);
CREATE TABLE IF NOT EXISTS applied_configs (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  path TEXT NOT NULL,
  yaml TEXT NOT NULL,
  hash TEXT NOT NULL,
  applied_by TEXT NOT NULL,
  applied_at_ns INTEGER NOT NULL
) STRICT;
CREATE TABLE IF NOT EXISTS intersection_states (
  intersection_id INTEGER PRIMARY KEY CHECK (intersection_id BETWEEN 1 AND 4294967295),
  mode TEXT NOT NULL CHECK (mode <> ''),
  plan TEXT NOT NULL,
  operator_chosen INTEGER NOT NULL CHECK (operator_chosen IN (0, 1)),
  updated_at_ns INTEGER NOT NULL
) STRICT;
)sql";

// The SCM's process events of each process, found at start-up (`LatestProcessEvents`) without
// reading the whole log: a partial index holds only them. Made on every open (IF NOT EXISTS):
// a database of the same schema version written before it gets it then; an older SCM that
// opens the file keeps it up to date without knowing it. The codes are ProcessWatch's
// (scm/core/process_watch.h), literal so that SQLite can match the query to the index.
constexpr const char* kProcessEventsIndex =
    "CREATE INDEX IF NOT EXISTS events_of_processes ON events (code, device_id, time_ns) "
    "WHERE code IN ('process_exited', 'process_restarted')";
// The high-resolution log (docs/controller.md): made on every open like the index above, so a
// database of schema version 1 written before it gets it then, and an SCM that does not know it
// leaves it alone. Rows are small and many (about one a second per intersection): no
// AUTOINCREMENT, ids may be reused once pruned.
constexpr const char* kHiresTable = R"sql(
CREATE TABLE IF NOT EXISTS hires (
  id INTEGER PRIMARY KEY,
  intersection_id INTEGER NOT NULL CHECK (intersection_id BETWEEN 0 AND 4294967295),
  time_ns INTEGER NOT NULL,
  code INTEGER NOT NULL CHECK (code BETWEEN 0 AND 65535),
  param INTEGER NOT NULL CHECK (param BETWEEN 0 AND 65535)
) STRICT;
CREATE INDEX IF NOT EXISTS hires_of_intersection ON hires (intersection_id, time_ns);
CREATE INDEX IF NOT EXISTS hires_by_time ON hires (time_ns);
)sql";
// The operators' phase controls in force, saved with each intersection's state: made on every
// open like the log above (a database of schema version 1 gets it then).
constexpr const char* kPhaseControlsTable = R"sql(
CREATE TABLE IF NOT EXISTS phase_controls (
  intersection_id INTEGER NOT NULL CHECK (intersection_id BETWEEN 1 AND 4294967295),
  control TEXT NOT NULL CHECK (control <> ''),
  plan TEXT NOT NULL,
  phase INTEGER NOT NULL CHECK (phase BETWEEN 1 AND 255),
  until_ns INTEGER NOT NULL,
  PRIMARY KEY (intersection_id, control, plan, phase)
) STRICT;
)sql";
constexpr const char* kLatestProcessEvents =
    "SELECT code, device_id, max(time_ns) FROM events "
    "WHERE code IN ('process_exited', 'process_restarted') GROUP BY code, device_id";

constexpr const char* kEventColumns =
    "id, time_ns, severity, source, code, message, intersection_id, device_id, actor, active";

std::string Quoted(std::string_view s) { return "\"" + std::string(s) + "\""; }

std::int64_t ToNs(Time t) { return t.time_since_epoch().count(); }
Time FromNs(std::int64_t ns) { return Time(Duration(ns)); }

// A prepared statement, finalised on destruction.
class Statement {
 public:
  Statement() = default;
  Statement(sqlite3* db, const char* sql) {
    const int rc = sqlite3_prepare_v3(db, sql, -1, SQLITE_PREPARE_PERSISTENT, &stmt_, nullptr);
    if (rc != SQLITE_OK) {
      throw StoreError(std::string("cannot prepare \"") + sql + "\": " + sqlite3_errmsg(db), rc);
    }
  }
  Statement(Statement&& other) noexcept : stmt_(std::exchange(other.stmt_, nullptr)) {}
  Statement& operator=(Statement&& other) noexcept {
    std::swap(stmt_, other.stmt_);
    return *this;
  }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  ~Statement() { sqlite3_finalize(stmt_); }
  [[nodiscard]] sqlite3_stmt* get() const { return stmt_; }

 private:
  sqlite3_stmt* stmt_ = nullptr;
};

// Binds, steps and reads one use of a statement; resets it and clears its bindings when it
// goes out of scope, so a statement never stays busy after an exception.
class Use {
 public:
  Use(sqlite3* db, const Statement& statement) : db_(db), s_(statement.get()) {}
  Use(const Use&) = delete;
  Use& operator=(const Use&) = delete;
  ~Use() {
    sqlite3_reset(s_);
    sqlite3_clear_bindings(s_);
  }

  Use& Bind(int index, std::int64_t value) {
    Check(sqlite3_bind_int64(s_, index, value), "bind");
    return *this;
  }
  Use& Bind(int index, std::string_view text) {
    // The text lives until the statement is reset (this object's lifetime), so SQLite need
    // not copy it: a null destructor is SQLITE_STATIC. An empty view may have a null data
    // pointer, which SQLite would bind as NULL, hence "".
    const char* data = text.empty() ? "" : text.data();
    Check(sqlite3_bind_text64(s_, index, data, text.size(), nullptr, SQLITE_UTF8), "bind");
    return *this;
  }
  Use& BindNull(int index) {
    Check(sqlite3_bind_null(s_, index), "bind");
    return *this;
  }

  // Steps once: true when a row is ready, false when done.
  bool Step() {
    const int rc = sqlite3_step(s_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    Check(rc, "step");
    return false;
  }
  // Steps a statement that returns no rows.
  void Run() {
    while (Step()) {
    }
  }

  [[nodiscard]] std::int64_t Int(int column) const { return sqlite3_column_int64(s_, column); }
  [[nodiscard]] std::string Text(int column) const {
    const unsigned char* text = sqlite3_column_text(s_, column);
    const int bytes = sqlite3_column_bytes(s_, column);
    if (text == nullptr) return "";
    return std::string(reinterpret_cast<const char*>(text), static_cast<std::size_t>(bytes));
  }

 private:
  void Check(int rc, const char* what) const {
    if (rc == SQLITE_OK) return;
    throw StoreError(std::string("SQLite ") + what + " of \"" + sqlite3_sql(s_) +
                         "\" failed: " + sqlite3_errmsg(db_),
                     rc);
  }
  sqlite3* db_;
  sqlite3_stmt* s_;
};

std::uint32_t ToIntersectionValue(std::int64_t v) {
  AUTODRIVE_THROW_UNLESS(v >= 0 && v <= std::numeric_limits<std::uint32_t>::max(),
                         "stored intersection id " << v << " is out of range");
  return static_cast<std::uint32_t>(v);
}

std::int64_t ToSqlLimit(std::size_t limit) {
  AUTODRIVE_THROW_UNLESS(limit >= 1 && limit <= kMaxQueryLimit,
                         "a query limit must be in [1, " << kMaxQueryLimit << "], got " << limit);
  return static_cast<std::int64_t>(limit);
}

}  // namespace

std::string ContentHash(std::string_view text) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const char c : text) {
    h ^= static_cast<std::uint8_t>(c);
    h *= 0x100000001b3ULL;
  }
  std::array<char, 17> hex{};
  std::snprintf(hex.data(), hex.size(), "%016llx", static_cast<unsigned long long>(h));
  return std::string(hex.data(), 16);
}

// The connection, closed on destruction.
struct Connection {
  sqlite3* db = nullptr;
  Connection() = default;
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;
  ~Connection() { sqlite3_close_v2(db); }
};

struct Store::Impl {
  std::string path;
  // Declared before the statements, so destroyed after them: the connection closes (and, as
  // the last one, checkpoints and removes the WAL file) once every statement is finalised.
  Connection connection;
  sqlite3*& db = connection.db;
  mutable std::mutex mutex;

  Statement begin, commit;
  Statement insert_event, count_events, select_events_oldest, select_events_newest;
  Statement last_event_id, latest_process_events;
  Statement insert_config, latest_config, config_by_id, config_history;
  Statement prune_events_before, prune_events_keep, prune_configs, count_configs;
  Statement upsert_state, select_states;
  Statement delete_controls, insert_control, select_controls;
  struct HiresStatements {
    Statement insert, select_one, select_all, prune_before, prune_keep, count;
  } hires;

  explicit Impl(std::string p) : path(std::move(p)) {}

  [[noreturn]] void Fail(const std::string& what, int rc) const {
    throw StoreError("SCM database " + Quoted(path) + ": " + what + ": " + sqlite3_errmsg(db), rc);
  }

  void Exec(const char* sql) const {
    const int rc = sqlite3_exec(db, sql, nullptr, nullptr, nullptr);
    if (rc != SQLITE_OK) Fail(std::string("\"") + sql + "\" failed", rc);
  }

  std::int64_t PragmaInt(const char* sql) const {
    sqlite3_stmt* s = nullptr;
    int rc = sqlite3_prepare_v2(db, sql, -1, &s, nullptr);
    std::int64_t value = 0;
    if (rc == SQLITE_OK) {
      rc = sqlite3_step(s);
      if (rc == SQLITE_ROW) {
        value = sqlite3_column_int64(s, 0);
        rc = SQLITE_OK;
      }
    }
    sqlite3_finalize(s);
    if ((rc & 0xff) == SQLITE_NOTADB) {
      throw InputError("cannot open the SCM database " + Quoted(path) +
                       ": the file is not an SQLite database");
    }
    if (rc != SQLITE_OK) Fail(std::string("\"") + sql + "\" failed", rc);
    return value;
  }

  std::string PragmaText(const char* sql) const {
    Statement s(db, sql);
    Use use(db, s);
    std::string out;
    while (use.Step()) {
      if (!out.empty()) out += '\n';
      out += use.Text(0);
    }
    return out;
  }

  void Open() {
    if (path != ":memory:") {
      namespace fs = std::filesystem;
      const fs::path file(path);
      const fs::path dir = file.parent_path().empty() ? fs::path(".") : file.parent_path();
      std::error_code ec;
      AUTODRIVE_THROW_UNLESS(fs::is_directory(dir, ec), "cannot open the SCM database "
                                                            << Quoted(path) << ": directory " << dir
                                                            << " does not exist");
      AUTODRIVE_THROW_UNLESS(!fs::is_directory(file, ec), "cannot open the SCM database "
                                                              << Quoted(path)
                                                              << ": it is a directory");
    }
    const int rc =
        sqlite3_open_v2(path.c_str(), &db,
                        SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
    if (rc != SQLITE_OK) {
      if (db == nullptr) throw StoreError("cannot open the SCM database " + Quoted(path), rc);
      Fail("cannot open", rc);
    }
    sqlite3_extended_result_codes(db, 1);
    sqlite3_busy_timeout(db, kBusyTimeoutMs);

    // Look before writing anything: a foreign or newer file is refused untouched.
    const std::int64_t application_id = PragmaInt("PRAGMA application_id");
    const std::int64_t version = PragmaInt("PRAGMA user_version");
    std::ostringstream why;
    if (application_id != 0 && application_id != kApplicationId) {
      why << "it belongs to another application (application_id 0x" << std::hex << application_id
          << ", expected 0x" << kApplicationId << ")";
    } else if (version > kSchemaVersion) {
      why << "its schema version is " << version << ", newer than this SCM's " << kSchemaVersion
          << " (it was written by a newer SCM; refusing to open it rather than lose data)";
    } else if (application_id == 0 && (version != 0 || PragmaInt("SELECT count(*) FROM "
                                                                 "sqlite_schema") != 0)) {
      why << "it is an SQLite database of another application (no SCM application_id)";
    } else if (application_id == kApplicationId && version < 1) {
      why << "it has the SCM application_id but schema version " << version;
    }
    if (!why.str().empty()) {
      throw InputError("cannot open the SCM database " + Quoted(path) + ": " + why.str());
    }

    if (path != ":memory:") {
      const std::string mode = PragmaText("PRAGMA journal_mode=WAL");
      AUTODRIVE_THROW_UNLESS(mode == "wal", "cannot open the SCM database "
                                                << Quoted(path)
                                                << ": cannot switch it to WAL mode (journal mode "
                                                << mode << "; is it on a network file system?)");
    }
    Exec("PRAGMA synchronous=NORMAL");
    // After a checkpoint the WAL file is truncated to this size: it never grows without bound.
    Exec("PRAGMA journal_size_limit=67108864");

    if (version == 0) {
      // Created in one transaction; IF NOT EXISTS and the version check inside it make two
      // processes creating the same file at once harmless.
      Exec("BEGIN IMMEDIATE");
      try {
        if (PragmaInt("PRAGMA user_version") == 0) {
          Exec(kSchemaV1);
          Exec(("PRAGMA application_id=" + std::to_string(kApplicationId)).c_str());
          Exec(("PRAGMA user_version=" + std::to_string(kSchemaVersion)).c_str());
        }
        Exec("COMMIT");
      } catch (...) {
        sqlite3_exec(db, "ROLLBACK", nullptr, nullptr, nullptr);
        throw;
      }
    }
    // Migrations from older versions go here when there are any (version < kSchemaVersion).
    Exec(kProcessEventsIndex);
    Exec(kHiresTable);
    Exec(kPhaseControlsTable);

    begin = Statement(db, "BEGIN IMMEDIATE");
    commit = Statement(db, "COMMIT");
    insert_event = Statement(db,
                             "INSERT INTO events (id, time_ns, severity, source, code, message, "
                             "intersection_id, device_id, actor, active) "
                             "VALUES (?10, ?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)");
    last_event_id = Statement(db, "SELECT seq FROM sqlite_sequence WHERE name = 'events'");
    latest_process_events = Statement(db, kLatestProcessEvents);
    count_events = Statement(db, "SELECT count(*) FROM events");
    const std::string select = std::string("SELECT ") + kEventColumns +
                               " FROM events WHERE time_ns >= ?1 AND id > ?2 ORDER BY id ";
    select_events_oldest = Statement(db, (select + "ASC LIMIT ?3").c_str());
    select_events_newest = Statement(db, (select + "DESC LIMIT ?3").c_str());
    insert_config = Statement(db,
                              "INSERT INTO applied_configs (path, yaml, hash, applied_by, "
                              "applied_at_ns) VALUES (?1, ?2, ?3, ?4, ?5)");
    latest_config = Statement(db,
                              "SELECT id, path, yaml, hash, applied_by, applied_at_ns "
                              "FROM applied_configs ORDER BY id DESC LIMIT 1");
    config_by_id = Statement(db,
                             "SELECT id, path, yaml, hash, applied_by, applied_at_ns "
                             "FROM applied_configs WHERE id = ?1");
    config_history = Statement(db,
                               "SELECT id, path, hash, applied_by, applied_at_ns "
                               "FROM applied_configs ORDER BY id DESC LIMIT ?1");
    upsert_state = Statement(db,
                             "INSERT INTO intersection_states (intersection_id, mode, plan, "
                             "operator_chosen, updated_at_ns) VALUES (?1, ?2, ?3, ?4, ?5) "
                             "ON CONFLICT (intersection_id) DO UPDATE SET mode = excluded.mode, "
                             "plan = excluded.plan, operator_chosen = excluded.operator_chosen, "
                             "updated_at_ns = excluded.updated_at_ns");
    prune_events_before = Statement(db, "DELETE FROM events WHERE time_ns < ?1");
    prune_events_keep = Statement(db,
                                  "DELETE FROM events WHERE id <= (SELECT id FROM events "
                                  "ORDER BY id DESC LIMIT 1 OFFSET ?1)");
    prune_configs = Statement(db,
                              "DELETE FROM applied_configs WHERE id NOT IN (SELECT id FROM "
                              "applied_configs ORDER BY id DESC LIMIT ?1) AND id IS NOT (SELECT "
                              "max(id) FROM applied_configs WHERE applied_by = 'scm')");
    count_configs = Statement(db, "SELECT count(*) FROM applied_configs");
    hires.insert = Statement(db,
                             "INSERT INTO hires (intersection_id, time_ns, code, param) "
                             "VALUES (?1, ?2, ?3, ?4)");
    hires.select_one = Statement(db,
                                 "SELECT intersection_id, time_ns, code, param FROM hires WHERE "
                                 "intersection_id = ?1 AND time_ns >= ?2 AND time_ns < ?3 "
                                 "ORDER BY time_ns, id LIMIT ?4");
    hires.select_all = Statement(db,
                                 "SELECT intersection_id, time_ns, code, param FROM hires WHERE "
                                 "?1 = 0 AND time_ns >= ?2 AND time_ns < ?3 "
                                 "ORDER BY time_ns, id LIMIT ?4");
    hires.prune_before = Statement(db, "DELETE FROM hires WHERE time_ns < ?1");
    hires.prune_keep = Statement(db,
                                 "DELETE FROM hires WHERE id <= (SELECT id FROM hires "
                                 "ORDER BY id DESC LIMIT 1 OFFSET ?1)");
    hires.count = Statement(db, "SELECT count(*) FROM hires");
    delete_controls = Statement(db, "DELETE FROM phase_controls WHERE intersection_id = ?1");
    insert_control = Statement(db,
                               "INSERT INTO phase_controls (intersection_id, control, plan, phase, "
                               "until_ns) VALUES (?1, ?2, ?3, ?4, ?5)");
    select_controls = Statement(db,
                                "SELECT control, plan, phase, until_ns FROM phase_controls WHERE "
                                "intersection_id = ?1 ORDER BY until_ns, control, plan, phase");
    select_states = Statement(db,
                              "SELECT intersection_id, mode, plan, operator_chosen, "
                              "updated_at_ns FROM intersection_states ORDER BY intersection_id");
  }

  // Runs `write` in one IMMEDIATE transaction (the write lock is taken up front, so it cannot
  // fail half-way for want of it), committing on return and rolling back on an exception.
  // `full_sync`: commit with synchronous=FULL (see the comment at the top of this file).
  template <typename F>
  auto Write(bool full_sync, F&& write) {
    if (full_sync) Exec("PRAGMA synchronous=FULL");
    try {
      Use(db, begin).Run();
      try {
        auto result = write();
        Use(db, commit).Run();
        if (full_sync) Exec("PRAGMA synchronous=NORMAL");
        return result;
      } catch (...) {
        // Not a prepared statement: this must not throw over the exception in flight.
        if (sqlite3_get_autocommit(db) == 0)
          sqlite3_exec(db, "ROLLBACK", nullptr, nullptr, nullptr);
        throw;
      }
    } catch (...) {
      if (full_sync) sqlite3_exec(db, "PRAGMA synchronous=NORMAL", nullptr, nullptr, nullptr);
      throw;
    }
  }

  AppliedConfig ReadConfig(const Use& use) const {
    AppliedConfig c;
    c.id = use.Int(0);
    c.path = use.Text(1);
    c.yaml = use.Text(2);
    c.hash = use.Text(3);
    c.applied_by = use.Text(4);
    c.applied_at = FromNs(use.Int(5));
    return c;
  }
};

Store::Store(const std::string& path) : impl_(std::make_unique<Impl>(path)) { impl_->Open(); }
Store::~Store() = default;
Store::Store(Store&&) noexcept = default;
Store& Store::operator=(Store&&) noexcept = default;

const std::string& Store::path() const { return impl_->path; }

std::int64_t Store::AppendEvent(const EventRecord& e) { return AppendEvents({e}); }

std::int64_t Store::AppendEvents(const std::vector<EventRecord>& events) {
  if (events.empty()) return 0;
  std::lock_guard lock(impl_->mutex);
  return impl_->Write(false, [&] {
    for (const EventRecord& e : events) {
      Use use(impl_->db, impl_->insert_event);
      use.Bind(1, ToNs(e.time))
          .Bind(2, std::int64_t{static_cast<std::uint8_t>(e.severity)})
          .Bind(3, e.source)
          .Bind(4, e.code)
          .Bind(5, e.message)
          .Bind(6, std::int64_t{e.intersection.value()})
          .Bind(7, e.device_id)
          .Bind(8, e.actor)
          .Bind(9, std::int64_t{e.active ? 1 : 0});
      if (e.id > 0) {
        use.Bind(10, e.id);
      } else {
        use.BindNull(10);  // the next id
      }
      use.Run();
    }
    return static_cast<std::int64_t>(sqlite3_last_insert_rowid(impl_->db));
  });
}

void Store::AppendHires(const std::vector<HiresRecord>& records) {
  if (records.empty()) return;
  std::lock_guard lock(impl_->mutex);
  impl_->Write(false, [&] {
    for (const HiresRecord& r : records) {
      Use use(impl_->db, impl_->hires.insert);
      use.Bind(1, std::int64_t{r.intersection.value()})
          .Bind(2, ToNs(r.time))
          .Bind(3, std::int64_t{r.code})
          .Bind(4, std::int64_t{r.param})
          .Run();
    }
    return 0;
  });
}

std::vector<HiresRecord> Store::Hires(const HiresQuery& q) const {
  AUTODRIVE_THROW_UNLESS(q.limit > 0 && q.limit <= kMaxQueryLimit,
                         "a query's limit must be 1.." << kMaxQueryLimit << ", got " << q.limit);
  AUTODRIVE_THROW_UNLESS(q.until >= q.since, "a query's until is before its since");
  std::lock_guard lock(impl_->mutex);
  Use use(impl_->db,
          q.intersection.value() == 0 ? impl_->hires.select_all : impl_->hires.select_one);
  use.Bind(1, std::int64_t{q.intersection.value()})
      .Bind(2, ToNs(q.since))
      .Bind(3, ToNs(q.until))
      .Bind(4, static_cast<std::int64_t>(q.limit));
  std::vector<HiresRecord> out;
  while (use.Step()) {
    out.push_back({IntersectionId(static_cast<std::uint32_t>(use.Int(0))), FromNs(use.Int(1)),
                   static_cast<std::uint16_t>(use.Int(2)), static_cast<std::uint16_t>(use.Int(3))});
  }
  return out;
}

std::int64_t Store::PruneHires(std::optional<Time> before, std::int64_t keep_newest) {
  AUTODRIVE_THROW_UNLESS(keep_newest >= 0, "keep_newest must be >= 0, got " << keep_newest);
  std::lock_guard lock(impl_->mutex);
  return impl_->Write(false, [&] {
    std::int64_t deleted = 0;
    if (before) {
      Use use(impl_->db, impl_->hires.prune_before);
      use.Bind(1, ToNs(*before)).Run();
      deleted += sqlite3_changes64(impl_->db);
    }
    Use use(impl_->db, impl_->hires.prune_keep);
    use.Bind(1, keep_newest).Run();
    deleted += sqlite3_changes64(impl_->db);
    return deleted;
  });
}

std::int64_t Store::HiresCount() const {
  std::lock_guard lock(impl_->mutex);
  Use use(impl_->db, impl_->hires.count);
  return use.Step() ? use.Int(0) : 0;
}

std::int64_t Store::PruneEvents(std::optional<Time> before, std::int64_t keep_newest) {
  AUTODRIVE_THROW_UNLESS(keep_newest >= 0, "keep_newest must be >= 0, got " << keep_newest);
  std::lock_guard lock(impl_->mutex);
  return impl_->Write(false, [&] {
    std::int64_t deleted = 0;
    if (before) {
      Use use(impl_->db, impl_->prune_events_before);
      use.Bind(1, ToNs(*before));
      use.Run();
      deleted += sqlite3_changes64(impl_->db);
    }
    Use use(impl_->db, impl_->prune_events_keep);
    use.Bind(1, keep_newest);
    use.Run();
    deleted += sqlite3_changes64(impl_->db);
    return deleted;
  });
}

std::vector<EventRecord> Store::Events(const EventQuery& query) const {
  const std::int64_t limit = ToSqlLimit(query.limit);
  std::lock_guard lock(impl_->mutex);
  Use use(impl_->db,
          query.newest_first ? impl_->select_events_newest : impl_->select_events_oldest);
  use.Bind(1, query.since ? ToNs(*query.since) : std::numeric_limits<std::int64_t>::min())
      .Bind(2, query.after_id.value_or(0))
      .Bind(3, limit);
  std::vector<EventRecord> out;
  while (use.Step()) {
    EventRecord e;
    e.id = use.Int(0);
    e.time = FromNs(use.Int(1));
    const std::int64_t severity = use.Int(2);
    AUTODRIVE_THROW_UNLESS(severity >= 0 && severity <= 4,
                           "stored event " << e.id << " has severity " << severity);
    e.severity = static_cast<Severity>(severity);
    e.source = use.Text(3);
    e.code = use.Text(4);
    e.message = use.Text(5);
    e.intersection = IntersectionId(ToIntersectionValue(use.Int(6)));
    e.device_id = use.Text(7);
    e.actor = use.Text(8);
    e.active = use.Int(9) != 0;
    out.push_back(std::move(e));
  }
  return out;
}

std::int64_t Store::LastEventId() const {
  std::lock_guard lock(impl_->mutex);
  Use use(impl_->db, impl_->last_event_id);
  return use.Step() ? use.Int(0) : 0;
}

std::vector<LatestDeviceEvent> Store::LatestProcessEvents() const {
  std::lock_guard lock(impl_->mutex);
  Use use(impl_->db, impl_->latest_process_events);
  std::vector<LatestDeviceEvent> out;
  while (use.Step()) {
    out.push_back(LatestDeviceEvent{use.Text(0), use.Text(1), FromNs(use.Int(2))});
  }
  return out;
}

std::int64_t Store::EventCount() const {
  std::lock_guard lock(impl_->mutex);
  Use use(impl_->db, impl_->count_events);
  return use.Step() ? use.Int(0) : 0;
}

std::int64_t Store::SaveAppliedConfig(std::string_view path, std::string_view yaml,
                                      std::string_view applied_by, Time applied_at) {
  const std::string hash = ContentHash(yaml);
  std::lock_guard lock(impl_->mutex);
  return impl_->Write(true, [&] {
    Use use(impl_->db, impl_->insert_config);
    use.Bind(1, path).Bind(2, yaml).Bind(3, hash).Bind(4, applied_by).Bind(5, ToNs(applied_at));
    use.Run();
    return static_cast<std::int64_t>(sqlite3_last_insert_rowid(impl_->db));
  });
}

std::optional<AppliedConfig> Store::LatestConfig() const {
  std::lock_guard lock(impl_->mutex);
  Use use(impl_->db, impl_->latest_config);
  if (!use.Step()) return std::nullopt;
  return impl_->ReadConfig(use);
}

std::optional<AppliedConfig> Store::ConfigById(std::int64_t id) const {
  std::lock_guard lock(impl_->mutex);
  Use use(impl_->db, impl_->config_by_id);
  use.Bind(1, id);
  if (!use.Step()) return std::nullopt;
  return impl_->ReadConfig(use);
}

std::vector<AppliedConfigSummary> Store::ConfigHistory(std::size_t limit) const {
  const std::int64_t sql_limit = ToSqlLimit(limit);
  std::lock_guard lock(impl_->mutex);
  Use use(impl_->db, impl_->config_history);
  use.Bind(1, sql_limit);
  std::vector<AppliedConfigSummary> out;
  while (use.Step()) {
    AppliedConfigSummary c;
    c.id = use.Int(0);
    c.path = use.Text(1);
    c.hash = use.Text(2);
    c.applied_by = use.Text(3);
    c.applied_at = FromNs(use.Int(4));
    out.push_back(std::move(c));
  }
  return out;
}

std::int64_t Store::PruneConfigs(std::size_t keep_newest) {
  const std::int64_t keep = ToSqlLimit(keep_newest);
  std::lock_guard lock(impl_->mutex);
  return impl_->Write(true, [&] {
    Use use(impl_->db, impl_->prune_configs);
    use.Bind(1, keep);
    use.Run();
    return static_cast<std::int64_t>(sqlite3_changes64(impl_->db));
  });
}

std::int64_t Store::ConfigCount() const {
  std::lock_guard lock(impl_->mutex);
  Use use(impl_->db, impl_->count_configs);
  return use.Step() ? use.Int(0) : 0;
}

void Store::SaveIntersectionState(const IntersectionStateRecord& state) {
  AUTODRIVE_THROW_UNLESS(state.intersection.value() != 0,
                         "an intersection state needs an intersection id, got 0");
  AUTODRIVE_THROW_UNLESS(!state.mode.empty(),
                         "the state of " << state.intersection << " has an empty mode");
  std::lock_guard lock(impl_->mutex);
  impl_->Write(true, [&] {
    Use use(impl_->db, impl_->upsert_state);
    use.Bind(1, std::int64_t{state.intersection.value()})
        .Bind(2, state.mode)
        .Bind(3, state.plan)
        .Bind(4, std::int64_t{state.operator_chosen ? 1 : 0})
        .Bind(5, ToNs(state.updated_at));
    use.Run();
    Use(impl_->db, impl_->delete_controls).Bind(1, std::int64_t{state.intersection.value()}).Run();
    for (const PhaseControlRecord& c : state.controls) {
      Use(impl_->db, impl_->insert_control)
          .Bind(1, std::int64_t{state.intersection.value()})
          .Bind(2, c.control)
          .Bind(3, c.plan)
          .Bind(4, std::int64_t{c.phase})
          .Bind(5, ToNs(c.until))
          .Run();
    }
    return 0;
  });
}

std::vector<IntersectionStateRecord> Store::LoadIntersectionStates() const {
  std::lock_guard lock(impl_->mutex);
  Use use(impl_->db, impl_->select_states);
  std::vector<IntersectionStateRecord> out;
  while (use.Step()) {
    IntersectionStateRecord s;
    s.intersection = IntersectionId(ToIntersectionValue(use.Int(0)));
    s.mode = use.Text(1);
    s.plan = use.Text(2);
    s.operator_chosen = use.Int(3) != 0;
    s.updated_at = FromNs(use.Int(4));
    out.push_back(std::move(s));
  }
  for (IntersectionStateRecord& s : out) {
    Use controls(impl_->db, impl_->select_controls);
    controls.Bind(1, std::int64_t{s.intersection.value()});
    while (controls.Step()) {
      s.controls.push_back({controls.Text(0), controls.Text(1),
                            static_cast<std::uint32_t>(controls.Int(2)), FromNs(controls.Int(3))});
    }
  }
  return out;
}

std::int64_t Store::SizeBytes() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->PragmaInt("PRAGMA page_count") * impl_->PragmaInt("PRAGMA page_size");
}

std::string Store::IntegrityCheck() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->PragmaText("PRAGMA integrity_check");
}

}  // namespace autodrive::scm
