#pragma once
/// @file
/// Time in the AutoDRIVE system (see docs/time.md).
///
/// There is one time type, `autodrive::Time`: an instant in *the clock the system runs on*,
/// which is the wall clock on the real track and `/clock` in simulation. A process chooses its
/// clock once at start-up (a `WallClock` or a `SimClock`) and every timestamp it makes comes
/// from that `Clock` object. `Time` is a distinct type from `std::chrono::system_clock` and
/// `std::chrono::steady_clock` time points, so reading the computer's clock directly and mixing
/// it with system time does not compile. Intervals that are measured rather than scheduled
/// (benchmarks, timeouts on I/O) use `std::chrono::steady_clock`, which is also a distinct type.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>

namespace autodrive {

/// A span of time, nanosecond resolution. Config keys carry the unit in their name (`yellow_s`).
using Duration = std::chrono::nanoseconds;

/// The tag clock of `Time`. It deliberately has no static `now()`: ask a `Clock` object.
struct SystemTimeClock {
  using rep = std::int64_t;
  using period = std::nano;
  using duration = Duration;
  using time_point = std::chrono::time_point<SystemTimeClock, Duration>;
  static constexpr bool is_steady = false;
};

/// An instant in the system's clock, nanoseconds since the Unix epoch (wall clock) or since
/// the simulation's epoch (simulated clock; the simulator decides, usually 0).
using Time = SystemTimeClock::time_point;

/// Seconds as a double, for printing and for maths that needs it (never for interfaces).
[[nodiscard]] constexpr double ToSeconds(Duration d) {
  return std::chrono::duration<double>(d).count();
}
/// Seconds since the clock's epoch, as a double.
[[nodiscard]] constexpr double ToSeconds(Time t) { return ToSeconds(t.time_since_epoch()); }
/// A Duration from a number of seconds, rounded to the nearest nanosecond.
[[nodiscard]] Duration FromSeconds(double seconds);
/// A Time from seconds since the clock's epoch, rounded to the nearest nanosecond.
[[nodiscard]] Time TimeFromSeconds(double seconds);
/// "12.345678901s" style text of a time point, for logs.
[[nodiscard]] std::string ToString(Time t);

/// Which clock a process runs on.
enum class ClockKind { kWall, kSimulated };
/// "wall" or "simulated".
[[nodiscard]] const char* ToString(ClockKind kind);

/// The clock the system runs on. Thread-safe. Implementations: `WallClock`, `SimClock`.
/// Not copyable or movable (threads may be waiting on it).
class Clock {
 public:
  Clock() = default;
  Clock(const Clock&) = delete;
  Clock& operator=(const Clock&) = delete;
  virtual ~Clock() = default;

  /// The current time.
  [[nodiscard]] virtual Time Now() const = 0;
  /// Which kind of clock this is.
  [[nodiscard]] virtual ClockKind kind() const = 0;
  /// Blocks until `Now() >= deadline` or until `Interrupt()` is called. Returns true when the
  /// deadline was reached, false when interrupted. After `Interrupt()` every call returns false
  /// at once.
  virtual bool SleepUntil(Time deadline) = 0;
  /// Blocks for `d` of this clock's time; see `SleepUntil`.
  bool SleepFor(Duration d) { return SleepUntil(Now() + d); }
  /// Wakes every sleeper and makes all later sleeps return false (used at shutdown).
  virtual void Interrupt() = 0;
  /// True once `Interrupt()` has been called.
  [[nodiscard]] virtual bool interrupted() const = 0;
};

/// The wall clock (`std::chrono::system_clock`), as used on the real track.
class WallClock final : public Clock {
 public:
  [[nodiscard]] Time Now() const override;
  [[nodiscard]] ClockKind kind() const override { return ClockKind::kWall; }
  bool SleepUntil(Time deadline) override;
  void Interrupt() override;
  [[nodiscard]] bool interrupted() const override;

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  bool interrupted_ = false;
};

/// Simulated time, advanced from outside: by `/clock` messages (see
/// `dds::SimClockSubscriber`) or by a test. It reads `Time{}` (the epoch) until the first
/// advance. Time never goes backwards: an `AdvanceTo` to an earlier time is ignored and
/// counted (a simulator restart shows up that way), so that deadlines stay meaningful.
class SimClock final : public Clock {
 public:
  [[nodiscard]] Time Now() const override;
  [[nodiscard]] ClockKind kind() const override { return ClockKind::kSimulated; }
  bool SleepUntil(Time deadline) override;
  void Interrupt() override;
  [[nodiscard]] bool interrupted() const override;

  /// Sets the time to `t` and wakes sleepers whose deadline has come. Returns false (and
  /// changes nothing) when `t` is earlier than the current time.
  bool AdvanceTo(Time t);
  /// True once the clock has been advanced at least once.
  [[nodiscard]] bool started() const;
  /// How many `AdvanceTo` calls were ignored because they went backwards.
  [[nodiscard]] std::uint64_t backward_jumps() const;

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  Time now_{};
  bool started_ = false;
  bool interrupted_ = false;
  std::uint64_t backward_jumps_ = 0;
};

/// Paces a loop at a fixed period on a `Clock` (SPaT at 10 Hz, heartbeats). Ticks are at
/// start + k * period; if the loop falls behind, missed ticks are skipped, not bunched.
/// Copyable only by reference to the same clock; not thread-safe.
class Ticker {
 public:
  /// @pre `period > 0`. The clock must outlive the ticker.
  Ticker(Clock& clock, Duration period);
  /// Sleeps until the next tick. Returns false when the clock was interrupted.
  bool WaitNext();
  /// Ticks skipped because the loop was late.
  [[nodiscard]] std::uint64_t missed() const { return missed_; }
  /// The time of the tick most recently waited for.
  [[nodiscard]] Time last_tick() const { return next_ - period_; }

 private:
  Clock& clock_;
  Duration period_;
  Time next_;
  std::uint64_t missed_ = 0;
};

}  // namespace autodrive
