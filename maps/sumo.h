#pragma once
/// @file
/// Exports a built `Map` as a SUMO network: plain XML (nodes, edges, connections, traffic light
/// programs) turned into `<name>.net.xml` by SUMO's own `netconvert`, plus a vehicle type file
/// for the 1:14 cars. The SUMO ids map back to the map's (see `SumoExport`).
///
/// How the map becomes a network (all ids are valid SUMO ids: no ':', '>', spaces, ...):
/// - **Edges.** One SUMO edge per road piece of one tile in one direction, holding that
///   direction's lanes: id `<tile>_<from side>_<to side>`, e.g. `r2c3_W_E` for the lanes
///   `r2c3:W>E:k`. Its shape is the middle of its lanes (`spreadType="center"`), so a one-lane
///   edge has exactly the lane's centreline; lane width is the map's, speed
///   `SumoOptions::speed_mps`. A turning loop (road end, parking; one lane) leaves and enters
///   one junction, which SUMO does not allow (it drops self-looped edges), so it is two edges
///   split at half its length by a plain junction `n_<tile>_loop`: `r0c2_W_W_a`, `r0c2_W_W_b`.
/// - **Lanes.** SUMO counts lanes from the kerb (index 0 is the rightmost), the map from the
///   centreline: map lane `k` of an edge with `n` lanes is SUMO lane `n - 1 - k`, id
///   `<edge>_<n-1-k>`. SUMO gives all lanes of one edge one length (their mean), so on a curve
///   with two lanes per direction each SUMO lane is as long as the middle of the road; on
///   straights and one-lane roads the lengths are the map's (a loop's: the sum of its halves).
/// - **Junctions.** Each intersection is one junction at its tile centre, id its `name`
///   (`x_r2c3` unless the layout names it), shaped by the mouths of its arms so that the edges
///   end on its tile edges as the lanes do. Type: `traffic_light` for signalised and for
///   stop-controlled (every approach has a stop sign; see "Traffic lights"),
///   `right_before_left` for yield and uncontrolled (every approach yields; SUMO has no
///   all-way yield, and `priority` would make one road the main road, which the map does not).
///   Every other tile edge a road crosses is a plain `priority` junction `n_<tile>_<side>`,
///   named by the tile to its west or north when that is on the map (`n_r1c0_E` between r1c0 and
///   r1c1), with a zero-area shape along the tile edge (netconvert makes the ones where a road
///   leaves the map `dead_end`).
/// - **Connections.** At an intersection exactly the map's movements, lane to lane, each with
///   the movement's path as its internal lane shape (so its length is the movement's). At
///   plain junctions the lanes' successors, with internal lanes of `kPlainConnectionLength_m`.
///   No turnarounds.
/// - **Traffic lights.** A signalised intersection's program (`tlLogic` with its junction's
///   id, programID "0") has link index `i` for its `i`-th movement (`Intersection::movements`
///   order) and serves one approach at a time: green, yellow, all red, in approach order. The
///   co-simulation (traffic) replaces it at run time with the lamps the lights show.
///   A stop-controlled intersection is a traffic light too, with short phases (`stop_green`,
///   `stop_yellow`, `stop_all_red`) that stand in for the all-way stop when SUMO runs alone; the
///   co-simulation runs it as an all-way stop (every vehicle stops, first come first served,
///   never two conflicting movements in the box). SUMO's own `allway_stop` is not used: a left
///   turn with a waiting point inside the junction rolls through it without stopping, and on
///   these small boxes (a 1 m tile) vehicles on crossing paths collide in it (11 junction
///   collisions in 10 minutes of 120 cars on a 4 x 4 grid of stop-controlled four-ways).
///
/// **Scale.** The network is the lab's map enlarged `SumoOptions::scale` times (14 by default: a
/// full-size city for the 1:14 lab), with speeds and accelerations enlarged alike and time
/// unchanged, so that SUMO's built-in constants, which assume full-size traffic, hold: a vehicle
/// under 0.1 m/s counts as halting (a Nigel crawling at 7 mm/s, not one at 38 % of its top
/// speed), shape points closer than 0.1 m are merged (7 mm of the lab), junction radii and
/// look-ahead distances are metres. Coordinates are the map frame's times the scale, without
/// netconvert's normalisation offset: a SUMO position divided by the scale is a map position.
/// `SumoExport::scale` says which scale a network has; `traffic` maps at this boundary.

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/ids.h"
#include "common/time.h"
#include "maps/map.h"

