#pragma once
/// @file
/// An intersection's high-resolution event log as its controller writes it (docs/controller.md,
/// "High-resolution event log"): codes of the Indiana enumerations (TPF-5(377) edition, as
/// UDOT's ATSPM reads them) with their parameters, buffered until the daemon takes them for its
/// writer thread. Bounded: events no one takes are dropped and counted, never grown without end.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/time.h"

namespace autodrive::scm {

/// An event of the log: a code and its parameter, a phase number (the plan's phase, from 1), a
/// detector channel, a flash status or a plan.
struct HiresEvent {
  MonoTime at{};
  std::uint16_t code = 0;
  std::uint16_t param = 0;
  bool operator==(const HiresEvent&) const = default;
};

/// The Indiana codes the controller logs.
namespace hires {
inline constexpr std::uint16_t kPhaseOn = 0;
inline constexpr std::uint16_t kPhaseBeginGreen = 1;
inline constexpr std::uint16_t kPhaseCheck = 2;  ///< a conflicting call: max timing starts
inline constexpr std::uint16_t kPhaseMinComplete = 3;
inline constexpr std::uint16_t kPhaseGapOut = 4;
inline constexpr std::uint16_t kPhaseMaxOut = 5;
inline constexpr std::uint16_t kPhaseForceOff = 6;
inline constexpr std::uint16_t kPhaseGreenTermination = 7;
inline constexpr std::uint16_t kPhaseBeginYellow = 8;
inline constexpr std::uint16_t kPhaseEndYellow = 9;
inline constexpr std::uint16_t kPhaseBeginRedClearance = 10;
inline constexpr std::uint16_t kPhaseEndRedClearance = 11;
inline constexpr std::uint16_t kPhaseInactive = 12;
inline constexpr std::uint16_t kTspEarlyForceOff = 19;
inline constexpr std::uint16_t kPhaseHoldActive = 41;
inline constexpr std::uint16_t kPhaseHoldReleased = 42;
inline constexpr std::uint16_t kPhaseCallRegistered = 43;
inline constexpr std::uint16_t kPhaseCallDropped = 44;
inline constexpr std::uint16_t kPhaseOmitOn = 46;
inline constexpr std::uint16_t kPhaseOmitOff = 47;
inline constexpr std::uint16_t kPedCallRegistered = 45;
inline constexpr std::uint16_t kPedOmitOn = 48;
inline constexpr std::uint16_t kPedOmitOff = 49;
inline constexpr std::uint16_t kPreemptionForceOff = 20;
inline constexpr std::uint16_t kDetectorOff = 81;
inline constexpr std::uint16_t kPreemptCallInputOn = 102;
inline constexpr std::uint16_t kPreemptCallInputOff = 104;
inline constexpr std::uint16_t kPreemptEntryStarted = 105;
inline constexpr std::uint16_t kPreemptBeginTrackClearance = 106;
inline constexpr std::uint16_t kPreemptBeginDwell = 107;
inline constexpr std::uint16_t kPreemptMaxPresenceExceeded = 110;
inline constexpr std::uint16_t kPreemptBeginExit = 111;
inline constexpr std::uint16_t kTspCheckIn = 112;
inline constexpr std::uint16_t kTspEarlyGreen = 113;
inline constexpr std::uint16_t kTspExtendGreen = 114;
inline constexpr std::uint16_t kTspCheckOut = 115;
/// The preempt and TSP number of V2I requests (one of each: a request replaces another).
inline constexpr std::uint16_t kV2iRequestNumber = 1;
inline constexpr std::uint16_t kDetectorOn = 82;
inline constexpr std::uint16_t kCoordPatternChange = 131;
inline constexpr std::uint16_t kUnitFlashStatusChange = 173;
/// unitFlashStatus values (NTCIP 1202 asc.3.6), the parameter of code 173.
inline constexpr std::uint16_t kNotFlash = 2;
inline constexpr std::uint16_t kFlashAutomatic = 3;     ///< a plan's or the operator's flash
inline constexpr std::uint16_t kFlashFaultMonitor = 5;  ///< fail-safe
inline constexpr std::uint16_t kFlashStartup = 7;
}  // namespace hires

/// The events of one intersection waiting to be taken, and the unit's flash status as last
/// logged (code 173 is written on changes only). Copyable with its controller.
class HiresLog {
 public:
  static constexpr std::size_t kMaxEvents = 4096;

  /// Starts with the start-up flash status logged at `now`.
  explicit HiresLog(MonoTime now) { Log(now, hires::kUnitFlashStatusChange, flash_status_); }

  /// Logs `code` with `param` at `at`, or counts it dropped when `kMaxEvents` wait.
  void Log(MonoTime at, std::uint16_t code, std::uint16_t param);
  /// Logs a unit flash status change (code 173) when `status` is not the last logged.
  void SetFlashStatus(MonoTime at, std::uint16_t status);

  /// The events since the last call, oldest first.
  std::vector<HiresEvent> Take();
  /// The events waiting, oldest first; `Clear` after reading them keeps the buffer.
  [[nodiscard]] const std::vector<HiresEvent>& events() const { return events_; }
  void Clear() { events_.clear(); }
  /// Events dropped because no one took them.
  [[nodiscard]] std::uint64_t dropped() const { return dropped_; }

 private:
  std::vector<HiresEvent> events_;
  std::uint64_t dropped_ = 0;
  std::uint16_t flash_status_ = hires::kFlashStartup;
};

}  // namespace autodrive::scm
