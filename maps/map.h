#pragma once
/// @file
/// A built map: everything the rest of the system needs from a layout (see docs/maps.md).
///
/// Map frame M: origin at the south-west corner of the layout's grid, x east (along columns),
/// y north (up the rows), z up; metres. Traffic drives on the right. Tile (row r, column c),
/// with row 0 the northmost as written in the layout, covers
/// [c T, (c+1) T] x [(rows-1-r) T, (rows-r) T] for tile size T.

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/geometry.h"
#include "common/ids.h"
#include "maps/layout.h"

namespace autodrive::maps {

/// A polyline in the map frame (m), ordered along the direction of travel where it has one.
using Polyline = std::vector<Eigen::Vector2d>;

/// A side of a tile, counter-clockwise from east. Rotating a module by k*90 degrees
/// counter-clockwise moves side s to side (s + k) % 4.
enum class Side { kEast = 0, kNorth = 1, kWest = 2, kSouth = 3 };
/// "E", "N", "W", "S".
[[nodiscard]] char SideLetter(Side side);
/// Side `s` after `quarter_turns` counter-clockwise quarter turns.
[[nodiscard]] inline Side Rotate(Side s, int quarter_turns) {
  return static_cast<Side>(((static_cast<int>(s) + quarter_turns) % 4 + 4) % 4);
}
/// The side across the tile.
[[nodiscard]] inline Side Opposite(Side s) { return Rotate(s, 2); }
/// The unit vector out of a tile through side `s`, map frame.
[[nodiscard]] inline Eigen::Vector2d Outward(Side s) {
  constexpr double kX[] = {1, 0, -1, 0};
  constexpr double kY[] = {0, 1, 0, -1};
  return {kX[static_cast<int>(s)], kY[static_cast<int>(s)]};
}
/// `d` turned a quarter clockwise (to its right) and counter-clockwise (to its left).
[[nodiscard]] inline Eigen::Vector2d RightOf(const Eigen::Vector2d& d) { return {d.y(), -d.x()}; }
[[nodiscard]] inline Eigen::Vector2d LeftOf(const Eigen::Vector2d& d) { return {-d.y(), d.x()}; }

/// Where a tile is in the grid.
struct TileIndex {
  int row = 0;
  int col = 0;
  bool operator==(const TileIndex&) const = default;
  /// "r2c3".
  [[nodiscard]] std::string Name() const;
};

/// The manoeuvre of a movement through an intersection.
enum class Turn { kStraight, kLeft, kRight, kUTurn };
[[nodiscard]] std::string_view ToString(Turn turn);

/// A stop line across the end of an ingress lane: `left` and `right` ends as seen in the
/// direction of travel.
struct StopLine {
  Eigen::Vector2d left = Eigen::Vector2d::Zero();
  Eigen::Vector2d right = Eigen::Vector2d::Zero();
};

/// One lane of one tile. Lanes chain across tile edges (`successors`) and through
/// intersections by movements.
struct Lane {
  LaneId id{0};
  std::string name;  ///< "r2c3:W>E:0": tile, from side > to side, index from the centreline
  TileIndex tile;
  Side from_side = Side::kEast;  ///< the tile edge it enters through
  Side to_side = Side::kEast;    ///< the tile edge it leaves through (== from_side for a loop)
  Polyline centreline;           ///< in the direction of travel
  Polyline left_boundary;        ///< same length as the centreline
  Polyline right_boundary;
  double width_m = 0.0;
  int index_from_centre = 0;       ///< 0 next to the road's centreline, growing to the kerb
  std::vector<LaneId> successors;  ///< lanes that start where this one ends (not via movements)
  std::vector<LaneId> predecessors;
  std::vector<MovementId> movements_out;  ///< movements that start at this lane's end
  std::vector<MovementId> movements_in;   ///< movements that end at this lane's start
  std::optional<StopLine> stop_line;      ///< at the end, when it enters a controlled intersection
  /// The intersection its end enters, and by which of its approaches (both set or neither).
  std::optional<IntersectionId> ingress_of;
  std::optional<ApproachId> ingress_approach;
  /// The intersection its start leaves, and by which of its approaches (both set or neither).
  /// A lane between two intersections has both pairs, each naming its own intersection's
  /// approach (west of one, east of the next).
  std::optional<IntersectionId> egress_of;
  std::optional<ApproachId> egress_approach;
  double length_m = 0.0;
};

/// A path through an intersection from the end of an ingress lane to the start of an egress
/// lane.
struct Movement {
  MovementId id{0};
  std::string name;  ///< "r2c3:S>W:0>0"
  IntersectionId intersection{0};
  LaneId from{0};
  LaneId to{0};
  ApproachId from_approach{0};
  ApproachId to_approach{0};
  Turn turn = Turn::kStraight;
  Polyline path;  ///< starts at `from`'s last point, ends at `to`'s first point
  double length_m = 0.0;
};

/// An arm of an intersection.
struct Approach {
  ApproachId id{0};  ///< 1 east, 2 north, 3 west, 4 south (the side it comes from)
  Side side = Side::kEast;
  std::vector<LaneId> ingress;  ///< lanes driving into the intersection, from the centreline out
  std::vector<LaneId> egress;   ///< lanes driving away from it
  double ingress_heading_rad = 0.0;  ///< direction of travel of the ingress lanes
};

/// A traffic light head: a physical or simulated `signal_<i>` device at a corner.
struct SignalHead {
  SignalHeadId id{0};
  IntersectionId intersection{0};
  ApproachId approach{0};  ///< the approach whose traffic it faces
  RigidTransform2 X_MH;    ///< position; +x of H points towards the approaching traffic
  std::array<double, 3> lamp_heights_m{0.19, 0.175, 0.16};  ///< red, yellow, green (AutoDRIVE)
};

/// An intersection (4-way or T) occupying one tile, which is its conflict box.
struct Intersection {
  IntersectionId id{0};
  std::string name;  ///< the cell's name= option, else "x_r2c3"
  TileIndex tile;
  Control control = Control::kSignal;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  std::vector<Approach> approaches;
  std::vector<MovementId> movements;
  /// Pairs (a, b) with a < b of movements that conflict: their paths cross, merge into one
  /// egress lane, or pass closer than the vehicle clearance. Movements from the same ingress
  /// lane (diverging) never conflict. Symmetric: stored once.
  std::vector<std::pair<MovementId, MovementId>> conflicts;
  std::vector<SignalHeadId> signal_heads;
};

/// A traffic sign.
struct Sign {
  SignId id{0};
  std::string type;      ///< as in SignSpec
  RigidTransform2 X_MS;  ///< +x of S is the direction its face looks
  double value = 0.0;
  std::optional<LaneId> lane;  ///< the lane it governs, when it governs one
};

/// A static obstacle: its footprint and height.
struct Obstacle {
  std::string kind;    ///< "box" or "wall"
  Polyline footprint;  ///< counter-clockwise polygon, map frame
  double height_m = 0.0;
};

/// A polygon with holes (counter-clockwise outer boundary, clockwise holes), map frame.
struct Region {
  Polyline outer;
  std::vector<Polyline> holes;
};

/// A parking bay: a rectangle in a parking tile.
struct ParkingBay {
  std::string name;  ///< "r0c2:bay1"
  Polyline footprint;
};

/// Elevation of the ground: heights at the tile grid's corners (rows+1) x (cols+1) and per-tile
/// ramps. See `TerrainHeight`.
struct Terrain {
  int rows = 0;
  int cols = 0;
  std::vector<double> tile_elevation_m;  ///< row-major, rows x cols
  std::vector<double> tile_rise_m;       ///< per tile; a ramp rises along its local +x
  std::vector<int> tile_rotation_deg;
};

/// Parameters of the build that are not part of a layout.
struct BuildOptions {
  /// Spacing of points along lane centrelines and movement paths (m).
  double sample_step_m = 0.02;
  /// Smallest turning radius of any lane or path the builder makes (m). Nigel's is 0.245 m
  /// (wheelbase / tan 30 deg); dead ends and parking loops use this radius.
  double min_turn_radius_m = 0.3;
  /// Two movements whose paths come closer than this conflict (m): Nigel's width 0.175 m plus
  /// a margin.
  double vehicle_clearance_m = 0.2;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("sample_step_m", sample_step_m, config::Range{0.001, 0.5});
    a.Optional("min_turn_radius_m", min_turn_radius_m, config::Range{0.05, 10.0});
    a.Optional("vehicle_clearance_m", vehicle_clearance_m, config::Range{0.0, 5.0});
  }
  bool operator==(const BuildOptions&) const = default;
};

