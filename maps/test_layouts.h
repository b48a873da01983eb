#pragma once
/// @file
/// Layouts shared by the maps tests. Include only from tests.

#include <string>

#include "maps/layout.h"

namespace autodrive::maps::test_layouts {

/// A four-way intersection with one lane per direction whose arms leave the map, on a 3 x 3
/// grid: the intersection tile is r1c1, centred at (1.5, 1.5). `control`: signal|stop|yield|none.
inline Layout FourWay(const std::string& control = "signal") {
  return MakeLayout("four_way", {{"empty", "straight@90", "empty"},
                                 {"straight", "x4 control=" + control, "straight"},
                                 {"empty", "straight@90", "empty"}});
}

}  // namespace autodrive::maps::test_layouts
