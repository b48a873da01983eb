#pragma once
/// @file
/// The fleet registry: the latest observation of every vehicle, located on the map (lane,
/// intersection, approach, distance to the stop line), published as `/autodrive/scm/fleet` and
/// queried by actuated signal control ("is a car waiting in this detector zone?"). Beside the
/// lab's fleet it keeps the background traffic (SUMO's vehicles), which detectors see as they
/// see lab cars but which is not published as part of the fleet.

#include <array>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "common/config.h"
#include "common/dds/messages.h"
#include "common/geometry.h"
#include "common/ids.h"
#include "common/time.h"
#include "maps/map.h"
#include "maps/query.h"

namespace autodrive::scm {

/// The fleet state as published.
using FleetStateMessage = dds::Message<msg::FleetState>;

/// Where a pose comes from; the values are the wire values (`TrackedVehicle_Constants`, checked
/// at the DDS edge). When several sources have a fresh observation of one vehicle, the registry
/// reports one, preferring simulator ground truth (exact by definition) over the Eye (an
/// external, absolute measurement with heading) over the devkit's `ips` topic (a position only,
/// heading from its motion) over odometry (the car's own estimate, which drifts).
enum class PoseSource : std::uint8_t {
  kEye = 1,
  kSimGroundTruth = 2,
  kOdometry = 3,
  kIps = 5,
};

/// "eye", "sim_ground_truth", "odometry" or "ips": the one name of each source, for the SCM's
/// logs and for every client that shows a fleet (scmctl, the dashboard).
[[nodiscard]] std::string_view ToString(PoseSource source);
/// The wire value (`TrackedVehicle_Constants`) of `source`.
[[nodiscard]] std::uint8_t ToWire(PoseSource source);
/// The source with wire value `value`, or nothing for a value that is none of the SCM's
/// (`FUSED`, which no part of the platform produces, or an unknown number).
[[nodiscard]] std::optional<PoseSource> PoseSourceFromWire(std::uint8_t value);

/// One observation of one vehicle.
struct VehicleObservation {
  VehicleId vehicle{0};
  PoseSource source = PoseSource::kEye;
  Time observed{};  ///< when the pose was true, in the system's clock
  /// The vehicle frame V (X forward, Y left, Z up) in the map frame M. A planar pose is
  /// `X_MV_2d.ToRigidTransform3()`; only x, y and yaw are used to locate the vehicle.
  RigidTransform3 X_MV;
  double speed_mps = 0.0;  ///< along V's +x; negative when reversing
  /// Pose covariance in ROS order (x, y, z, roll, pitch, yaw; row-major 6x6); zeros when
  /// unknown.
  std::array<double, 36> pose_covariance{};
  std::optional<TagId> tag;  ///< the AprilTag on its roof, when known
  /// False when the source does not know the heading (the yaw of `X_MV` means nothing): the
  /// vehicle is then located on the nearest lane whatever its direction (a parked car whose
  /// `ips` never moved still gets its lane).
  bool heading_known = true;
};

/// Where a vehicle is on the map. Everything is empty for a vehicle off the road network.
struct VehicleLocation {
  /// The lane it is on. Inside an intersection box on a movement: the ingress lane the
  /// movement starts from.
  std::optional<LaneId> lane;
  /// Inside an intersection box: the movement whose path it is on, when one is near.
  std::optional<MovementId> movement;
  /// The intersection whose box it is in, or whose ingress lane it is on.
  std::optional<IntersectionId> intersection;
  /// With `intersection` on an ingress lane or a movement: the approach it came from.
  std::optional<ApproachId> approach;
  /// With `approach`: the distance along the lane from the vehicle's origin to the stop line
  /// (the ingress lane's end, where an uncontrolled intersection has no line), m; negative past
  /// it (along the movement's path).
  std::optional<double> distance_to_stop_line_m;
  bool operator==(const VehicleLocation&) const = default;
};

/// A vehicle as the registry reports it: the observation chosen and where it is.
struct FleetVehicle {
  VehicleObservation observation;
  VehicleLocation location;
};

/// One background vehicle (SUMO's, from `/autodrive/scm/traffic`) as its source hands it to the
/// registry. The views point into the message: valid for the call only.
struct TrafficObservation {
  std::string_view id;  ///< the traffic simulation's id, unique among its vehicles
  /// The name of the map lane it is on ("r2c3:W>E:0") or of the movement it follows inside an
  /// intersection ("r2c3:S>W:0>0"); empty when on neither.
  std::string_view map_lane;
  /// The centre of its footprint in the map frame M (m).
  Eigen::Vector2d p_MC = Eigen::Vector2d::Zero();
  double length_m = 0.0;  ///< its footprint's length along its direction of travel
};

/// What `FleetRegistry::ObserveTraffic` did with a batch.
struct TrafficUpdate {
  std::size_t recorded = 0;   ///< on a lane or movement of this map, recorded
  std::size_t elsewhere = 0;  ///< on no lane or movement of this map (empty or unknown name)
  std::size_t ignored = 0;    ///< older than what is recorded of the same vehicle
  std::size_t refused = 0;    ///< malformed (see `ObserveTraffic`) or beyond the capacity
  std::size_t dropped = 0;    ///< forgotten as stale
};

/// How many vehicles are on one approach of an intersection: on its ingress lanes or inside the
/// box on a movement from it.
struct ApproachCount {
  ApproachId approach{0};
  std::size_t lab = 0;         ///< the lab's fleet (as in `Vehicles`)
  std::size_t background = 0;  ///< background traffic
  bool operator==(const ApproachCount&) const = default;
};

/// A detection zone of actuated control: a stretch of `lane` between `from_stop_line_m` and
/// `to_stop_line_m` upstream of its stop line (m; e.g. 0 to 0.4; negative values reach past
/// the line into the box), both ends included.
struct DetectorZone {
  LaneId lane{0};
  double from_stop_line_m = 0.0;
  double to_stop_line_m = 0.0;
};

/// Parameters of the registry.
struct FleetRegistryParams {
  /// Observations older than this are dropped from the output.
  Duration staleness = std::chrono::seconds(1);
  /// A vehicle is on a lane when its origin is within half the lane's width plus this of the
  /// centreline (m).
  double lane_margin_m = 0.05;
  /// ... and its heading is within this of the lane's direction there (rad), so a car is never
  /// put on the opposing lane.
  double max_heading_error_rad = kPi / 3;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("staleness_s", staleness);
    a.Optional("lane_margin_m", lane_margin_m, config::Range{0.0, 1.0});
    a.Optional("max_heading_error_rad", max_heading_error_rad, config::Range{0.0, kPi});
  }
  /// Checks the ranges (staleness > 0, margin in [0, 1] m, heading error in [0, pi]).
  /// @throws InputError naming the value.
  void Validate() const;
  bool operator==(const FleetRegistryParams&) const = default;
};

