#pragma once
/// @file
/// What a head showed over time, from its lamp changes as `logs/lamps.csv` has them: steady
/// aspects, and flashing ones told from their alternation. The report draws them
/// (report_data.cpp); the metrics judge a flashing red by the stop-sign rule (metrics.cpp).

#include <utility>
#include <vector>

namespace autodrive::scenarios::internal {

/// A stretch of time over which a head showed one aspect: the `Aspect` wire numbers
/// (common/aspect.h): 0 off, 1 red, 2 yellow, 3 green, 4 flashing red, 5 flashing yellow.
struct LampBand {
  double from_s = 0;
  double to_s = 0;
  int aspect = 0;
  bool operator==(const LampBand&) const = default;
};

/// A head's bands from its lamp changes as `logs/lamps.csv` has them (time, state; in time
/// order; a state is what the lamps show at that instant, so a flashing aspect alternates its
/// colour and 0): three or more stretches in a row, each at most `flash_half_max_s` long,
/// alternating between off and one colour (red or yellow) are one flashing band. The last band
/// ends at `end_s`; nothing is drawn before the first change. Adjacent bands of one aspect are
/// merged.
[[nodiscard]] std::vector<LampBand> LampBands(const std::vector<std::pair<double, int>>& changes,
                                              double end_s, double flash_half_max_s = 1.0);

/// The aspect of `bands` at `t` (0 before the first band).
[[nodiscard]] int AspectAt(const std::vector<LampBand>& bands, double t);

}  // namespace autodrive::scenarios::internal
