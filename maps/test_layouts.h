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

/// Two signalised four-ways one road tile apart, one lane per direction, their other arms
/// leaving the map, on a 3 x 5 grid: intersections r1c1 (centre (1.5, 1.5)) and r1c3
/// (centre (3.5, 1.5)). The lanes of r1c2 leave one intersection and enter the other.
inline Layout TwoFourWays() {
  return MakeLayout("two_four_ways", {{"empty", "straight@90", "empty", "straight@90", "empty"},
                                      {"straight", "x4", "straight", "x4", "straight"},
                                      {"empty", "straight@90", "empty", "straight@90", "empty"}});
}

}  // namespace autodrive::maps::test_layouts
