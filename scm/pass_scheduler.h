#pragma once
/// @file
/// When the daemon's loop does what: the pure rules of `Scm`'s pass, on an explicit clock. SPaT
/// (with fleet and heartbeat) is due on its period and never bunches after a late pass;
/// housekeeping every second and the event log's pruning on its period; requests are handled
/// until SPaT's deadline comes, except the few SPaT gives way to once per deadline when one waits
/// while it is being filled; the loop sleeps until the earliest deadline of the tick, SPaT,
/// housekeeping, the controllers, supervision and the device table. A pass that begins well
/// after the deadline it waited for is a stall; `StallWatch` says which stalls become events. No
/// DDS and no clock of its own: every rule takes the time, so it is tested in-process on a
/// simulated clock (pass_scheduler_test.cpp). See docs/scm.md, "Daemon behaviour".

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "common/time.h"

namespace autodrive::scm {

/// The periods the loop keeps, lab time on the control clock.
struct PassScheduleParams {
  Duration tick = std::chrono::milliseconds(20);           ///< the loop's longest sleep
  Duration spat_period = std::chrono::milliseconds(100);   ///< SPaT, fleet and heartbeat
  Duration prune_period = std::chrono::minutes(10);        ///< event log retention, checked
  Duration housekeeping_period = std::chrono::seconds(1);  ///< V2I flush, stranger operators
  /// Requests answered past SPaT's deadline when SPaT gave way to a waiting one.
  std::size_t requests_before_spat = 4;
  /// A pass that begins this long after its deadline is a stall.
  Duration stall_threshold = std::chrono::milliseconds(100);
};

/// The deadlines of the loop's other parts, for `PassScheduler::NextDeadline`.
struct OtherDeadlines {
  MonoTime controllers;  ///< the earliest controller wake (`CityRuntime::next_wake`)
  MonoTime supervision;  ///< `DeviceSupervisor::next_deadline`
  MonoTime devices;      ///< `DeviceTable::next_deadline`
};

/// What is due in the loop's pass, and when the loop wakes next. Copyable value; loop thread.
class PassScheduler {
 public:
  explicit PassScheduler(PassScheduleParams params = {});

  /// A city starts (or restarts) at `now`: SPaT, the tick and housekeeping are due at once;
  /// pruning too the first time only.
  void Start(MonoTime now);
  /// A new session of the control timeline at `now`: every deadline, pruning's included, is due
  /// at once.
  void Restart(MonoTime now);

  /// Whether SPaT's deadline has come at `now`.
  [[nodiscard]] bool SpatDue(MonoTime now) const { return now >= next_spat_; }
  /// Whether one more request may be handled at `now`: before SPaT's deadline, or one of the
  /// few SPaT gave way to.
  [[nodiscard]] bool MayHandleRequest(MonoTime now) const;
  /// Counts a request handled at `now` against those SPaT gave way to (when past its deadline).
  void CountRequest(MonoTime now);
  /// Whether SPaT's filling may still stop for a waiting request: once per deadline.
  [[nodiscard]] bool MayGiveWay() const { return !spat_gave_way_; }
  /// SPaT's filling stopped for a waiting request: the next pass answers a few first.
  void GiveWay();
  /// SPaT was sent at `now`: the next is a period after its deadline; periods missed by a late
  /// pass are skipped rather than bunched.
  void SpatSent(MonoTime now);

  /// Whether housekeeping is due at `now`.
  [[nodiscard]] bool HousekeepingDue(MonoTime now) const { return now >= next_housekeeping_; }
  /// Housekeeping runs at `now`; true when the event log is to be pruned too.
  [[nodiscard]] bool Housekeep(MonoTime now);

  /// How late a pass beginning at `now` is after the deadline the loop waited for: 0 when it
  /// began before it (woken by a request) and before the first `EndPass`.
  [[nodiscard]] Duration Lateness(MonoTime now) const;
  /// How late a pass beginning at `now` is, when it began more than the stall threshold after
  /// the deadline the loop waited for; nothing otherwise (and before the first `EndPass`).
  [[nodiscard]] std::optional<Duration> Stall(MonoTime now) const;
  /// The pass at `now` is over: the tick moves past `now` and the loop waits for
  /// `NextDeadline(now, others)`.
  void EndPass(MonoTime now, const OtherDeadlines& others);
  /// The earliest of the tick, SPaT, housekeeping, supervision, the device table and the
  /// controllers' wake. A controller due at or before `now` (the pass just run) was stepped by
  /// it; one that is due again at once asks to be stepped on every pass (a call on its green
  /// phase keeps its gap timer running): the next tick does that, rather than a wake at once
  /// that would spin the loop for as long as a car stands on the detector.
  [[nodiscard]] MonoTime NextDeadline(MonoTime now, const OtherDeadlines& others) const;

  [[nodiscard]] const PassScheduleParams& params() const { return params_; }

 private:
  PassScheduleParams params_;
  MonoTime next_spat_{};
  bool spat_gave_way_ = false;          // SPaT's filling stopped once for this deadline
  std::size_t requests_past_spat_ = 0;  // requests still allowed past SPaT's deadline
  MonoTime next_tick_{};
  MonoTime next_housekeeping_{};
  MonoTime next_prune_{};
  MonoTime planned_wake_{};  // the deadline the loop waits for after a pass
};

/// Which stalls of the loop become events: every stall of at least `event_threshold` counts,
/// and one event per `event_period` at most reports them (a simulated clock far ahead of a slow
/// SCM would otherwise fill the event log). Copyable value.
class StallWatch {
 public:
  static constexpr Duration kEventThreshold = std::chrono::milliseconds(250);
  static constexpr Duration kEventPeriod = std::chrono::minutes(10);

  /// Notes a stall of `stall` seen at `now`. Returns the number of long stalls the event about
  /// it reports (this one included) when an event is due now, else nothing.
  [[nodiscard]] std::optional<std::uint64_t> Note(Duration stall, MonoTime now);

 private:
  MonoTime last_event_{};
  std::uint64_t unreported_ = 0;  // long stalls since the last event
};

/// The loop's recent timing, for `scmctl status` (and for telling whether something beside the
/// SCM slows it): how long each of the last `kWindow` passes took and how late each began after
/// the deadline it waited for, as percentiles over that window. Copyable value; loop thread.
class LoopTimes {
 public:
  /// About a minute of passes at the loop's 20 ms tick.
  static constexpr std::size_t kWindow = 3000;

  /// Notes one pass: `work` from its start to its end, `late` its lateness (`Lateness`).
  void Note(Duration work, Duration late);
  /// The `q` quantile (0..1, nearest rank) of the passes' work and lateness in the window; 0
  /// before the first pass.
  [[nodiscard]] Duration WorkQuantile(double q) const { return Quantile(work_, q); }
  [[nodiscard]] Duration LateQuantile(double q) const { return Quantile(late_, q); }
  /// Passes in the window.
  [[nodiscard]] std::size_t size() const { return work_.size(); }

 private:
  [[nodiscard]] static Duration Quantile(std::vector<Duration> values, double q);
  std::vector<Duration> work_;  // ring buffers of kWindow at most, `next_` the oldest when full
  std::vector<Duration> late_;
  std::size_t next_ = 0;
};

}  // namespace autodrive::scm
