#include "examples/v2i/glosa.h"

#include <algorithm>

namespace autodrive::examples {

using State = vehicle_sim::SignalIndication::State;

std::optional<double> GreenStartsIn(const vehicle_sim::SignalIndication& shown) {
  switch (shown.state) {
    case State::kRed:
      // A red group's next state is its green: next_time says when, else the red's own end.
      if (shown.next_green_s) return shown.next_green_s;
      if (shown.likely_end_s) return shown.likely_end_s;
      return shown.min_end_s;
    case State::kYellow:
      return shown.next_green_s;  // after the yellow comes red: only next_time knows
    default:
      return std::nullopt;
  }
}

std::optional<double> GlosaSpeed(const GlosaParams& params, double to_line_m,
                                 const vehicle_sim::SignalIndication& shown) {
  if (to_line_m <= 0.0 || to_line_m > params.horizon_m || params.cruise_mps <= 0.0) {
    return std::nullopt;
  }
  std::optional<double> green_in;
  if (shown.state == State::kGreen) {
    // Through at cruise before the green ends? Then no advice; else aim for the next green.
    const std::optional<double> ends = shown.likely_end_s ? shown.likely_end_s : shown.min_end_s;
    const double through_s = (to_line_m + params.body_length_m) / params.cruise_mps;
    if (!ends || through_s <= *ends) return std::nullopt;
    green_in = shown.next_green_s;
  } else {
    green_in = GreenStartsIn(shown);
  }
  if (!green_in) return std::nullopt;
  const double arrive_at = *green_in + params.margin_s;
  if (to_line_m / params.cruise_mps >= arrive_at) return std::nullopt;  // on green anyway
  return std::max(to_line_m / arrive_at, params.min_speed_mps);
}

}  // namespace autodrive::examples