/// The latest observation of every vehicle from every source, each located on the map when it
/// arrives. Thread-safe: observations may come from DDS listener threads while the daemon's loop
/// reads. Holds a reference to the map, which must outlive it; not copyable or movable.
class FleetRegistry {
 public:
  /// A registry over `map` (which must outlive it).
  /// @throws InputError when `params` is out of range.
  explicit FleetRegistry(const maps::Map& map, FleetRegistryParams params = {});
  FleetRegistry(const FleetRegistry&) = delete;
  FleetRegistry& operator=(const FleetRegistry&) = delete;

  /// Records `observation`, replacing the previous one of the same vehicle and source unless
  /// that one is newer by at most `staleness` (an observation that arrives out of order is
  /// ignored; one older by more is taken as the source's clock having restarted, e.g. a new
  /// simulation run, and replaces it). Returns true when it was recorded.
  /// @throws InputError when the source is not one of `PoseSource`, or the speed or a
  ///   covariance element is not finite.
  bool Observe(const VehicleObservation& observation);

  /// Where a vehicle with pose `X_MV` (map frame) is: in an intersection box, on the movement
  /// whose path is nearest (within the lane half-width plus margin, heading-compatible), else
  /// on the nearest heading-compatible lane within its half-width plus margin.
  [[nodiscard]] VehicleLocation Locate(const RigidTransform2& X_MV,
                                       bool heading_known = true) const;

