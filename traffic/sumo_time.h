#pragma once
/// @file
/// SUMO's own clock: the simulated time of SUMO's run, a timeline of its own (it starts at 0
/// with SUMO, steps by `step_s`, and is neither the control timeline `MonoTime` nor the wire's
/// `Time`). SUMO's API speaks seconds as `double`; they become a `SumoTime` at the co-simulation's
/// edge (`CoSimulation::Step`) and nowhere else, so that the rules (all-way stops, demand) count
/// whole nanoseconds. SUMO's clock counts milliseconds, so the conversion is exact both ways.

#include <chrono>
#include <cstdint>

#include "common/time.h"

namespace autodrive::traffic {

/// The tag clock of `SumoTime`. No static `now()`: SUMO says what time it is.
struct SumoClock {
  using rep = std::int64_t;
  using period = std::nano;
  using duration = Duration;
  using time_point = std::chrono::time_point<SumoClock, Duration>;
  static constexpr bool is_steady = true;
};

/// An instant of SUMO's run: its simulated time since it started.
using SumoTime = SumoClock::time_point;

/// SUMO's time in seconds (its API's `simulation.getTime`) as a SumoTime, to the nanosecond.
/// @throws InputError for a value that is not finite (as `FromSeconds`).
[[nodiscard]] inline SumoTime SumoTimeFromSeconds(double seconds) {
  return SumoTime(FromSeconds(seconds));
}

using autodrive::ToSeconds;  // for Duration, beside SumoTime's
/// Seconds since SUMO's start, for logs and SUMO's API.
[[nodiscard]] inline double ToSeconds(SumoTime t) {
  return autodrive::ToSeconds(t.time_since_epoch());
}

}  // namespace autodrive::traffic