namespace autodrive::maps {

/// Length of the internal lanes netconvert builds at plain tile-edge junctions (m): SUMO needs
/// one, so it is kept as short as SUMO writes.
inline constexpr double kPlainConnectionLength_m = 0.001;

/// A SUMO vehicle type (`vType`) for the cars. Defaults: Nigel, the 1:14 AutoDRIVE car
/// (0.318 x 0.175 x 0.257 m, top speed 0.26 m/s), with accelerations chosen for it: it reaches
/// top speed in about half a second (accel 0.5 m/s^2) and brakes from it in a quarter of a
/// second (decel 1 m/s^2), and keeps 5 cm to the car ahead when stopped.
/// Sizes, speeds and accelerations are the lab's (m, m/s, m/s^2); the export multiplies them by
/// `SumoOptions::scale`.
struct SumoVehicleType {
  std::string id = "nigel";
  std::string vclass = "passenger";     ///< SUMO's `vClass` (passenger, bus, emergency, ...)
  std::string gui_shape = "passenger";  ///< how sumo-gui draws it
  double length_m = 0.318;
  double width_m = 0.175;
  double height_m = 0.257;
  double max_speed_mps = 0.26;
  double accel_mps2 = 0.5;
  double decel_mps2 = 1.0;
  double emergency_decel_mps2 = 2.0;  ///< at least `decel_mps2`
  double min_gap_m = 0.05;            ///< gap to the leader when standing
  double speed_factor = 1.0;          ///< multiplies lane speed limits (SUMO's `speedFactor`)
  double sigma = 0.5;                 ///< driver imperfection in [0, 1] (SUMO's default)
  std::string color = "1,1,0";        ///< sumo-gui's colour (r,g,b in [0, 1])

  /// Throws `InputError` naming the type, the field and the value when a value is out of range.
  void Validate() const;
};

/// The lab's bus: a 12 m bus at 1:14 (0.86 x 0.18 m), slower and gentler than a Nigel.
SumoVehicleType LabBus();
/// The lab's emergency vehicle: a Nigel in SUMO's `emergency` class.
SumoVehicleType LabEmergencyVehicle();

/// SUMO metres per lab metre of an exported network: the lab is 1:14.
inline constexpr double kSumoScale = 14.0;

/// One phase of a fixed-time program given for an intersection: its movements green for `green`,
/// then those not green in the next phase yellow for `yellow`, then all red for `all_red`.
struct SumoSignalPhase {
  std::vector<MovementId> movements;
  Duration green{0};
  Duration yellow{0};
  Duration all_red{0};
};

/// A fixed-time program for one signalised intersection (e.g. a city's plan), in place of the
/// export's default; `offset` as SUMO's tlLogic offset.
struct SumoSignalProgram {
  std::vector<SumoSignalPhase> phases;
  Duration offset{0};
};

/// Parameters of the export.
struct SumoOptions {
  /// Speed limit of every edge (m/s): a lab speed, not a road speed.
  double speed_mps = 0.25;
  /// The netconvert program: a path, or a name looked up in PATH.
  std::string netconvert = "netconvert";
  /// Arguments added at the end of the netconvert command line.
  std::vector<std::string> extra_netconvert_args;
  /// The static traffic light program: per approach, green, then yellow, then all red.
  Duration green = std::chrono::seconds(12);
  Duration yellow = std::chrono::seconds(3);
  Duration all_red = std::chrono::seconds(2);  ///< zero: no all-red phase
  /// Programs given for signalised intersections, in place of the one above.
  std::map<IntersectionId, SumoSignalProgram> programs;
  /// The stand-in program of a stop-controlled intersection (SUMO alone), per approach.
  Duration stop_green = std::chrono::seconds(4);
  Duration stop_yellow = std::chrono::seconds(2);
  Duration stop_all_red = std::chrono::seconds(3);
  /// SUMO metres per lab metre (see "Scale" above); 1 writes the lab's own sizes.
  double scale = kSumoScale;
  SumoVehicleType vehicle_type;  ///< the default type (Nigel)
  /// Further types written beside it (ids unique): by default the bus and the emergency vehicle.
  std::vector<SumoVehicleType> other_vehicle_types{LabBus(), LabEmergencyVehicle()};

