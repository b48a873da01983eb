#pragma once
/// @file
/// The V2I MAP message (`/autodrive/scm/map`, SAE J2735 MapData semantics) and the signs
/// registry (`/autodrive/scm/signs`), derived from a built map (see DESIGN.md, "V2I semantics").
///
/// MAP describes every intersection of the map:
/// - `control`: SIGNALISED, STOP_CONTROLLED, YIELD_CONTROLLED or UNCONTROLLED;
///   `ref_point`: the centre of the intersection box, at terrain height.
/// - approaches: the map's ids (1 east, 2 north, 3 west, 4 south: the side traffic comes
///   from), named "east", "north", "west", "south", with the heading of ingress travel.
/// - lanes, numbered 1, 2, ... within the intersection: for each approach in map order its
///   ingress lanes then its egress lanes, each from the road's centreline out to the kerb.
///   `map_lane_id` is the map's lane name ("r2c1:W>E:0"). An ingress lane's centreline ends
///   at its stop line (where the lane meets the box); controlled intersections give it a stop
///   line. Each ingress lane lists its connections: the map's movement id, the egress lane it
///   leads to, the manoeuvre, the signal group (0 when none), and the path through the box.
/// - signal groups as assigned (`SignalGroupAssignment`), with their movements and the names of
///   the heads that show them ("signal_<i>").
///
/// Polylines (centrelines and paths) are resampled at equal steps of `kMapPointSpacingM` along
/// the line, both ends kept exactly (see `Decimate`); the builder's 2 cm samples would make
/// MAP 2.5 times larger with no use to a vehicle. On Nigel's tightest lane (radius 0.35 m) a
/// 5 cm chord deviates from the arc by under 1 mm. Heights (z) are the terrain's height at each
/// point.
///
/// The header's stamp is left at zero (the publisher stamps the message); frame_id is "map".

#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/dds/messages.h"
#include "common/ids.h"
#include "maps/map.h"

namespace autodrive::scm {

/// The MAP message as published.
using MapDataMessage = dds::Message<msg::MapData>;
/// The signs registry as published.
using SignRegistryMessage = dds::Message<msg::SignRegistry>;

/// Largest spacing (m, along the line) of the points of MAP centrelines and paths.
inline constexpr double kMapPointSpacingM = 0.05;

/// One signal group as MAP describes it.
struct SignalGroupInfo {
  SignalGroupId id{0};
  std::string name;                   ///< e.g. "north_approach"
  std::vector<MovementId> movements;  ///< map movements it controls
  std::vector<SignalHeadId> heads;    ///< the lights that show it
};

/// The groups of each signalised intersection (others: no groups, signal_group 0).
using SignalGroupAssignment = std::map<IntersectionId, std::vector<SignalGroupInfo>>;

/// The MAP message of every intersection of `map` for city `city` (or, when `only` is not
/// empty, of those it lists: a district's), with the signal groups of `groups`, at `revision`
/// (the message's and every intersection's revision). A movement of a signalised intersection
/// that no group lists gets signal_group 0 (not signalised).
/// @throws InputError naming the offending id when `groups` does not fit the map: an
///   intersection that is not in the map or not signalised, a group id 0 or used twice in one
///   intersection, a movement or head that is not of that intersection, a movement in two
///   groups.
[[nodiscard]] MapDataMessage BuildMapData(const maps::Map& map, std::string_view city,
                                          const SignalGroupAssignment& groups,
                                          std::uint32_t revision,
                                          std::span<const IntersectionId> only = {});

/// The signs registry of every sign of `map` for city `city` at `revision`: id, type
/// (`TrafficSign_Constants`), value, pose (position at terrain height, facing along +x), the
/// name of the lane it governs (empty if none) and a human-readable label (e.g. "stop, west_t
/// east approach", "speed limit 0.25 m/s").
/// @throws InputError naming the sign and its type when the type is not one of stop, yield,
///   speed_limit, no_entry, parking, curve_left, curve_right, pedestrian_crossing, one_way.
[[nodiscard]] SignRegistryMessage BuildSignRegistry(const maps::Map& map, std::string_view city,
                                                    std::uint32_t revision);

/// The `TrafficSign_Constants` value of a map sign type ("stop" is STOP, ...).
/// @throws InputError naming the type when it is not a known one.
[[nodiscard]] std::uint8_t SignTypeToWire(std::string_view type);

/// "east", "north", "west" or "south": the name MAP gives an approach from `side`.
[[nodiscard]] std::string_view ApproachName(maps::Side side);

/// `line` resampled for MAP: its first point, then points every `spacing_m` of arc length
/// along it (interpolated on its segments), then its last point; when the last step would be
/// shorter than `spacing_m / 2` the point before the end is dropped, so every step is between
/// `spacing_m / 2` and `1.5 * spacing_m` (unless the whole line is shorter). A line of fewer
/// than two points is returned as it is.
/// @throws InputError when `spacing_m` is not positive and finite.
[[nodiscard]] maps::Polyline Decimate(const maps::Polyline& line,
                                      double spacing_m = kMapPointSpacingM);

}  // namespace autodrive::scm
