#pragma once
/// @file
/// The map file (`map.yaml`), the machine format other components load maps from.
///
/// ```yaml
/// format: autodrive-map/1
/// options: {sample_step_m: 0.02, min_turn_radius_m: 0.3, vehicle_clearance_m: 0.2}
/// summary: {lanes: 48, intersections: 1, movements: 12, conflicts: 30, signal_heads: 4, ...}
/// layout: {name: ..., tile_size_m: ..., grid: [...], ...}    # the layout it was built from
/// ```
///
/// The layout is the source of truth and the builder is deterministic, so `LoadMap` rebuilds
/// the map and checks the result against the summary: a file written by a builder that made a
/// different map is refused instead of silently changing lane or movement ids.

#include <string>

#include "maps/map.h"

namespace autodrive::maps {

/// Counts that identify a built map, stored in map.yaml and checked on load.
struct MapSummary {
  int rows = 0;
  int cols = 0;
  int lanes = 0;
  int intersections = 0;
  int movements = 0;
  int conflicts = 0;
  int signal_heads = 0;
  int signs = 0;
  int obstacles = 0;
  double road_area_m2 = 0.0;
  double drivable_area_m2 = 0.0;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("rows", rows);
    a.Required("cols", cols);
    a.Required("lanes", lanes);
    a.Required("intersections", intersections);
    a.Required("movements", movements);
    a.Required("conflicts", conflicts);
    a.Required("signal_heads", signal_heads);
    a.Required("signs", signs);
    a.Required("obstacles", obstacles);
    a.Required("road_area_m2", road_area_m2);
    a.Required("drivable_area_m2", drivable_area_m2);
  }
  /// Equal counts and areas equal to 1e-9 relative.
  [[nodiscard]] bool Matches(const MapSummary& other) const;
  /// "lanes 48, intersections 1, ..." for messages.
  [[nodiscard]] std::string ToString() const;
};

/// The summary of a built map.
[[nodiscard]] MapSummary Summarise(const Map& map);
/// Area of regions with holes (m^2).
[[nodiscard]] double Area(const std::vector<Region>& regions);

/// Writes map.yaml for `map`. Throws `ConfigError` when the file cannot be written.
void SaveMap(const Map& map, const std::string& path);
/// Loads a map.yaml: reads it strictly, rebuilds the map from its layout and options, and
/// checks the summary. Throws `ConfigError` (bad file, with location), `InputError` (bad
/// layout, or a summary that does not match the rebuilt map).
[[nodiscard]] Map LoadMap(const std::string& path);
/// Loads a map from a map.yaml or directly from a layout file (any YAML with a `grid` key).
[[nodiscard]] Map LoadMapOrLayout(const std::string& path);

}  // namespace autodrive::maps
