#include "scm/store/persistence.h"

#include <spdlog/spdlog.h>

#include "common/error.h"

namespace autodrive::scm {

namespace {
// Events written per transaction at most: a burst is batched, and one batch never holds the
// database for long.
constexpr std::size_t kBatch = 512;
}  // namespace

Persistence::Persistence(Store store, std::function<void()> wake)
    : store_(std::move(store)), wake_(std::move(wake)) {
  hires_.reserve(kMaxQueuedHires);
  stats_.event_count = store_.EventCount();
  stats_.size_bytes = store_.SizeBytes();
  thread_ = std::jthread([this](std::stop_token stop) { Run(stop); });
}

Persistence::~Persistence() {
  Flush();
  thread_.request_stop();
  cv_.notify_all();
  thread_.join();
}

bool Persistence::AppendEvent(EventRecord event) {
  {
    std::lock_guard lock(mutex_);
    if (events_.size() >= kMaxQueuedEvents) {
      ++stats_.events_dropped;
      return false;
    }
    events_.push_back(std::move(event));
  }
  cv_.notify_one();
  return true;
}

void Persistence::AppendHires(const std::vector<HiresRecord>& records) {
  if (records.empty()) return;
  {
    std::lock_guard lock(mutex_);
    const std::size_t room = kMaxQueuedHires - std::min(kMaxQueuedHires, hires_.size());
    const std::size_t taken = std::min(room, records.size());
    hires_.insert(hires_.end(), records.begin(),
                  records.begin() + static_cast<std::ptrdiff_t>(taken));
    stats_.hires_dropped += records.size() - taken;
  }
  cv_.notify_one();
}

void Persistence::QueryHires(HiresQuery query,
                             std::function<void(std::vector<HiresRecord>, std::string)> done) {
  Post([this, query, done = std::move(done)]() mutable {
    std::vector<HiresRecord> records;
    std::string error;
    try {
      records = store_.Hires(query);
    } catch (const std::exception& e) {
      error = e.what();
    }
    Complete([done = std::move(done), records = std::move(records),
              error = std::move(error)]() mutable { done(std::move(records), std::move(error)); });
  });
}

void Persistence::SaveIntersectionState(IntersectionStateRecord state) {
  {
    std::lock_guard lock(mutex_);
    states_.insert_or_assign(state.intersection.value(), std::move(state));
  }
  cv_.notify_one();
}

void Persistence::Post(Job job) {
  {
    std::lock_guard lock(mutex_);
    jobs_.push_back(std::move(job));
  }
  cv_.notify_one();
}

void Persistence::Complete(std::function<void()> completion) {
  {
    std::lock_guard lock(mutex_);
    completions_.push_back(std::move(completion));
    has_completions_.store(true);
  }
  if (wake_) wake_();
}

void Persistence::SaveAppliedConfig(
    std::string path, std::string yaml, std::string applied_by, Time at,
    std::function<void(std::optional<std::int64_t>, std::string)> done) {
  Post([this, path = std::move(path), yaml = std::move(yaml), applied_by = std::move(applied_by),
        at, done = std::move(done)]() mutable {
    std::optional<std::int64_t> id;
    std::string error;
    try {
      id = store_.SaveAppliedConfig(path, yaml, applied_by, at);
    } catch (const std::exception& e) {
      error = e.what();
      std::lock_guard lock(mutex_);
      ++stats_.failures;
    }
    Complete([done = std::move(done), id, error = std::move(error)]() mutable {
      done(id, std::move(error));
    });
  });
}

void Persistence::QueryEvents(EventQuery query,
                              std::function<void(std::vector<EventRecord>, std::string)> done) {
  Post([this, query, done = std::move(done)]() mutable {
    std::vector<EventRecord> events;
    std::string error;
    try {
      events = store_.Events(query);
    } catch (const std::exception& e) {
      error = e.what();
    }
    Complete([done = std::move(done), events = std::move(events),
              error = std::move(error)]() mutable { done(std::move(events), std::move(error)); });
  });
}

void Persistence::Prune(Time now, const RetentionPolicy& policy) {
  Post([this, now, policy] {
    try {
      const std::int64_t events = store_.PruneEvents(now - policy.max_event_age, policy.max_events);
      const std::int64_t configs = store_.PruneConfigs(policy.max_configs);
      const std::int64_t hires = store_.PruneHires(now - policy.max_event_age, policy.max_hires);
      const std::int64_t count = store_.EventCount();
      const std::int64_t size = store_.SizeBytes();
      std::lock_guard lock(mutex_);
      stats_.events_pruned += static_cast<std::uint64_t>(events);
      stats_.configs_pruned += static_cast<std::uint64_t>(configs);
      stats_.hires_pruned += static_cast<std::uint64_t>(hires);
      stats_.event_count = count;
      stats_.size_bytes = size;
    } catch (const std::exception& e) {
      spdlog::error("event log: pruning failed: {}", e.what());
      std::lock_guard lock(mutex_);
      ++stats_.failures;
    }
  });
}

void Persistence::RunCompletions() {
  if (!has_completions_.load()) return;
  std::vector<std::function<void()>> ready;
  {
    std::lock_guard lock(mutex_);
    ready.swap(completions_);
    has_completions_.store(false);
  }
  for (auto& c : ready) c();
}

void Persistence::Flush() {
  std::unique_lock lock(mutex_);
  idle_cv_.wait(lock, [&] {
    return events_.empty() && hires_.empty() && states_.empty() && jobs_.empty() && !busy_;
  });
}

PersistenceStats Persistence::stats() const {
  std::lock_guard lock(mutex_);
  PersistenceStats s = stats_;
  s.queued = events_.size() + hires_.size() + states_.size() + jobs_.size();
  return s;
}

void Persistence::Run(const std::stop_token& stop) {
  std::vector<EventRecord> batch;
  batch.reserve(kBatch);
  std::vector<HiresRecord> hires;
  hires.reserve(kMaxQueuedHires);
  for (;;) {
    std::optional<IntersectionStateRecord> state;
    Job job;
    {
      std::unique_lock lock(mutex_);
      busy_ = false;
      idle_cv_.notify_all();
      const auto work = [&] {
        return !events_.empty() || !hires_.empty() || !states_.empty() || !jobs_.empty();
      };
      cv_.wait(lock, stop, work);
      if (!work()) return;  // stop requested
      busy_ = true;
      while (!events_.empty() && batch.size() < kBatch) {
        batch.push_back(std::move(events_.front()));
        events_.pop_front();
      }
      if (batch.empty() && !hires_.empty()) hires.swap(hires_);  // all of it, in one go
      if (batch.empty() && hires.empty() && !states_.empty()) {
        state = std::move(states_.begin()->second);
        states_.erase(states_.begin());
      }
      if (batch.empty() && hires.empty() && !state && !jobs_.empty()) {
        job = std::move(jobs_.front());
        jobs_.pop_front();
      }
    }
    // Outside the lock: SQLite may take milliseconds (fsync) while the loop keeps queueing.
    if (!batch.empty()) {
      try {
        store_.AppendEvents(batch);
        std::lock_guard lock(mutex_);
        stats_.events_written += batch.size();
        stats_.event_count += static_cast<std::int64_t>(batch.size());
      } catch (const std::exception& e) {
        spdlog::error("event log: cannot store {} events: {}", batch.size(), e.what());
        std::lock_guard lock(mutex_);
        ++stats_.failures;
      }
      batch.clear();
    } else if (!hires.empty()) {
      try {
        store_.AppendHires(hires);
        std::lock_guard lock(mutex_);
        stats_.hires_written += hires.size();
      } catch (const std::exception& e) {
        spdlog::error("high-resolution log: cannot store {} records: {}", hires.size(), e.what());
        std::lock_guard lock(mutex_);
        ++stats_.failures;
      }
      hires.clear();
    } else if (state) {
      try {
        store_.SaveIntersectionState(*state);
        std::lock_guard lock(mutex_);
        ++stats_.states_written;
      } catch (const std::exception& e) {
        spdlog::error("cannot save the state of intersection {}: {}", state->intersection.value(),
                      e.what());
        std::lock_guard lock(mutex_);
        ++stats_.failures;
      }
    } else if (job) {
      job();
    }
  }
}

}  // namespace autodrive::scm
