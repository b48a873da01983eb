#include "scm/store/store.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>
#include <tuple>

#include "common/test_support.h"

namespace autodrive::scm {
namespace {

namespace fs = std::filesystem;
using std::chrono::seconds;
using namespace std::string_literals;

// A fresh directory per test, removed afterwards.
class StoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::path(::testing::TempDir()) / "scm_store_test_XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr) << "mkdtemp " << pattern;
    dir_ = pattern;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  [[nodiscard]] std::string DbPath() const { return (dir_ / "scm.db").string(); }

  fs::path dir_;
};

EventRecord MakeEvent(int i) {
  EventRecord e;
  e.time = Time(seconds(100 + i));
  e.severity = static_cast<Severity>(i % 5);
  e.source = "scm/test";
  e.code = "code_" + std::to_string(i);
  e.message = "event number " + std::to_string(i);
  e.intersection = IntersectionId(static_cast<std::uint32_t>(i % 3));
  e.device_id = i % 2 ? "signal_" + std::to_string(i) : "";
  e.actor = i % 4 ? "scm" : "operator_7";
  e.active = i % 3 == 1;
  return e;
}

// Runs `sql` on the file with raw SQLite (to tamper with it as another program would).
void RawExec(const std::string& path, const std::string& sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  char* error = nullptr;
  const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &error);
  EXPECT_EQ(rc, SQLITE_OK) << sql << ": " << (error ? error : "");
  sqlite3_free(error);
  sqlite3_close(db);
}

std::string RawText(const std::string& path, const std::string& sql) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* s = nullptr;
  EXPECT_EQ(sqlite3_prepare_v2(db, sql.c_str(), -1, &s, nullptr), SQLITE_OK);
  std::string out;
  if (sqlite3_step(s) == SQLITE_ROW) out = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
  sqlite3_finalize(s);
  sqlite3_close(db);
  return out;
}

// SQLite's query plan of `sql` on the file, its steps joined by "; ".
std::string RawPlan(const std::string& path, const std::string& sql) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* s = nullptr;
  EXPECT_EQ(sqlite3_prepare_v2(db, ("EXPLAIN QUERY PLAN " + sql).c_str(), -1, &s, nullptr),
            SQLITE_OK);
  std::string out;
  while (sqlite3_step(s) == SQLITE_ROW) {
    out += reinterpret_cast<const char*>(sqlite3_column_text(s, 3));
    out += "; ";
  }
  sqlite3_finalize(s);
  sqlite3_close(db);
  return out;
}

TEST(ContentHash, IsFnv1a64InSixteenHexDigits) {
  // Reference values of 64-bit FNV-1a (Fowler, Noll, Vo test vectors).
  EXPECT_EQ(ContentHash(""), "cbf29ce484222325");
  EXPECT_EQ(ContentHash("a"), "af63dc4c8601ec8c");
  EXPECT_EQ(ContentHash("foobar"), "85944171f73967e8");
  EXPECT_NE(ContentHash("yellow_s: 3.0\n"), ContentHash("yellow_s: 3.5\n"));
}

TEST_F(StoreTest, AppendReturnsConsecutiveIdsAndRoundTripsEveryField) {
  Store store(":memory:");
  EXPECT_EQ(store.EventCount(), 0);
  std::vector<EventRecord> written;
  for (int i = 0; i < 10; ++i) {
    EventRecord e = MakeEvent(i);
    const std::int64_t id = store.AppendEvent(e);  // id 0: the next one
    EXPECT_EQ(id, i + 1);
    e.id = id;
    written.push_back(e);
  }
  EXPECT_EQ(store.EventCount(), 10);
  EXPECT_EQ(store.Events({}), written);
}

TEST_F(StoreTest, AnEventNumberedByTheScmKeepsItsIdAndTheCountGoesOnAfterPruning) {
  Store store(DbPath());
  EXPECT_EQ(store.LastEventId(), 0);
  // The SCM numbers its events as it raises them (from LastEventId); one it had to drop leaves
  // a gap.
  EventRecord e = MakeEvent(1);
  e.id = 1;
  EXPECT_EQ(store.AppendEvent(e), 1);
  e.id = 3;
  EXPECT_EQ(store.AppendEvent(e), 3);
  EXPECT_EQ(store.LastEventId(), 3);
  const auto got = store.Events({});
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[1].id, 3);
  e.id = 3;
  EXPECT_THROW(store.AppendEvent(e), StoreError) << "an id is used once";
  // Pruned to nothing, then reopened (the SCM restarted): the count goes on, ids are not reused.
  EXPECT_EQ(store.PruneEvents(std::nullopt, 0), 2);
  Store reopened(DbPath());
  EXPECT_EQ(reopened.EventCount(), 0);
  EXPECT_EQ(reopened.LastEventId(), 3);
  e.id = 0;
  EXPECT_EQ(reopened.AppendEvent(e), 4);
}

