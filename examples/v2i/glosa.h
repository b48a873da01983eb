#pragma once
/// @file
/// Green-light optimal speed advisory (GLOSA): from SPaT's times, the speed at which a car
/// reaches its stop line as its movement turns green, instead of stopping at a red there.
/// The rule (as in SUMO's `glosa` device and the C-ITS GLOSA use case): within `horizon_m` of
/// the line, when the signal shows red (or yellow) and the green is expected later than the
/// car would arrive at its cruising speed, drive at the distance over the time to that green
/// (plus a margin), never slower than `min_speed_mps`; when it shows green but will end before
/// the car's tail is through, aim for the next green the same way. Otherwise, no advice.

#include <optional>

#include "vehicle_sim/lane_driver.h"

namespace autodrive::examples {

struct GlosaParams {
  double horizon_m = 3.0;        ///< advice from this far before the stop line (front bumper)
  double cruise_mps = 0.156;     ///< the car's speed without advice
  double min_speed_mps = 0.05;   ///< the slowest speed advised
  double margin_s = 1.0;         ///< arrive this long after the expected start of green
  double body_length_m = 0.318;  ///< for "through before the green ends"
};

/// When the movement's green is expected to start, in seconds from now; nothing when SPaT
/// does not say (no next_time, likely or min end where they would tell it) or it is green.
[[nodiscard]] std::optional<double> GreenStartsIn(const vehicle_sim::SignalIndication& shown);

/// The advised speed (m/s) for a car whose front bumper is `to_line_m` before the stop line of
/// a movement showing `shown`; nothing when there is no advice (drive as usual).
[[nodiscard]] std::optional<double> GlosaSpeed(const GlosaParams& params, double to_line_m,
                                               const vehicle_sim::SignalIndication& shown);

}  // namespace autodrive::examples