  /// Throws `InputError` naming the field and the value when a value is out of range.
  void Validate() const;
};

/// A SUMO lane: an edge and an index counted from the kerb (0 is the rightmost).
struct SumoLaneRef {
  std::string edge;
  int index = 0;
  /// The SUMO lane id, `<edge>_<index>`.
  [[nodiscard]] std::string id() const { return edge + "_" + std::to_string(index); }
  bool operator==(const SumoLaneRef&) const = default;
};

/// Where a movement is in the SUMO network.
struct SumoMovement {
  SumoLaneRef from;  ///< the ingress lane (its last piece)
  SumoLaneRef to;    ///< the egress lane (its first piece)
  std::string junction;
  /// The movement's link index in the junction's traffic light (its index in
  /// `Intersection::movements`); unset when the intersection is neither signalised nor
  /// stop-controlled.
  std::optional<int> tls_link_index;
};

/// What `ExportSumo` wrote and how the map's ids map to SUMO's. Value type.
struct SumoExport {
  std::filesystem::path node_file;        ///< `<name>.nod.xml`
  std::filesystem::path edge_file;        ///< `<name>.edg.xml`
  std::filesystem::path connection_file;  ///< `<name>.con.xml`
  std::filesystem::path tll_file;         ///< `<name>.tll.xml` (empty `<tlLogics/>` when none)
  std::filesystem::path net_file;         ///< `<name>.net.xml`, written by netconvert
  std::filesystem::path vtype_file;       ///< `<name>.vtypes.xml`, an additional file
  /// `<name>.sumocfg`: the network and the vehicle types, with the options a lab run needs
  /// (no teleports, junction collision checks); `sumo -c` it with a route file.
  std::filesystem::path config_file;
  std::filesystem::path log_file;               ///< `<name>.netconvert.log`: its stdout and stderr
  std::string vehicle_type;                     ///< the default vType's id
  double scale = kSumoScale;                    ///< SUMO metres per lab metre
  std::vector<std::string> netconvert_command;  ///< as run
  /// Every map lane: the SUMO lane it starts on.
  std::map<LaneId, SumoLaneRef> lanes;
  /// Every map lane: the SUMO lanes it runs along, in driving order (two for a turning loop,
  /// else one).
  std::map<LaneId, std::vector<SumoLaneRef>> lane_pieces;
  std::map<IntersectionId, std::string> junctions;  ///< every intersection: SUMO junction id
  std::map<MovementId, SumoMovement> movements;     ///< every movement
  /// Every SUMO edge but internal ones: the map lanes it holds, by index from the centreline.
  std::map<std::string, std::vector<LaneId>> edges;

  const SumoLaneRef& lane(LaneId id) const { return lanes.at(id); }
  const SumoMovement& movement(MovementId id) const { return movements.at(id); }
};

/// Writes the map's SUMO plain XML and vehicle type into `out_dir` (created if missing) and
/// runs netconvert on them; files are named after the map (characters other than letters,
/// digits, '-', '_' and '.' become '_'; "map" when the name is empty). Nothing is written
/// outside `out_dir`. The plain XML files are pugixml documents, written with four spaces of
/// indentation; each movement's connection follows a comment with the movement's name.
/// Throws `InputError` when the options are out of range, an intersection name is not a valid
/// SUMO id, holds a control character (which XML cannot carry) or two intersections share one,
/// a file cannot be written, or netconvert cannot be started or fails (the message has the
/// command line and netconvert's output).
/// Throws `InputError` for a map without lanes (nothing to export).
SumoExport ExportSumo(const Map& map, const std::string& out_dir, const SumoOptions& options = {});

}  // namespace autodrive::maps