  /// Every vehicle with a fresh observation at `now` (observed within `staleness` of `now`,
  /// either side: hosts' clocks differ a little), the preferred source's when several are (see
  /// `PoseSource`), by vehicle id.
  [[nodiscard]] std::vector<FleetVehicle> Vehicles(Time now) const;

  /// `Vehicles(now)` as the fleet state message: header stamp `now`, frame "map"; per vehicle
  /// its name ("nigel_1"), tag id (0 when unknown), source, observed time, pose with
  /// covariance, twist (linear x = speed, zero covariance) and location (empty lane name and
  /// zeros where `VehicleLocation` is empty).
  [[nodiscard]] FleetStateMessage State(Time now) const;
  /// `State(now)` written into `m`, reusing its memory: no allocation while the vehicles, their
  /// names and lanes stay the same (the daemon's 10 Hz publisher).
  void StateInto(Time now, FleetStateMessage& m) const;

  /// True when a fresh vehicle (as in `Vehicles`) is on `zone.lane` with its distance to the
  /// stop line in [`zone.from_stop_line_m`, `zone.to_stop_line_m`], or when a fresh background
  /// vehicle's footprint on `zone.lane` (or on a movement from it) reaches into that range. A
  /// lab vehicle's origin is what counts (its length is not known): widen the zone by half a
  /// car length to detect any part of a car. Costs the lab vehicles plus the background
  /// vehicles on that lane; allocates nothing.
  /// @throws InputError when the lane is not in the map or is not an ingress lane, or when the
  ///   zone's range is empty or not finite.
  [[nodiscard]] bool Occupied(const DetectorZone& zone, Time now) const;

  /// Records background traffic observed at `observed` (the traffic simulation's step, in the
  /// system's clock). Each vehicle is placed by its `map_lane` name: on a lane, its distance
  /// to the lane's stop line when the lane enters an intersection; on a movement, the ingress
  /// lane the movement starts from with a negative distance (past the line), as `Locate` does.
  /// A vehicle whose name is on no lane or movement of this map is not recorded, and one
  /// recorded before is forgotten (it left this map). A vehicle named in an earlier batch and
  /// not in this one stays until it is stale (as lab vehicles do); one whose stored
  /// observation is newer by at most `staleness` is left alone (out of order), and a newer one
  /// by more is replaced (a restarted simulation). Vehicles stale at `observed` are forgotten.
  /// Refused and counted, never thrown: an empty id or one longer than `kMaxTrafficIdBytes`, a
  /// position or length that is not finite, a negative length, and new vehicles beyond
  /// `kMaxTrafficVehicles`. Allocates only for vehicles it has not seen before (and for a lane
  /// name longer than any the vehicle had). Thread-safe; holds the registry's lock for the
  /// batch (about 0.4 ms for 5,000 vehicles).
  TrafficUpdate ObserveTraffic(Time observed, std::span<const TrafficObservation> objects);

  /// Background vehicles on this map that are fresh at `now` (as in `Vehicles`).
  [[nodiscard]] std::size_t BackgroundVehicles(Time now) const;

  /// For each approach of intersection `x` (in the map's order), the fresh vehicles on it, lab
  /// and background. Empty when `x` is not an intersection of the map.
  [[nodiscard]] std::vector<ApproachCount> ApproachCounts(IntersectionId x, Time now) const;

  /// Forgets observations, of lab and background vehicles, that are stale at `now`. Returns
  /// how many were forgotten.
  std::size_t DropStale(Time now);

  /// Background vehicles a registry keeps at most: a batch's vehicles beyond it are refused
  /// (the traffic topic comes from the network and must not grow the SCM without bound).
  static constexpr std::size_t kMaxTrafficVehicles = 65'536;
  /// The longest background vehicle id taken, bytes.
  static constexpr std::size_t kMaxTrafficIdBytes = 256;

  /// The parameters.
  [[nodiscard]] const FleetRegistryParams& params() const { return params_; }