TEST_F(StoreTest, TheNewestProcessEventOfEachDeviceIsFoundThroughItsOwnIndex) {
  Store store(DbPath());
  EXPECT_TRUE(store.LatestProcessEvents().empty());
  const auto event = [](std::string code, std::string device, int s) {
    EventRecord e = MakeEvent(0);
    e.code = std::move(code);
    e.device_id = std::move(device);
    e.time = Time(seconds(s));
    return e;
  };
  store.AppendEvents(
      {event("process_exited", "process/lights", 10),
       event("process_restarted", "process/lights", 12),
       event("process_exited", "process/lights", 30), event("process_exited", "process/scm", 20),
       event("device_lost", "process/lights", 99), event("process_exited", "process/lights", 25)});
  std::vector<LatestDeviceEvent> latest = store.LatestProcessEvents();
  std::sort(latest.begin(), latest.end(), [](const auto& a, const auto& b) {
    return std::tie(a.code, a.device_id) < std::tie(b.code, b.device_id);
  });
  EXPECT_EQ(latest, (std::vector<LatestDeviceEvent>{
                        {"process_exited", "process/lights", Time(seconds(30))},
                        {"process_exited", "process/scm", Time(seconds(20))},
                        {"process_restarted", "process/lights", Time(seconds(12))}}));
  // Read through the partial index, not the whole log (a million events at most): SQLite's
  // plan of the store's query.
  const std::string plan = RawPlan(DbPath(),
                                   "SELECT code, device_id, max(time_ns) FROM events WHERE code IN "
                                   "('process_exited', 'process_restarted') GROUP BY code, "
                                   "device_id");
  EXPECT_NE(plan.find("USING COVERING INDEX events_of_processes"), std::string::npos) << plan;
}

TEST_F(StoreTest, TheHighResolutionLogIsQueriedByIntersectionAndWindowAndPruned) {
  {
    // A database of schema version 1 written before the log existed: the table comes on open.
    Store store(DbPath());
    RawExec(DbPath(), "DROP TABLE hires");
  }
  Store store(DbPath());
  EXPECT_EQ(store.HiresCount(), 0);
  const IntersectionId a(1), b(2);
  const Time t0(seconds(1000));
  std::vector<HiresRecord> records;
  for (int i = 0; i < 100; ++i) {
    records.push_back({i % 2 == 0 ? a : b, t0 + std::chrono::milliseconds(100 * i),
                       static_cast<std::uint16_t>(i % 13), static_cast<std::uint16_t>(1 + i % 8)});
  }
  records.push_back({a, t0, 65535, 65535});  // the largest code and parameter, at t0 again
  store.AppendHires(records);
  EXPECT_EQ(store.HiresCount(), 101);
  HiresQuery q;
  q.intersection = a;
  q.since = t0;
  q.until = t0 + seconds(1);  // excluded
  const std::vector<HiresRecord> got = store.Hires(q);
  ASSERT_EQ(got.size(), 6u);
  EXPECT_EQ(got[0], records[0]);
  EXPECT_EQ(got[1], records[100]) << "same time: append order";
  EXPECT_EQ(got[5], records[8]);
  q.intersection = IntersectionId(0);  // every intersection
  EXPECT_EQ(store.Hires(q).size(), 11u);
  q.limit = 0;
  EXPECT_THROW((void)store.Hires(q), InputError);
  // Pruned by age, then by count (the newest kept).
  EXPECT_EQ(store.PruneHires(t0 + seconds(5), 1000), 51);
  EXPECT_EQ(store.PruneHires(std::nullopt, 10), 40);
  q.limit = 1000;
  q.until = t0 + seconds(100);
  const std::vector<HiresRecord> left = store.Hires(q);
  ASSERT_EQ(left.size(), 10u);
  EXPECT_EQ(left.back(), records[99]);
  // Read through its index, not the whole table.
  const std::string plan = RawPlan(DbPath(),
                                   "SELECT intersection_id, time_ns, code, param FROM hires WHERE "
                                   "intersection_id = 1 AND time_ns >= 0 AND time_ns < 10 ORDER BY "
                                   "time_ns, id LIMIT 5");
  EXPECT_NE(plan.find("hires_of_intersection"), std::string::npos) << plan;
}

