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

std::string ToString(Time t) {
  const auto ns = t.time_since_epoch().count();
  const auto sec = ns / 1'000'000'000;
  const auto frac = std::abs(ns % 1'000'000'000);
  char buffer[48];
  std::snprintf(buffer, sizeof buffer, "%s%lld.%09llds", (ns < 0 && sec == 0) ? "-" : "",
                static_cast<long long>(sec), static_cast<long long>(frac));
  return buffer;
}

const char* ToString(ClockKind kind) {
  switch (kind) {
    case ClockKind::kWall:
      return "wall";
    case ClockKind::kSimulated:
      return "simulated";
  }
  return "?";
}

Time WallClock::Now() const {
  const auto since_epoch = std::chrono::system_clock::now().time_since_epoch();
  return Time(std::chrono::duration_cast<Duration>(since_epoch));
}

bool WallClock::SleepUntil(Time deadline) {
  const std::chrono::system_clock::time_point wall_deadline(
      std::chrono::duration_cast<std::chrono::system_clock::duration>(deadline.time_since_epoch()));
  std::unique_lock lock(mutex_);
  // Waiting on the system clock follows wall-clock adjustments, as the system's time does.
  cv_.wait_until(lock, wall_deadline, [&] { return interrupted_; });
  return !interrupted_;
}

void WallClock::Interrupt() {
  {
    std::lock_guard lock(mutex_);
    interrupted_ = true;
  }
  cv_.notify_all();
}

bool WallClock::interrupted() const {
  std::lock_guard lock(mutex_);
  return interrupted_;
}

Time SimClock::Now() const {
  std::lock_guard lock(mutex_);
  return now_;
}

bool SimClock::SleepUntil(Time deadline) {
  std::unique_lock lock(mutex_);
  cv_.wait(lock, [&] { return interrupted_ || now_ >= deadline; });
  return !interrupted_;
}

void SimClock::Interrupt() {
  {
    std::lock_guard lock(mutex_);
    interrupted_ = true;
  }
  cv_.notify_all();
}

bool SimClock::interrupted() const {
  std::lock_guard lock(mutex_);
  return interrupted_;
}

bool SimClock::AdvanceTo(Time t) {
  {
    std::lock_guard lock(mutex_);
    if (started_ && t < now_) {
      ++backward_jumps_;
      return false;
    }
    now_ = t;
    started_ = true;
  }
  cv_.notify_all();
  return true;
}

bool SimClock::started() const {
  std::lock_guard lock(mutex_);
  return started_;
}

std::uint64_t SimClock::backward_jumps() const {
  std::lock_guard lock(mutex_);
  return backward_jumps_;
}

Ticker::Ticker(Clock& clock, Duration period)
    : clock_(clock), period_(period), next_(clock.Now() + period) {
  AUTODRIVE_CHECK(period > Duration::zero(), "period=" << period.count() << "ns");
}

bool Ticker::WaitNext() {
  if (!clock_.SleepUntil(next_)) {
    return false;
  }
  const Time now = clock_.Now();
  next_ += period_;
  if (now >= next_) {
    // Late by one period or more: skip the ticks we missed instead of firing them in a burst.
    const auto behind = (now - next_) / period_ + 1;
    missed_ += static_cast<std::uint64_t>(behind);
    next_ += behind * period_;
  }
  return true;
}

}  // namespace autodrive
