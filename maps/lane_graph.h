#pragma once
/// @file
/// The lane graph of a built map: which lanes follow which, directly across tile edges or
/// through an intersection by a movement.

#include <string>
#include <vector>

#include "maps/map.h"

namespace autodrive::maps {

/// The lanes a vehicle on `lane` can drive into next: its successors across the tile edge and
/// the egress lanes of the movements that start at its end.
[[nodiscard]] std::vector<LaneId> NextLanes(const Map& map, LaneId lane);

/// True when the lane ends on the map's boundary with nothing after it (traffic leaves the map).
[[nodiscard]] bool LeavesMap(const Map& map, const Lane& lane);
/// True when the lane starts on the map's boundary with nothing before it (traffic enters).
[[nodiscard]] bool EntersMap(const Map& map, const Lane& lane);

/// Checks that every lane can reach a lane that leaves the map or a loop, and can be reached
/// from a lane that enters the map or from a loop. Returns one line per lane that cannot
/// ("r0c1:W>E:0 cannot reach the map boundary or a loop"); empty when all can.
[[nodiscard]] std::vector<std::string> CheckReachability(const Map& map);

/// A shortest route (by length) from the start of `from` to the end of `to`, as the lanes
/// driven, or empty when there is none.
[[nodiscard]] std::vector<LaneId> Route(const Map& map, LaneId from, LaneId to);

}  // namespace autodrive::maps