TEST_F(StoreTest, TextWithQuotesNulsAndNonAsciiRoundTrips) {
  Store store(":memory:");
  EventRecord e = MakeEvent(1);
  e.message = "it's \"quoted\"; DROP TABLE events; --\0tail \xc3\xa9"s;
  e.source = "";
  store.AppendEvent(e);
  const auto got = store.Events({});
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].message, e.message);
  EXPECT_EQ(got[0].source, "");
}

TEST_F(StoreTest, QueriesFilterBySinceAndAfterIdInAppendOrder) {
  Store store(":memory:");
  // Times are not monotonic in the log (a simulated clock may restart): order is by id.
  const int times_s[] = {10, 30, 20, 40, 5, 50};
  for (const int t : times_s) {
    EventRecord e = MakeEvent(t);
    e.time = Time(seconds(t));
    store.AppendEvent(e);
  }
  const auto ids = [](const std::vector<EventRecord>& events) {
    std::vector<std::int64_t> out;
    for (const auto& e : events) out.push_back(e.id);
    return out;
  };
  EventQuery q;
  q.since = Time(seconds(20));
  EXPECT_EQ(ids(store.Events(q)), (std::vector<std::int64_t>{2, 3, 4, 6}));
  q.after_id = 3;
  EXPECT_EQ(ids(store.Events(q)), (std::vector<std::int64_t>{4, 6}));
  q.since.reset();
  EXPECT_EQ(ids(store.Events(q)), (std::vector<std::int64_t>{4, 5, 6}));
  q.limit = 2;
  EXPECT_EQ(ids(store.Events(q)), (std::vector<std::int64_t>{4, 5}));
  q.newest_first = true;
  EXPECT_EQ(ids(store.Events(q)), (std::vector<std::int64_t>{6, 5}));
  q.after_id = 6;
  EXPECT_TRUE(store.Events(q).empty());
  q.limit = 0;
  EXPECT_EQ(test::ErrorMessage([&] { (void)store.Events(q); }),
            "a query limit must be in [1, 1000000], got 0");
}

TEST_F(StoreTest, ConfigurationsAreKeptWithHashAuthorAndTimeNewestFirst) {
  Store store(":memory:");
  EXPECT_FALSE(store.LatestConfig().has_value());
  EXPECT_TRUE(store.ConfigHistory().empty());
  const std::string yaml1 = "city: driving_school\nyellow_s: 3.0\n";
  const std::string yaml2 = "city: driving_school\nyellow_s: 2.5\n";
  EXPECT_EQ(store.SaveAppliedConfig("config/cities/a.yaml", yaml1, "scm", Time(seconds(1))), 1);
  EXPECT_EQ(store.SaveAppliedConfig("config/cities/b.yaml", yaml2, "op_1", Time(seconds(2))), 2);

  const auto latest = store.LatestConfig();
  ASSERT_TRUE(latest.has_value());
  EXPECT_EQ(*latest, (AppliedConfig{2, "config/cities/b.yaml", yaml2, ContentHash(yaml2), "op_1",
                                    Time(seconds(2))}));
  const auto first = store.ConfigById(1);
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(first->yaml, yaml1);
  EXPECT_EQ(first->hash, ContentHash(yaml1));
  EXPECT_FALSE(store.ConfigById(3).has_value());

  const auto history = store.ConfigHistory();
  ASSERT_EQ(history.size(), 2u);
  EXPECT_EQ(history[0], (AppliedConfigSummary{2, "config/cities/b.yaml", ContentHash(yaml2), "op_1",
                                              Time(seconds(2))}));
  EXPECT_EQ(history[1].id, 1);
  EXPECT_EQ(store.ConfigHistory(1).size(), 1u);
}

