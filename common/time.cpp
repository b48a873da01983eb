#include "common/time.h"

#include <cmath>
#include <cstdio>

#include "common/error.h"

namespace autodrive {

Duration FromSeconds(double seconds) {
  AUTODRIVE_THROW_UNLESS(std::isfinite(seconds) && std::abs(seconds) < 9.2e9,
                         "a time in seconds must be finite and below 9.2e9, got " << seconds);
  return Duration(static_cast<Duration::rep>(std::llround(seconds * 1e9)));
}

Time TimeFromSeconds(double seconds) { return Time(FromSeconds(seconds)); }

MonoTime MonoFromSeconds(double seconds) { return MonoTime(FromSeconds(seconds)); }

namespace {
std::string SecondsText(std::int64_t ns) {
  const auto sec = ns / 1'000'000'000;
  const auto frac = std::abs(ns % 1'000'000'000);
  char buffer[48];
  std::snprintf(buffer, sizeof buffer, "%s%lld.%09llds", (ns < 0 && sec == 0) ? "-" : "",
                static_cast<long long>(sec), static_cast<long long>(frac));
  return buffer;
}
}  // namespace

std::string ToString(Time t) { return SecondsText(t.time_since_epoch().count()); }

std::string ToString(MonoTime t) { return "mono " + SecondsText(t.time_since_epoch().count()); }

const char* ToString(ClockKind kind) {
  switch (kind) {
    case ClockKind::kWall:
      return "wall";
    case ClockKind::kSimulated:
      return "simulated";
  }
  return "?";
}

// --- WallClock ------------------------------------------------------------------------------

WallClock::WallClock(WallTimeSources sources) : sources_(std::move(sources)) {}

Time SystemNow() {
  return Time(
      std::chrono::duration_cast<Duration>(std::chrono::system_clock::now().time_since_epoch()));
}

Time WallClock::ReadWall() const {
  if (sources_.wall) return sources_.wall();
  return SystemNow();
}

MonoTime WallClock::ReadMonotonic() const {
  if (sources_.monotonic) return sources_.monotonic();
  return MonoTime(
      std::chrono::duration_cast<Duration>(std::chrono::steady_clock::now().time_since_epoch()));
}

ClockReading WallClock::Read() const {
  // Read the wall clock between two readings of the steady clock and keep the tightest of a
  // few tries, so that a preemption between the two reads is not mistaken for a step.
  MonoTime mono{};
  Time wall{};
  Duration best_gap = Duration::max();
  for (int attempt = 0; attempt < 3; ++attempt) {
    const MonoTime before = ReadMonotonic();
    const Time w = ReadWall();
    const MonoTime after = ReadMonotonic();
    const Duration gap = after - before;
    if (gap < best_gap) {
      best_gap = gap;
      mono = before + gap / 2;
      wall = w;
    }
    if (gap < std::chrono::microseconds(50)) break;
  }
  std::lock_guard lock(mutex_);
  const Duration observed = wall.time_since_epoch() - mono.time_since_epoch();
  if (!offset_) {
    offset_ = observed;
  } else if (const Duration jump = observed - *offset_;
             jump > kStepThreshold || jump < -kStepThreshold) {
    ++steps_;
    stepped_ += jump;
    offset_ = observed;
  }
  return ClockReading{mono, Time(mono.time_since_epoch() + *offset_), 0};
}

bool WallClock::SleepUntil(MonoTime deadline) {
  std::unique_lock lock(mutex_);
  for (;;) {
    if (interrupted_) return false;
    lock.unlock();
    const MonoTime now = ReadMonotonic();
    lock.lock();
    if (now >= deadline) return !interrupted_;
    // The steady clock paces the wait: a step of the wall clock cannot stretch or cut it.
    cv_.wait_for(lock, deadline - now, [&] { return interrupted_; });
  }
}

void WallClock::Interrupt() {
  {
    std::lock_guard lock(mutex_);
    interrupted_ = true;
  }
  cv_.notify_all();
  waker_.Call();
}

bool WallClock::interrupted() const {
  std::lock_guard lock(mutex_);
  return interrupted_;
}

std::optional<Duration> WallClock::RealTimeUntil(MonoTime deadline) const {
  return deadline - ReadMonotonic();
}

void WallClock::SetWaker(std::function<void()> waker) { waker_.Set(std::move(waker)); }

void WallClock::WakeAt(MonoTime /*deadline*/) {
  // Waiters on the wall clock time themselves (RealTimeUntil); only an interrupt wakes them.
  bool fire = false;
  {
    std::lock_guard lock(mutex_);
    fire = interrupted_;
  }
  if (fire) waker_.Call();
}

std::uint64_t WallClock::steps() const {
  std::lock_guard lock(mutex_);
  return steps_;
}

Duration WallClock::stepped() const {
  std::lock_guard lock(mutex_);
  return stepped_;
}

// --- SimClock -------------------------------------------------------------------------------

ClockReading SimClock::Read() const {
  std::lock_guard lock(mutex_);
  return ClockReading{MonoTime(now_.time_since_epoch()), now_, session_};
}

bool SimClock::SleepUntil(MonoTime deadline) {
  std::unique_lock lock(mutex_);
  const std::uint64_t session = session_;
  cv_.wait(lock, [&] {
    return interrupted_ || session_ != session ||
           now_.time_since_epoch() >= deadline.time_since_epoch();
  });
  return !interrupted_;
}

void SimClock::Interrupt() {
  {
    std::lock_guard lock(mutex_);
    interrupted_ = true;
    wake_at_.reset();
  }
  cv_.notify_all();
  waker_.Call();
}

bool SimClock::interrupted() const {
  std::lock_guard lock(mutex_);
  return interrupted_;
}

void SimClock::SetWaker(std::function<void()> waker) { waker_.Set(std::move(waker)); }

void SimClock::WakeAt(MonoTime deadline) {
  // The waker is called outside the clock's lock (it may take other locks), under its slot's.
  bool fire = false;
  {
    std::lock_guard lock(mutex_);
    if (interrupted_ || now_.time_since_epoch() >= deadline.time_since_epoch()) {
      fire = true;
      wake_at_.reset();
    } else {
      wake_at_ = deadline;
    }
  }
  if (fire) waker_.Call();
}

SimClock::Advance SimClock::AdvanceTo(Time t) {
  Advance result = Advance::kForward;
  bool fire = false;
  {
    std::lock_guard lock(mutex_);
    if (started_ && t < now_) {
      if (now_ - t < kRestartThreshold) {
        ++backward_jumps_;
        return Advance::kIgnored;
      }
      ++session_;
      result = Advance::kRestarted;
    }
    now_ = t;
    started_ = true;
    if (wake_at_ && (result == Advance::kRestarted ||
                     now_.time_since_epoch() >= wake_at_->time_since_epoch())) {
      wake_at_.reset();
      fire = true;
    }
  }
  cv_.notify_all();
  if (fire) waker_.Call();
  return result;
}

bool SimClock::started() const {
  std::lock_guard lock(mutex_);
  return started_;
}

bool SimClock::WaitForStart() {
  std::unique_lock lock(mutex_);
  cv_.wait(lock, [&] { return interrupted_ || started_; });
  return !interrupted_;
}

std::uint64_t SimClock::backward_jumps() const {
  std::lock_guard lock(mutex_);
  return backward_jumps_;
}

std::uint64_t SimClock::restarts() const {
  std::lock_guard lock(mutex_);
  return session_;
}

// --- Ticker ---------------------------------------------------------------------------------

Ticker::Ticker(Clock& clock, Duration period) : clock_(clock), period_(period) {
  AUTODRIVE_CHECK(period > Duration::zero(), "period=" << period.count() << "ns");
  const ClockReading r = clock_.Read();
  next_ = r.mono + period_;
  session_ = r.session;
}

bool Ticker::WaitNext() {
  for (;;) {
    ClockReading r = clock_.Read();
    if (r.session == session_ && r.mono < next_) {
      if (!clock_.SleepUntil(next_)) return false;
      r = clock_.Read();
    }
    if (clock_.interrupted()) return false;
    if (r.session != session_) {
      // The control timeline restarted: tick from its new time.
      session_ = r.session;
      next_ = r.mono + period_;
      continue;
    }
    if (r.mono < next_) continue;
    next_ += period_;
    if (r.mono >= next_) {
      // Late by one period or more: skip the ticks we missed instead of firing them in a burst.
      const auto behind = (r.mono - next_) / period_ + 1;
      missed_ += static_cast<std::uint64_t>(behind);
      next_ += behind * period_;
    }
    return true;
  }
}

}  // namespace autodrive
