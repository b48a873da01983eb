// The database behind its writer thread: nothing the loop queues is lost, the queue is bounded,
// answers come back as completions on the caller's thread, retention keeps the file flat.
#include "scm/store/persistence.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <filesystem>
#include <thread>

namespace autodrive::scm {
namespace {

using std::chrono::seconds;

class PersistenceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("scm_persistence_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string Db() const { return (dir_ / "scm.db").string(); }
  static EventRecord Ev(int i) {
    return EventRecord{0,
                       Time(seconds(1000 + i)),
                       Severity::kInfo,
                       "scm",
                       "test",
                       "event " + std::to_string(i),
                       IntersectionId(0),
                       "",
                       "scm",
                       false};
  }
  std::filesystem::path dir_;
};

TEST_F(PersistenceTest, EverythingQueuedIsWrittenAndSurvivesAReopen) {
  {
    Persistence p(Store(Db()), nullptr);
    for (int i = 0; i < 2000; ++i) ASSERT_TRUE(p.AppendEvent(Ev(i)));
    for (std::uint32_t x = 1; x <= 3; ++x) {
      for (int k = 0; k < 50; ++k) {  // coalesced: the newest state per intersection wins
        p.SaveIntersectionState(
            {IntersectionId(x), k % 2 ? "manual" : "fixed", "day", true, Time(seconds(k)), {}});
      }
    }
    p.Flush();
    EXPECT_EQ(p.stats().events_written, 2000u);
    EXPECT_EQ(p.stats().events_dropped, 0u);
    EXPECT_LE(p.stats().states_written, 150u);
  }
  Store store(Db());
  EXPECT_EQ(store.EventCount(), 2000);
  const auto states = store.LoadIntersectionStates();
  ASSERT_EQ(states.size(), 3u);
  for (const auto& s : states) EXPECT_EQ(s.mode, "manual") << "the newest state was kept";
}

TEST_F(PersistenceTest, TheQueueIsBoundedAndAFullQueueDropsAndCountsInsteadOfWaiting) {
  Persistence p(Store(Db()), nullptr);
  // Another connection holds the database: the writer thread waits in SQLite's busy handler,
  // and events pile up in the queue.
  sqlite3* other = nullptr;
  ASSERT_EQ(sqlite3_open(Db().c_str(), &other), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(other, "BEGIN EXCLUSIVE", nullptr, nullptr, nullptr), SQLITE_OK);
  std::size_t accepted = 0;
  std::size_t dropped = 0;
  for (std::size_t i = 0; i < Persistence::kMaxQueuedEvents * 3; ++i) {
    (p.AppendEvent(Ev(static_cast<int>(i))) ? accepted : dropped)++;
  }
  ASSERT_EQ(sqlite3_exec(other, "ROLLBACK", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(other);
  p.Flush();
  EXPECT_GT(dropped, 0u) << "a full queue drops rather than blocks the caller";
  EXPECT_LE(accepted, Persistence::kMaxQueuedEvents + 512) << "the queue plus one batch";
  EXPECT_EQ(p.stats().events_dropped, dropped);
  EXPECT_EQ(p.stats().events_written + p.stats().failures * 512, accepted)
      << "what was accepted was written (or its batch failed and was counted)";
}

TEST_F(PersistenceTest, AnswersComeBackOnTheCallersThreadWhenItRunsCompletions) {
  std::atomic<int> wakes{0};
  Persistence p(Store(Db()), [&] { ++wakes; });
  for (int i = 0; i < 20; ++i) p.AppendEvent(Ev(i));
  std::vector<EventRecord> got;
  std::thread::id answered_on;
  p.QueryEvents(EventQuery{std::nullopt, std::nullopt, 5, true},
                [&](std::vector<EventRecord> events, std::string error) {
                  EXPECT_EQ(error, "");
                  got = std::move(events);
                  answered_on = std::this_thread::get_id();
                });
  std::optional<std::int64_t> saved;
  p.SaveAppliedConfig("x.yaml", "name: x", "alice", Time(seconds(5)),
                      [&](std::optional<std::int64_t> id, std::string) { saved = id; });
  p.Flush();
  EXPECT_TRUE(got.empty()) << "nothing runs before the caller asks";
  EXPECT_GE(wakes.load(), 2);
  p.RunCompletions();
  ASSERT_EQ(got.size(), 5u);
  EXPECT_EQ(got[0].message, "event 19") << "newest first";
  EXPECT_EQ(answered_on, std::this_thread::get_id());
  EXPECT_EQ(saved, 1);
}

TEST_F(PersistenceTest, RetentionPrunesByAgeAndCount) {
  Persistence p(Store(Db()), nullptr);
  for (int i = 0; i < 3000; ++i) p.AppendEvent(Ev(i));
  RetentionPolicy policy;
  policy.max_event_age = seconds(1000);  // relative to the prune's "now" below
  policy.max_events = 1000;
  p.Prune(Time(seconds(1000 + 1500)), policy);  // older than 1500: i < 500 go
  p.Flush();
  EXPECT_EQ(p.stats().event_count, 1000);
  EXPECT_EQ(p.stats().events_pruned, 2000u);
  EXPECT_GT(p.stats().size_bytes, 0);
}

}  // namespace
}  // namespace autodrive::scm
