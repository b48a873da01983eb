#pragma once
/// @file
/// The intergreen matrix (docs/scm.md, "Intergreens"): for each pair of conflicting signal
/// groups, the least time from the end of the clearing group's green to the start of the
/// entering group's, computed the RiLSA way from the map's movement paths and their conflict
/// zones, t = t_cross + (s_clear + L) / v_clear - s_enter / v_enter, with the ITE change figure
/// (W + L) / V beside it as a second check. Pure: no I/O.

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "maps/map.h"
#include "scm/core/city.h"
#include "scm/core/city_config.h"

namespace autodrive::scm {

/// What the matrix is computed for.
struct IntergreenInputs {
  /// The vehicles that clear the box (`safety.clearing_vehicles`): each pair's figure is the
  /// worst of them (the slowest and longest).
  std::vector<ClearingVehicleConfig> clearing_vehicles;
  /// The speed of an entering vehicle crossing its stop line as its green starts (m/s): the
  /// fastest the city declares.
  double entering_speed_mps = 0.26;
  /// t_cross: after the clearing group's green ends, how long a vehicle may still cross its
  /// stop line (s).
  double crossing_time_s = 0.0;
};

/// One entry of the matrix: the pair of conflicting movements (one of each group) and the
/// clearing vehicle that need the longest intergreen, with the figures that give it.
struct IntergreenEntry {
  std::size_t clearing = 0;  ///< group index (its green ends)
  std::size_t entering = 0;  ///< group index (its green starts)
  MovementId clearing_movement{0};
  MovementId entering_movement{0};
  std::string vehicle;              ///< the clearing vehicle's name
  double vehicle_length_m = 0.0;    ///< L
  double clearing_speed_mps = 0.0;  ///< v_clear
  /// s_clear: the clearing movement's path from its stop line to the far edge of the conflict
  /// zone (where the paths are less than half a lane width apart).
  double clearing_path_m = 0.0;
  /// s_enter: the entering movement's path from its stop line to the near edge of the zone.
  double entering_path_m = 0.0;
  double clearing_time_s = 0.0;  ///< (s_clear + L) / v_clear
  double entering_time_s = 0.0;  ///< s_enter / v_enter
  double crossing_time_s = 0.0;  ///< t_cross
  /// t_cross + clearing - entering, at least 0, rounded up to 0.1 s.
  double intergreen_s = 0.0;
  /// (W + L) / V for the clearing movement (W its whole path through the box), rounded up to
  /// 0.1 s: the ITE red clearance of that movement and vehicle.
  double ite_s = 0.0;
};

/// The entry for clearing movement `clearing` and entering movement `entering` (group indices
/// left 0) with `vehicle` clearing. The conflict zone is where the paths are within half a lane
/// width, or, for paths that never come that close, the map's vehicle clearance; movements
/// whose paths come closer than neither get the ITE figure, with zero paths.
[[nodiscard]] IntergreenEntry MovementIntergreen(const maps::Map& map, MovementId clearing,
                                                 MovementId entering,
                                                 const ClearingVehicleConfig& vehicle,
                                                 const IntergreenInputs& inputs);

/// Where two movements' paths conflict, remembered by the paths' shape relative to each other
/// (a city's intersections are mostly alike: a grid of a thousand has a handful of shapes).
/// Give one to `ComputeIntergreens` calls over one map to skip the geometry it has seen.
/// Not thread-safe.
class IntergreenCache {
 public:
  IntergreenCache();
  ~IntergreenCache();
  IntergreenCache(const IntergreenCache&) = delete;
  IntergreenCache& operator=(const IntergreenCache&) = delete;

  struct Zones;
  /// The zones of `clearing` and `entering` on `map`, computed on the first call for their
  /// shape.
  [[nodiscard]] const Zones& Get(const maps::Map& map, const maps::Movement& clearing,
                                 const maps::Movement& entering);

 private:
  struct Table;
  std::unique_ptr<Table> table_;
};

/// `[clearing][entering]` for every pair of conflicting groups of `x` (nothing elsewhere): the
/// worst over the pairs of their movements that conflict on the map and the clearing vehicles.
/// Groups whose movements do not meet on the map (a conflict added by configuration) get the
/// ITE figure of the clearing group's movements, with no entering movement and zero paths.
[[nodiscard]] std::vector<std::vector<std::optional<IntergreenEntry>>> ComputeIntergreens(
    const maps::Map& map, const IntersectionModel& x, const IntergreenInputs& inputs,
    IntergreenCache* cache = nullptr);

}  // namespace autodrive::scm
