#pragma once
/// @file
/// The layout of a lab's track: a grid of modules with rotations, plus freely placed obstacles
/// and signs. Loaded strictly from YAML (see docs/maps.md for the format).
///
/// ```yaml
/// name: driving_school
/// tile_size_m: 1.0          # edge of one square module
/// lane_width_m: 0.3
/// grid:                     # rows from north (top) to south; columns from west to east
///   - [curve@270, straight, curve@180]
///   - [straight@90, empty, straight@90]
///   - [curve, x4 control=signal, curve@90]
/// obstacles:
///   - {kind: box, x_m: 1.5, y_m: 1.5, length_m: 0.2, width_m: 0.2, height_m: 0.2}
/// ```

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/config.h"

namespace autodrive::maps {

/// The kinds of module a tile holds.
enum class ModuleType {
  kEmpty,         ///< ground, nothing to drive on (walls and boxes may stand on it)
  kStraight,      ///< road from the west edge to the east edge
  kCurve,         ///< 90-degree road from the south edge to the east edge
  kIntersection,  ///< 4-way intersection, roads on all four edges
  kTJunction,     ///< T-junction, roads on the west, east and south edges
  kRoadEnd,       ///< road from the west edge ending in a turning loop
  kParking,       ///< parking area entered from the south edge, bays along the north
  kRamp,          ///< straight road west to east rising by `rise_m` (terrain)
  kOpen,          ///< open drivable floor without lanes (the Parking School's area)
};

/// How an intersection is controlled.
enum class Control { kSignal, kStop, kYield, kUncontrolled };

/// One grid cell: `TYPE[@ROTATION] [key=value ...]`, e.g. `curve@90`, `x4 control=stop`,
/// `straight@90 lanes=2`, `ramp rise=0.1`, `empty` (or `.`). Rotation is counter-clockwise in
/// degrees, a multiple of 90. Keys: `lanes` (per direction, 1 or 2; default: the layout's), `width`
/// (lane width in m; default: the layout's), `control` (signal|stop|yield|none; intersections,
/// default signal), `rise` (ramps, m), `elevation` (m, default 0), `name` (intersections),
/// `heads` (signalised intersections: the ids of their signal heads, `heads=E4/N5/W6/S7` by
/// the side of the approach each faces, or `heads=4` for consecutive ids in the order E, N, W, S
/// of the approaches there are; without it the builder gives ids above every id given). Types:
/// empty (or .), straight, curve, x4, t, end, parking, ramp, open. Written in YAML as one string.
struct Cell {
  ModuleType type = ModuleType::kEmpty;
  int rotation_deg = 0;                ///< 0, 90, 180 or 270
  std::optional<int> lanes;            ///< lanes per direction; unset: the layout's default
  std::optional<double> lane_width_m;  ///< lane width (m); unset: the layout's default
  Control control = Control::kSignal;
  double rise_m = 0.0;
  double elevation_m = 0.0;
  std::string name;
  std::optional<std::uint32_t> first_head;     ///< heads=FIRST
  std::map<char, std::uint32_t> head_by_side;  ///< heads=E4/N5/...: by the side 'E', 'N', 'W', 'S'

  /// Parses the cell text. Throws `InputError` naming what is wrong and the text seen.
  static Cell FromConfigString(std::string_view text);
  /// The cell as text, parsed back by `FromConfigString` to an equal cell.
  [[nodiscard]] std::string ToConfigString() const;
  bool operator==(const Cell&) const = default;
};

/// A freely placed static obstacle: a box (e.g. a construction box) or a wall segment.
struct ObstacleSpec {
  std::string kind = "box";  ///< "box" or "wall"
  double x_m = 0.0;          ///< centre, map frame
  double y_m = 0.0;
  double yaw_rad = 0.0;  ///< direction of the length axis
  double length_m = 0.2;
  double width_m = 0.2;
  double height_m = 0.2;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("kind", kind, config::OneOf{{"box", "wall"}});
    a.Required("x_m", x_m);
    a.Required("y_m", y_m);
    a.Optional("yaw_rad", yaw_rad, config::Range{-7.0, 7.0});
    a.Optional("length_m", length_m, config::Range{0.01, 100.0});
    a.Optional("width_m", width_m, config::Range{0.005, 100.0});
    a.Optional("height_m", height_m, config::Range{0.0, 10.0});
  }
  bool operator==(const ObstacleSpec&) const = default;
};

/// A freely placed sign. Signs that controlled intersections need (stop, yield) are added by
/// the builder; these are the others (speed limits, curve warnings, parking, ...).
struct SignSpec {
  std::string type;  ///< stop|yield|speed_limit|no_entry|parking|curve_left|curve_right|...
  double x_m = 0.0;  ///< map frame
  double y_m = 0.0;
  double yaw_rad = 0.0;  ///< the direction the sign's face looks (towards the traffic it governs)
  double value = 0.0;    ///< e.g. the speed limit in m/s
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("type", type,
               config::OneOf{{"stop", "yield", "speed_limit", "no_entry", "parking", "curve_left",
                              "curve_right", "pedestrian_crossing", "one_way"}});
    a.Required("x_m", x_m);
    a.Required("y_m", y_m);
    a.Optional("yaw_rad", yaw_rad, config::Range{-7.0, 7.0});
    a.Optional("value", value);
  }
  bool operator==(const SignSpec&) const = default;
};

/// A whole layout, as read from YAML.
struct Layout {
  std::string name;
  double tile_size_m = 1.0;
  double lane_width_m = 0.3;
  int lanes_per_direction = 1;
  bool boundary_walls = false;  ///< walls around the whole grid
  double wall_thickness_m = 0.02;
  double wall_height_m = 0.2;
  std::vector<std::vector<Cell>> grid;  ///< rows, north first
  std::vector<ObstacleSpec> obstacles;
  std::vector<SignSpec> signs;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Optional("tile_size_m", tile_size_m, config::Range{0.3, 10.0});
    a.Optional("lane_width_m", lane_width_m, config::Range{0.1, 2.0});
    a.Optional("lanes_per_direction", lanes_per_direction, config::Range{1, 2});
    a.Optional("boundary_walls", boundary_walls);
    a.Optional("wall_thickness_m", wall_thickness_m, config::Range{0.001, 1.0});
    a.Optional("wall_height_m", wall_height_m, config::Range{0.01, 5.0});
    a.Required("grid", grid);
    a.Optional("obstacles", obstacles);
    a.Optional("signs", signs);
  }
  /// Checks the rules that need more than one key (a rectangular grid, roads that fit the
  /// tile). Throws `InputError`.
  void Validate() const;
  bool operator==(const Layout&) const = default;
};

/// A layout named `name` from rows of cell texts (north row first), with default parameters,
/// for layouts made in code. Throws `InputError` for a bad cell.
[[nodiscard]] Layout MakeLayout(const std::string& name,
                                const std::vector<std::vector<std::string>>& rows);

/// Loads a layout file. Throws `ConfigError` with file, line and key on bad input.
Layout LoadLayout(const std::string& path);

/// "empty", "straight", ... as written in cells.
[[nodiscard]] std::string_view ToString(ModuleType type);
[[nodiscard]] std::string_view ToString(Control control);

}  // namespace autodrive::maps