 private:
  struct Entry {
    VehicleObservation observation;
    VehicleLocation location;
  };
  // A lane or movement as background vehicles are placed on it by name.
  struct Place {
    // Its centreline or path within 1 mm: a few segments where the map has fifty, so that
    // thousands of vehicles a message are placed quickly.
    maps::Polyline line;
    double length_m = 0.0;  // of `line`
    LaneId lane{0};         // the lane, or the ingress lane the movement starts from
    // An ingress lane: the intersection it enters and by which approach; a movement: the one
    // it crosses and the approach it comes from. Nothing for other lanes.
    std::optional<IntersectionId> intersection;
    ApproachId approach{0};
    bool movement = false;  // distances to the stop line are negative along it
  };
  // A background vehicle: where it is and when it was seen.
  struct Background {
    Time observed{};
    std::string place_name;   // the name it was placed by: while it stays, no lookup
    std::uint32_t place = 0;  // index into `places_`
    // With the place's intersection: from its centre to the stop line (negative past it).
    double distance_to_stop_line_m = 0.0;
    double half_length_m = 0.0;
  };
  // A background vehicle in the per-lane index that `Occupied` reads: its footprint's extent
  // as distances to the stop line.
  struct ZoneEntry {
    double nearest_m = 0.0;   // its front
    double farthest_m = 0.0;  // its back
    Time observed{};
  };
  struct StringHash {
    using is_transparent = void;
    std::size_t operator()(std::string_view s) const noexcept {
      return std::hash<std::string_view>{}(s);
    }
  };
  [[nodiscard]] bool Fresh(const VehicleObservation& o, Time now) const;
  // Observed within `staleness` of `now`, either side.
  [[nodiscard]] bool FreshAt(Time observed, Time now) const;
  // Heading compatible; any heading fits when `yaw_rad` is nothing (unknown heading).
  // `direction_rad`: the lane's (or path's) direction at the car.
  [[nodiscard]] bool HeadingFits(double direction_rad, std::optional<double> yaw_rad) const;
  // The nearest lane that fits (within reach, heading-compatible) and the arc length along it.
  [[nodiscard]] std::optional<std::pair<LaneId, double>> NearestLane(
      const Eigen::Vector2d& p, std::optional<double> yaw_rad) const;
  // Calls f(entry) for the chosen entry of each vehicle fresh at `now`, in vehicle order,
  // without allocating. Caller holds the lock.
  template <typename F>
  void ForEachChosen(Time now, F&& f) const;
  [[nodiscard]] const maps::Intersection* BoxAt(const Eigen::Vector2d& p) const;
  [[nodiscard]] std::vector<const Entry*> Chosen(Time now) const;
  // The index into `places_` of the lane or movement called `name`, or nothing.
  [[nodiscard]] std::optional<std::uint32_t> FindPlace(std::string_view name) const;
  // Places `b` at `o`'s centre on place `place`.
  void PlaceBackground(const TrafficObservation& o, std::uint32_t place, Background& b) const;
  // Rebuilds the per-lane index from `background_`. Caller holds the lock. Allocates nothing
  // once the index has grown to the number of vehicles.
  void IndexBackground();
  // Forgets background vehicles stale at `now`. Caller holds the lock.
  std::size_t DropStaleBackground(Time now);

  const maps::Map& map_;
  const FleetRegistryParams params_;
  const maps::MapIndex index_;
  std::vector<Eigen::AlignedBox2d> lane_boxes_;  // per lane: centreline box, grown by the reach
  double max_reach_m_ = 0.0;                     // the largest lane half-width plus margin
  std::vector<const maps::Intersection*> box_of_tile_;  // row-major; null where none
  // Lanes (by id) then movements (by id); indices by name (views of the map's names).
  std::vector<Place> places_;
  std::unordered_map<std::string_view, std::uint32_t> place_of_name_;
  mutable std::mutex mutex_;
  std::map<std::pair<VehicleId, PoseSource>, Entry> entries_;
  std::unordered_map<std::string, Background, StringHash, std::equal_to<>> background_;
  // The background vehicles with a distance to a stop line, by lane: those on lane id l are
  // zone_entries_[lane_first_[l - 1], lane_first_[l]).
  std::vector<std::uint32_t> lane_first_;
  std::vector<std::uint32_t> lane_fill_;
  std::vector<ZoneEntry> zone_entries_;
};

}  // namespace autodrive::scm
