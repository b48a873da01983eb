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
  /// Advice from this far before the stop line (front bumper): 8 m is 112 m at full scale,
  /// about the range of SUMO's glosa device (100 m by default).
  double horizon_m = 8.0;
  double cruise_mps = 0.156;  ///< the car's speed without advice
  /// The slowest speed advised: slower, the paper's command noise (σ 0.013 m/s) stops the car
  /// now and then, and a stop is what GLOSA is for avoiding.
  double min_speed_mps = 0.06;
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
