#pragma once
/// @file
/// Time in the AutoDRIVE system (see docs/time.md).
///
/// Two timelines, two types, never mixed:
/// - `autodrive::Time` is *system time*, what goes on the wire: the wall clock (ns since the
///   Unix epoch) on the real track, `/clock` in simulation. Message stamps, SPaT times, the
///   event log and time-of-day schedules use it.
/// - `autodrive::MonoTime` is the *control timeline*: monotonic, so that durations measured on
///   it (min green, yellow, red clearance, time-outs) cannot be shortened or stretched by a
///   step of the wall clock (NTP, an operator's `date -s`). It is the computer's steady clock on
///   the real track and the simulated time in simulation. It never goes on the wire.
///
/// A process builds one `Clock` at start-up (a `WallClock` or a `SimClock`). `Clock::Read`
/// returns both timelines from one consistent mapping (`ClockReading`), so a loop that reads
/// once per pass converts every control instant it publishes with the same offset
/// (`ClockReading::ToWire`). Neither type converts from `std::chrono::system_clock` or
/// `steady_clock` time points, so reading the computer's clocks directly and mixing them with
/// either timeline does not compile. Intervals measured for their own sake (benchmarks, I/O
/// time-outs) use `std::chrono::steady_clock`.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
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
/// the simulation's epoch (simulated clock; the simulator decides, usually 0). For the wire.
using Time = SystemTimeClock::time_point;

/// The tag clock of `MonoTime`. No static `now()`: ask a `Clock` object.
struct MonotonicTimeClock {
  using rep = std::int64_t;
  using period = std::nano;
  using duration = Duration;
  using time_point = std::chrono::time_point<MonotonicTimeClock, Duration>;
  static constexpr bool is_steady = true;
};

/// An instant on the control timeline (see the file comment): the steady clock's nanoseconds
/// on the real track, the simulated time in simulation. Monotonic within a clock session
/// (`ClockReading::session`); a simulator restart starts a new session.
using MonoTime = MonotonicTimeClock::time_point;

/// Seconds as a double, for printing and for maths that needs it (never for interfaces).
[[nodiscard]] constexpr double ToSeconds(Duration d) {
  return std::chrono::duration<double>(d).count();
}
/// Seconds since the clock's epoch, as a double.
[[nodiscard]] constexpr double ToSeconds(Time t) { return ToSeconds(t.time_since_epoch()); }
/// Seconds since the control timeline's origin, as a double.
[[nodiscard]] constexpr double ToSeconds(MonoTime t) { return ToSeconds(t.time_since_epoch()); }
/// A Duration from a number of seconds, rounded to the nearest nanosecond.
[[nodiscard]] Duration FromSeconds(double seconds);
/// A Time from seconds since the clock's epoch, rounded to the nearest nanosecond.
[[nodiscard]] Time TimeFromSeconds(double seconds);
/// The system clock's time now (`std::chrono::system_clock`), for stamps of live data and
/// latency figures. Durations that safety depends on are measured on a `Clock`'s monotonic
/// time instead (docs/time.md).
[[nodiscard]] Time SystemNow();
/// A MonoTime from seconds since the timeline's origin (tests, simulation).
[[nodiscard]] MonoTime MonoFromSeconds(double seconds);
/// "12.345678901s" style text of a time point, for logs.
[[nodiscard]] std::string ToString(Time t);
/// "mono 12.345678901s".
[[nodiscard]] std::string ToString(MonoTime t);

/// Which clock a process runs on.
enum class ClockKind { kWall, kSimulated };
/// "wall" or "simulated".
[[nodiscard]] const char* ToString(ClockKind kind);

/// One reading of a clock: a control instant, the system time that corresponds to it, and
/// the session they belong to. A loop reads once per pass and converts every control instant
/// it publishes with `ToWire`, so all the times of one message share one mapping.
struct ClockReading {
  MonoTime mono{};
  Time wire{};
  /// Increments when the control timeline restarts (a simulator restart: `/clock` went back).
  std::uint64_t session = 0;

  /// The system time of control instant `t` under this reading's mapping.
  [[nodiscard]] Time ToWire(MonoTime t) const { return wire + (t - mono); }
  /// The control instant of system time `t` under this reading's mapping.
  [[nodiscard]] MonoTime FromWire(Time t) const { return mono + (t - wire); }
};

