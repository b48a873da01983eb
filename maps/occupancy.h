#pragma once
/// @file
/// Occupancy grids of a built map, in the format of ROS's `map_server` (a PGM image and a YAML
/// file), for LIDAR localisation and path planners.

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "maps/map.h"

namespace autodrive::maps {

/// A 2D occupancy grid over the map frame M, laid out like ROS's `nav_msgs/OccupancyGrid`:
/// `cells` is row-major with row 0 at the SOUTH edge (lowest y) and column 0 at the west edge;
/// cell (col, row) covers `origin_m + [col, col + 1) x [row, row + 1) * resolution_m`. Values
/// are `kFree` (0) or `kOccupied` (100), as in `nav_msgs/OccupancyGrid`. (The PGM written by
/// `WriteOccupancyGrid` is flipped, its first row being the north edge, as `map_server`
/// expects.) A plain value type: copyable and movable.
struct OccupancyGrid {
  /// A cell nothing stands on and that may be driven on.
  static constexpr std::uint8_t kFree = 0;
  /// A cell an obstacle touches or (for road-only grids) whose centre is off the road.
  static constexpr std::uint8_t kOccupied = 100;

  double resolution_m = 0.05;  ///< edge of one square cell (m)
  /// The south-west corner of cell (0, 0) in the map frame (m): the map frame's origin.
  Eigen::Vector2d origin_m = Eigen::Vector2d::Zero();
  int width = 0;                    ///< number of columns (along +x)
  int height = 0;                   ///< number of rows (along +y)
  std::vector<std::uint8_t> cells;  ///< width * height values, row-major from the south row

  /// The value of cell (col, row). Precondition (checked, aborts): inside the grid.
  [[nodiscard]] std::uint8_t at(int col, int row) const;
  /// True when cell (col, row) is `kFree`. Precondition (checked, aborts): inside the grid.
  [[nodiscard]] bool IsFree(int col, int row) const { return at(col, row) == kFree; }
  /// The centre of cell (col, row) in the map frame (m). Any col, row (no bounds check).
  [[nodiscard]] Eigen::Vector2d CellCentre(int col, int row) const;
  /// The number of free cells.
  [[nodiscard]] std::size_t FreeCount() const;
  bool operator==(const OccupancyGrid&) const = default;
};

/// Rasterises the map into an occupancy grid covering the whole map,
/// [0, cols T] x [0, rows T] (the last row and column are partial when the map's size is not a
/// multiple of `resolution_m`), with its origin at the map frame's origin.
///
/// Obstacles (the layout's boxes and walls, and the boundary walls) are rasterised
/// conservatively: a cell is occupied when the obstacle's footprint (a closed polygon) touches
/// the cell's square anywhere, however little: a wall thinner than a cell that runs between
/// cell centres, a box smaller than a cell, a corner that just clips a cell. The test is exact
/// (each footprint edge is clipped to each row; a cell no edge touches is inside exactly when
/// its centre is), except that the cell's square is first shrunk by 10^-6 of a cell on each
/// side, so that a footprint that only meets a cell's edge (a 0.3 m box on a 0.05 m grid),
/// or overlaps it by a rounding error, leaves that cell free. Cells that no obstacle touches
/// are never occupied by one (no dilation beyond the touched cells).
///
/// With `road_only` (the default), a cell is also occupied when its centre lies outside the
/// map's `drivable` regions (road surface minus obstacles), so everything off the road is
/// occupied. That side keeps the centre rule on purpose: a cell that the edge of the road
/// crosses is free when its centre is on the road. The road's edge is a rule of the road
/// (paint, the edge of a tile), not something a car or a LIDAR collides with, and the centre
/// rule keeps the free area equal to the drivable area on average, where a conservative edge
/// would narrow every 0.3 m lane by up to a cell on each side. Planners that must keep the
/// whole car on the road inflate by their own margin. Without `road_only`, only the obstacles
/// are occupied and the ground around the roads is free, as a LIDAR sees it. Signs and signal
/// heads have no footprint in the map and are not obstacles: they are occupied only as ground
/// off the road in a road-only grid.
///
/// A scanline fill plus a walk along each obstacle's edges: time proportional to the number of
/// cells, plus the number of polygon edges times the rows they span, plus the cells that the
/// obstacles' outlines cross (a 64x64-tile map at 0.05 m takes well under a second).
/// @param resolution_m cell edge (m): finite and > 0, giving at most 100 million cells.
/// @throws InputError naming the resolution if it is not finite, not positive, or too fine.
[[nodiscard]] OccupancyGrid MakeOccupancyGrid(const Map& map, double resolution_m = 0.05,
                                              bool road_only = true);

/// Writes the grid for ROS's `map_server`: an 8-bit binary PGM (P5) at `pgm_path`, its first
/// row the grid's NORTH row, 254 for free cells and 0 for occupied ones; and the YAML at
/// `yaml_path`: `image` (the PGM's path relative to the YAML's directory), `resolution`,
/// `origin: [x, y, 0.0]`, `negate: 0`, `occupied_thresh: 0.65`, `free_thresh: 0.196` and
/// `mode: trinary`.
/// Precondition (checked, aborts): `cells.size() == width * height`, positive sizes.
/// @throws InputError naming the path and the reason if a file cannot be written.
void WriteOccupancyGrid(const OccupancyGrid& grid, const std::string& pgm_path,
                        const std::string& yaml_path);

}  // namespace autodrive::maps