TEST_F(StoreTest, IntersectionStatesAreUpsertedAndLoadedById) {
  Store store(":memory:");
  store.SaveIntersectionState(
      {IntersectionId(3), "actuated", "am_peak", false, Time(seconds(1)), {}});
  store.SaveIntersectionState({IntersectionId(1), "fixed", "default", false, Time(seconds(2)), {}});
  store.SaveIntersectionState({IntersectionId(3), "flash", "", true, Time(seconds(3)), {}});
  const auto states = store.LoadIntersectionStates();
  ASSERT_EQ(states.size(), 2u);
  EXPECT_EQ(states[0], (IntersectionStateRecord{
                           IntersectionId(1), "fixed", "default", false, Time(seconds(2)), {}}));
  EXPECT_EQ(states[1],
            (IntersectionStateRecord{IntersectionId(3), "flash", "", true, Time(seconds(3)), {}}));

  EXPECT_EQ(test::ErrorMessage([&] {
              store.SaveIntersectionState({IntersectionId(0), "fixed", "", false, Time(), {}});
            }),
            "an intersection state needs an intersection id, got 0");
  EXPECT_EQ(test::ErrorMessage([&] {
              store.SaveIntersectionState({IntersectionId(2), "", "", false, Time(), {}});
            }),
            "the state of IntersectionId(2) has an empty mode");
}

TEST_F(StoreTest, PhaseControlsAreSavedWithTheirIntersectionsStateAndReplacedWhole) {
  {
    Store store(DbPath());
    const std::vector<PhaseControlRecord> two = {{"omit", "day", 2, Time(seconds(100))},
                                                 {"hold", "evening", 1, Time(seconds(50))}};
    store.SaveIntersectionState({IntersectionId(4), "auto", "auto", true, Time(seconds(1)), two});
    store.SaveIntersectionState({IntersectionId(5), "auto", "auto", true, Time(seconds(1)), two});
    // A later save of the same intersection replaces its controls, not another's.
    store.SaveIntersectionState({IntersectionId(5),
                                 "auto",
                                 "auto",
                                 true,
                                 Time(seconds(2)),
                                 {{"call", "day", 3, Time(seconds(9))}}});
  }
  Store store(DbPath());  // reopened: they were written to the file
  const auto states = store.LoadIntersectionStates();
  ASSERT_EQ(states.size(), 2u);
  EXPECT_EQ(states[0].controls,
            (std::vector<PhaseControlRecord>{{"hold", "evening", 1, Time(seconds(50))},
                                             {"omit", "day", 2, Time(seconds(100))}}))
      << "in order of their ends";
  EXPECT_EQ(states[1].controls,
            (std::vector<PhaseControlRecord>{{"call", "day", 3, Time(seconds(9))}}));
  store.SaveIntersectionState({IntersectionId(4), "auto", "auto", true, Time(seconds(3)), {}});
  EXPECT_TRUE(store.LoadIntersectionStates()[0].controls.empty());
}

TEST_F(StoreTest, ReopenedFileHasEverythingAndIsInWalMode) {
  {
    Store store(DbPath());
    for (int i = 0; i < 5; ++i) store.AppendEvent(MakeEvent(i));
    store.SaveAppliedConfig("a.yaml", "x: 1\n", "scm", Time(seconds(7)));
    store.SaveIntersectionState({IntersectionId(1), "manual", "p", true, Time(seconds(8)), {}});
  }
  EXPECT_EQ(RawText(DbPath(), "PRAGMA journal_mode"), "wal");
  EXPECT_EQ(RawText(DbPath(), "PRAGMA user_version"), "1");
  Store store(DbPath());
  EXPECT_EQ(store.IntegrityCheck(), "ok");
  EXPECT_EQ(store.EventCount(), 5);
  const auto events = store.Events({});
  ASSERT_EQ(events.size(), 5u);
  EventRecord expected = MakeEvent(4);
  expected.id = 5;
  EXPECT_EQ(events[4], expected);
  ASSERT_TRUE(store.LatestConfig().has_value());
  EXPECT_EQ(store.LatestConfig()->yaml, "x: 1\n");
  ASSERT_EQ(store.LoadIntersectionStates().size(), 1u);
  EXPECT_EQ(store.LoadIntersectionStates()[0].mode, "manual");
  // Ids continue after a reopen.
  EXPECT_EQ(store.AppendEvent(MakeEvent(9)), 6);
}

TEST_F(StoreTest, RefusesANewerSchemaVersion) {
  { Store store(DbPath()); }
  RawExec(DbPath(), "PRAGMA user_version=2");
  EXPECT_EQ(test::ErrorMessage([&] { Store store(DbPath()); }),
            "cannot open the SCM database \"" + DbPath() +
                "\": its schema version is 2, newer than this SCM's 1 (it was written by a newer "
                "SCM; refusing to open it rather than lose data)");
  // Refused untouched.
  EXPECT_EQ(RawText(DbPath(), "PRAGMA user_version"), "2");
}