/// The clock the system runs on. Thread-safe. Implementations: `WallClock`, `SimClock`.
/// Not copyable or movable (threads may be waiting on it).
class Clock {
 public:
  Clock() = default;
  Clock(const Clock&) = delete;
  Clock& operator=(const Clock&) = delete;
  virtual ~Clock() = default;

  /// Both timelines now, from one consistent mapping.
  [[nodiscard]] virtual ClockReading Read() const = 0;
  /// The current system time (`Read().wire`).
  [[nodiscard]] Time Now() const { return Read().wire; }
  /// The current control instant (`Read().mono`).
  [[nodiscard]] MonoTime Monotonic() const { return Read().mono; }
  /// Which kind of clock this is.
  [[nodiscard]] virtual ClockKind kind() const = 0;
  /// Blocks until the control timeline reaches `deadline`, the clock starts a new session, or
  /// `Interrupt()` is called. Returns false when interrupted, true otherwise (the caller
  /// checks the session). After `Interrupt()` every call returns false at once.
  virtual bool SleepUntil(MonoTime deadline) = 0;
  /// Blocks for `d` of control time; see `SleepUntil`.
  bool SleepFor(Duration d) { return SleepUntil(Monotonic() + d); }
  /// Wakes every sleeper and makes all later sleeps return false (used at shutdown).
  virtual void Interrupt() = 0;
  /// True once `Interrupt()` has been called.
  [[nodiscard]] virtual bool interrupted() const = 0;

  /// How long in real (steady) time until the control timeline reaches `deadline`, when that
  /// is known: the wall clock knows; a simulated clock does not (its time moves when `/clock`
  /// says) and returns nothing; the caller then relies on `SetWaker`/`WakeAt`.
  [[nodiscard]] virtual std::optional<Duration> RealTimeUntil(MonoTime deadline) const = 0;
  /// Sets the function that `WakeAt` calls: for a loop that blocks on something else than the
  /// clock (a DDS waitset) between deadlines. Called from the thread that advances the clock;
  /// it must be quick and must not call back into the clock. Set it before the loop starts.
  virtual void SetWaker(std::function<void()> waker) = 0;
  /// Arms the waker to be called once when the control timeline reaches `deadline`, the clock
  /// starts a new session, or it is interrupted (at once when that has already happened).
  /// Replaces the previous deadline. Never allocates. The wall clock only calls it on
  /// `Interrupt` (waiters use `RealTimeUntil` for the time).
  virtual void WakeAt(MonoTime deadline) = 0;
};

/// Where a `WallClock` reads time. Tests inject sources to step the wall clock while the
/// control timeline runs evenly; programs use the defaults.
struct WallTimeSources {
  /// The wall clock; default `std::chrono::system_clock`.
  std::function<Time()> wall;
  /// The monotonic clock; default `std::chrono::steady_clock`.
  std::function<MonoTime()> monotonic;
};

/// The clock of the real track: the control timeline is the computer's steady clock, system
/// time the wall clock. The mapping between them (wall minus steady) is kept fixed and only
/// re-anchored when the wall clock is seen to step by more than `kStepThreshold` (NTP slewing
/// moves both clocks alike and never re-anchors it), so that every wire time derived from a
/// control instant is consistent from one reading to the next; `steps()` counts the jumps.
/// The waker a clock calls (`Clock::SetWaker`), called outside the clock's own lock (it may
/// take other locks) but under a lock of its own, which `Set` takes too: once `Set(nullptr)`
/// returns, no call of the old waker is running or can start, so its owner may go away.
class WakerSlot {
 public:
  void Set(std::function<void()> waker) {
    std::lock_guard lock(mutex_);
    waker_ = std::move(waker);
  }
  void Call() {
    std::lock_guard lock(mutex_);
    if (waker_) waker_();
  }

 private:
  std::mutex mutex_;
  std::function<void()> waker_;
};

class WallClock final : public Clock {
 public:
  /// A wall-clock step larger than this re-anchors the mapping.
  static constexpr Duration kStepThreshold = std::chrono::milliseconds(1);