/// The whole built map. Value type; ids of lanes, movements and intersections index their
/// vectors (`lanes[id.value() - 1]`); signal head ids are the layout's (`signal_head(id)`).
struct Map {
  Layout layout;         ///< what it was built from
  BuildOptions options;  ///< how
  std::string name;
  double tile_size_m = 1.0;
  double lane_width_m = 0.3;
  int rows = 0;
  int cols = 0;
  std::vector<std::vector<Cell>> cells;
  std::vector<Lane> lanes;
  std::vector<Movement> movements;
  std::vector<Intersection> intersections;
  std::vector<SignalHead> signal_heads;
  std::vector<Sign> signs;
  std::vector<Obstacle> obstacles;
  std::vector<ParkingBay> parking_bays;
  /// Union of lanes, movements, open floors and parking areas, per tile: regions of
  /// neighbouring tiles meet along tile edges and never overlap.
  std::vector<Region> road_surface;
  std::vector<Region> drivable;  ///< road surface minus obstacles, per tile likewise
  Terrain terrain;

  const Lane& lane(LaneId id) const { return lanes.at(id.value() - 1); }
  const Movement& movement(MovementId id) const { return movements.at(id.value() - 1); }
  const Intersection& intersection(IntersectionId id) const {
    return intersections.at(id.value() - 1);
  }
  /// The lane named `name` ("r2c3:W>E:0", as `autodrive-map info` lists them), or null.
  [[nodiscard]] const Lane* FindLane(std::string_view lane_name) const {
    for (const Lane& l : lanes) {
      if (l.name == lane_name) return &l;
    }
    return nullptr;
  }
  /// The head with id `id`. Head ids are the layout's (docs/maps.md), not positions:
  /// `signal_heads` is in ascending id order and may have gaps. @throws std::out_of_range for
  /// an id the map has not.
  [[nodiscard]] const SignalHead& signal_head(SignalHeadId id) const;
  /// Whether the map has a head with id `id`.
  [[nodiscard]] bool HasSignalHead(SignalHeadId id) const;
  /// "signal_5 (centre, W approach)": the head's name, its intersection and the side of the
  /// approach it faces; "signal_5 (not in map NAME)" for an id the map has not.
  [[nodiscard]] std::string DescribeSignalHead(SignalHeadId id) const;
  /// The centre of tile `t` in the map frame.
  [[nodiscard]] Eigen::Vector2d TileCentre(const TileIndex& t) const {
    return {(t.col + 0.5) * tile_size_m, (rows - 1 - t.row + 0.5) * tile_size_m};
  }
  /// The map's extent: [0, cols T] x [0, rows T].
  [[nodiscard]] Eigen::Vector2d size_m() const { return {cols * tile_size_m, rows * tile_size_m}; }
  /// True when the two movements of one intersection conflict.
  [[nodiscard]] bool Conflict(MovementId a, MovementId b) const;
};

}  // namespace autodrive::maps