TEST_F(StoreTest, RefusesAMissingDirectory) {
  const std::string path = (dir_ / "no_such_dir" / "scm.db").string();
  EXPECT_EQ(test::ErrorMessage([&] { Store store(path); }),
            "cannot open the SCM database \"" + path + "\": directory \"" +
                (dir_ / "no_such_dir").string() + "\" does not exist");
}

TEST_F(StoreTest, RefusesAFileThatIsNotAnSqliteDatabase) {
  std::ofstream(DbPath())
      << "format: autodrive-map/1\nthis is YAML, not SQLite, and long enough "
         "to fill a header of one hundred bytes..............................\n";
  EXPECT_EQ(
      test::ErrorMessage([&] { Store store(DbPath()); }),
      "cannot open the SCM database \"" + DbPath() + "\": the file is not an SQLite database");
}

TEST_F(StoreTest, RefusesAnotherApplicationsDatabase) {
  RawExec(DbPath(), "CREATE TABLE photos (id INTEGER PRIMARY KEY)");
  EXPECT_EQ(test::ErrorMessage([&] { Store store(DbPath()); }),
            "cannot open the SCM database \"" + DbPath() +
                "\": it is an SQLite database of another application (no SCM application_id)");
  RawExec(DbPath(), "PRAGMA application_id=1234");
  EXPECT_EQ(test::ErrorMessage([&] { Store store(DbPath()); }),
            "cannot open the SCM database \"" + DbPath() +
                "\": it belongs to another application (application_id 0x4d2, expected "
                "0x41445343)");
}

TEST_F(StoreTest, AppendsFromManyThreadsGetDistinctContiguousIds) {
  Store store(DbPath());
  constexpr int kThreads = 4;
  constexpr int kEach = 50;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&store, t] {
      for (int i = 0; i < kEach; ++i) store.AppendEvent(MakeEvent(t * kEach + i));
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(store.EventCount(), kThreads * kEach);
  const auto events = store.Events({});
  ASSERT_EQ(events.size(), std::size_t{kThreads * kEach});
  for (std::size_t i = 0; i < events.size(); ++i) EXPECT_EQ(events[i].id, std::int64_t(i) + 1);
}

TEST_F(StoreTest, MovedStoreKeepsWorking) {
  Store a(":memory:");
  a.AppendEvent(MakeEvent(1));
  Store b = std::move(a);
  EXPECT_EQ(b.AppendEvent(MakeEvent(2)), 2);
  EXPECT_EQ(b.EventCount(), 2);
}