  /// The system's clocks, or injected ones (tests).
  explicit WallClock(WallTimeSources sources = {});
  [[nodiscard]] ClockReading Read() const override;
  [[nodiscard]] ClockKind kind() const override { return ClockKind::kWall; }
  bool SleepUntil(MonoTime deadline) override;
  void Interrupt() override;
  [[nodiscard]] bool interrupted() const override;
  [[nodiscard]] std::optional<Duration> RealTimeUntil(MonoTime deadline) const override;
  void SetWaker(std::function<void()> waker) override;
  void WakeAt(MonoTime deadline) override;
  /// How many times the wall clock was seen to step (the mapping was re-anchored), and by how
  /// much in total (signed).
  [[nodiscard]] std::uint64_t steps() const;
  [[nodiscard]] Duration stepped() const;

 private:
  [[nodiscard]] Time ReadWall() const;
  [[nodiscard]] MonoTime ReadMonotonic() const;

  WallTimeSources sources_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  bool interrupted_ = false;
  mutable std::optional<Duration> offset_;  // wall - monotonic
  mutable std::uint64_t steps_ = 0;
  mutable Duration stepped_{0};
  WakerSlot waker_;
};

/// Simulated time, advanced from outside: by `/clock` messages (see
/// `dds::SimClockSubscriber`) or by a test. Both timelines are the simulated time (the mapping
/// is the identity). It reads the epoch until the first advance. Time goes backwards only when
/// the simulator restarts: a jump back of at least `kRestartThreshold` starts a new session
/// (sleepers wake and see the new session); a smaller one (reordering) is ignored and counted.
class SimClock final : public Clock {
 public:
  /// A jump back at least this large is a simulator restart.
  static constexpr Duration kRestartThreshold = std::chrono::seconds(1);
  /// What `AdvanceTo` did.
  enum class Advance { kForward, kIgnored, kRestarted };

  [[nodiscard]] ClockReading Read() const override;
  [[nodiscard]] ClockKind kind() const override { return ClockKind::kSimulated; }
  bool SleepUntil(MonoTime deadline) override;
  void Interrupt() override;
  [[nodiscard]] bool interrupted() const override;
  [[nodiscard]] std::optional<Duration> RealTimeUntil(MonoTime) const override {
    return std::nullopt;
  }
  void SetWaker(std::function<void()> waker) override;
  void WakeAt(MonoTime deadline) override;

  /// Sets the time to `t` and wakes sleepers whose deadline has come (see the class comment
  /// for time going backwards).
  Advance AdvanceTo(Time t);
  /// True once the clock has been advanced at least once.
  [[nodiscard]] bool started() const;
  /// Blocks until the first advance, or until interrupted (then false).
  bool WaitForStart();
  /// How many `AdvanceTo` calls were ignored because they went back a little.
  [[nodiscard]] std::uint64_t backward_jumps() const;
  /// How many times the simulation restarted (the session of `Read()`).
  [[nodiscard]] std::uint64_t restarts() const;

 private:
  void WakeLocked();
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  Time now_{};
  bool started_ = false;
  bool interrupted_ = false;
  std::uint64_t session_ = 0;
  std::uint64_t backward_jumps_ = 0;
  WakerSlot waker_;
  std::optional<MonoTime> wake_at_;
};

/// Paces a loop at a fixed period of a clock's control timeline (heartbeats, tools). Ticks are
/// at start + k * period; if the loop falls behind, missed ticks are skipped, not bunched; a new
/// clock session restarts the ticks from the new time. Not thread-safe.
class Ticker {
 public:
  /// @pre `period > 0`. The clock must outlive the ticker.
  Ticker(Clock& clock, Duration period);
  /// Sleeps until the next tick. Returns false when the clock was interrupted.
  bool WaitNext();
  /// Ticks skipped because the loop was late.
  [[nodiscard]] std::uint64_t missed() const { return missed_; }
  /// The time of the tick most recently waited for.
  [[nodiscard]] MonoTime last_tick() const { return next_ - period_; }

 private:
  Clock& clock_;
  Duration period_;
  MonoTime next_;
  std::uint64_t session_ = 0;
  std::uint64_t missed_ = 0;
};

}  // namespace autodrive
