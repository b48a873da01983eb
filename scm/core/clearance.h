#pragma once
/// @file
/// The twin's clearance measurement (docs/scm.md, "Clearances"): does a car that enters the box
/// on the last instant of its yellow get out before a car of a conflicting movement, starting on
/// its green, reaches it? The intergreens are what the SCM's own controller shows for a plan;
/// the cars drive the map's lanes and movement paths with their footprints. Pure: no I/O.

#include <string>
#include <vector>

#include "common/time.h"
#include "maps/map.h"
#include "scm/core/city.h"

namespace autodrive::scm {

/// The two cars of a measurement (lab units).
struct ClearanceCars {
  double length_m = 0.318;  ///< footprint (a Nigel's body)
  double width_m = 0.175;
  double entering_speed_mps = 0.26;  ///< the car entering on the last instant of yellow
  double starting_speed_mps = 0.26;  ///< the cross car, crossing its stop line as green starts
};

/// One pair of conflicting movements under one intergreen.
struct ClearanceCase {
  std::string ending_group;       ///< "1 (east)": its yellow ends
  std::string starting_group;     ///< its green starts `intergreen` later
  std::string ending_movement;    ///< the entering car's path
  std::string starting_movement;  ///< the cross car's path
  Duration intergreen{0};     ///< end of yellow to the conflicting green, as the controller runs
  double min_gap_m = 0.0;     ///< the footprints' closest approach (0 when they meet)
  bool meet = false;          ///< the footprints overlap at some instant
  double meet_after_s = 0.0;  ///< when they first overlap, from the green's start
};

/// The intergreen between each group's end of yellow and each conflicting group's next green,
/// as `x`'s controller runs its plan `plan` (a fixed or actuated plan index) with every detector
/// called: `[a][b]`, or nothing where a and b do not conflict or b never follows a.
[[nodiscard]] std::vector<std::vector<std::optional<Duration>>> MeasuredIntergreens(
    const IntersectionModel& x, std::size_t plan);

/// For every pair of conflicting movements (one of each of two conflicting groups), drives the
/// entering car through its movement from its stop line at the last instant of yellow and the
/// cross car from its stop line at its green, both at constant speed, and reports how close
/// their footprints come. `intergreens` is `MeasuredIntergreens`'.
[[nodiscard]] std::vector<ClearanceCase> MeasureClearances(
    const maps::Map& map, const IntersectionModel& x,
    const std::vector<std::vector<std::optional<Duration>>>& intergreens,
    const ClearanceCars& cars);

}  // namespace autodrive::scm