// The child writes events (and now and then an intersection state and a configuration, which
// commit with synchronous=FULL) in a loop and reports each committed event id through a pipe;
// the parent SIGKILLs it at a pseudo-random moment. After every kill the file must be intact and
// hold every event the child reported (plus at most the one it committed but had no time to
// report), with ids 1..n and nothing missing.
TEST_F(StoreTest, NothingCommittedIsLostAndTheFileIsIntactWhenTheWriterIsKilled) {
  std::mt19937 rng(20240611);
  const int rounds = 4 * test::SoakFactor();
  std::int64_t committed_before = 0;
  for (int round = 0; round < rounds; ++round) {
    int fds[2];
    ASSERT_EQ(pipe(fds), 0);
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      close(fds[0]);
      try {
        Store store(DbPath());
        for (int i = 0;; ++i) {
          EventRecord e = MakeEvent(i);
          e.message.assign(static_cast<std::size_t>(50 + (i * 37) % 3000), 'x');
          const std::int64_t id = store.AppendEvent(e);
          if (i % 16 == 0) {
            store.SaveIntersectionState(
                {IntersectionId(1), "fixed", std::to_string(i), false, Time(seconds(i)), {}});
          }
          if (i % 64 == 0) store.SaveAppliedConfig("c.yaml", e.message, "scm", Time(seconds(i)));
          if (write(fds[1], &id, sizeof id) != static_cast<ssize_t>(sizeof id)) _exit(3);
        }
      } catch (...) {
        _exit(2);
      }
    }
    close(fds[1]);
    // Let it commit a pseudo-random number of events, then a pseudo-random pause more.
    const int target = std::uniform_int_distribution<int>(20, 400)(rng);
    std::int64_t last = committed_before;
    for (int n = 0; n < target;) {
      std::int64_t id = 0;
      const ssize_t got = read(fds[0], &id, sizeof id);
      if (got < 0 && errno == EINTR) continue;
      ASSERT_EQ(got, static_cast<ssize_t>(sizeof id)) << "the writer stopped early";
      EXPECT_EQ(id, last + 1);
      last = id;
      ++n;
    }
    usleep(static_cast<useconds_t>(std::uniform_int_distribution<int>(0, 3000)(rng)));
    ASSERT_EQ(kill(pid, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL)
        << "the writer was not killed but exited with status " << status;
    std::int64_t id = 0;
    while (read(fds[0], &id, sizeof id) == static_cast<ssize_t>(sizeof id)) {
      EXPECT_EQ(id, last + 1);
      last = id;
    }
    close(fds[0]);

    Store store(DbPath());
    EXPECT_EQ(store.IntegrityCheck(), "ok") << "round " << round;
    const std::int64_t count = store.EventCount();
    EXPECT_TRUE(count == last || count == last + 1)
        << "round " << round << ": " << count << " events, the child reported " << last;
    EventQuery all;
    all.limit = 1'000'000;
    const auto events = store.Events(all);
    ASSERT_EQ(events.size(), static_cast<std::size_t>(count));
    for (std::size_t i = 0; i < events.size(); ++i) {
      ASSERT_EQ(events[i].id, std::int64_t(i) + 1) << "round " << round;
    }
    ASSERT_EQ(store.LoadIntersectionStates().size(), 1u);
    ASSERT_TRUE(store.LatestConfig().has_value());
    EXPECT_EQ(store.LatestConfig()->hash, ContentHash(store.LatestConfig()->yaml));
    committed_before = count;
  }
}

}  // namespace
}  // namespace autodrive::scm

namespace autodrive::scm {
namespace {

TEST_F(StoreTest, PruningKeepsTheNewestEventsAndTheFileStopsGrowing) {
  Store store(DbPath());
  std::vector<EventRecord> batch;
  for (int i = 0; i < 1000; ++i) batch.push_back(MakeEvent(i));
  EXPECT_EQ(store.AppendEvents(batch), 1000);
  EXPECT_EQ(store.EventCount(), 1000);
  // By age: events before t=100+300 go; by count: the newest 500 stay.
  EXPECT_EQ(store.PruneEvents(Time(seconds(400)), 500), 500);
  EXPECT_EQ(store.EventCount(), 500);
  const auto oldest = store.Events(EventQuery{std::nullopt, std::nullopt, 1, false});
  ASSERT_EQ(oldest.size(), 1u);
  EXPECT_EQ(oldest[0].id, 501) << "ids are never reused and the newest are kept";
  // Steady state: append and prune a thousand times as many; the file stops growing.
  std::int64_t size_after_first_round = 0;
  for (int round = 0; round < 20; ++round) {
    batch.clear();
    for (int i = 0; i < 500; ++i) batch.push_back(MakeEvent(i));
    store.AppendEvents(batch);
    store.PruneEvents(std::nullopt, 500);
    if (round == 1) size_after_first_round = store.SizeBytes();
  }
  EXPECT_EQ(store.EventCount(), 500);
  // Freed pages are reused: after 20 rounds the file is within a few pages of its size after
  // the second (B-tree splits may take a page or two).
  EXPECT_LE(store.SizeBytes(), size_after_first_round + 4 * 4096) << "the file keeps growing";
}

TEST_F(StoreTest, ConfigHistoryIsBoundedButKeepsTheLastStartUpRecord) {
  Store store(DbPath());
  store.SaveAppliedConfig("city.yaml", "name: a", "scm", Time(seconds(1)));
  for (int i = 0; i < 10; ++i) {
    store.SaveAppliedConfig("mine.yaml", "name: " + std::to_string(i), "operator",
                            Time(seconds(2 + i)));
  }
  EXPECT_EQ(store.PruneConfigs(3), 7);
  const auto history = store.ConfigHistory(100);
  ASSERT_EQ(history.size(), 4u);
  EXPECT_EQ(history[0].id, 11);
  EXPECT_EQ(history[3].applied_by, "scm") << "the start-up record stays";
  EXPECT_EQ(store.ConfigCount(), 4);
  EXPECT_THROW((void)store.PruneConfigs(0), InputError);
}

}  // namespace
}  // namespace autodrive::scm
