#pragma once
/// @file
/// Generated layouts for scale tests.

#include "maps/layout.h"

namespace autodrive::maps {

/// A grid city of `rows` x `cols` four-way intersections, one straight tile between
/// neighbours and arms leaving the map at the edges: (2 rows + 1) x (2 cols + 1) tiles.
/// `control`: "signal", "stop", or "mixed" (signalised and stop-controlled in a checkerboard).
/// Throws `InputError` for rows or cols outside [1, 200] or an unknown control.
[[nodiscard]] Layout GridCity(int rows, int cols, const std::string& control = "mixed");

}  // namespace autodrive::maps
