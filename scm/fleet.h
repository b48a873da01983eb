#pragma once
/// @file
/// The fleet registry: the latest observation of every vehicle, located on the map (lane,
/// intersection, approach, distance to the stop line), published as `/autodrive/scm/fleet` and
/// queried by actuated signal control ("is a car waiting in this detector zone?").

#include <array>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
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

/// "eye", "sim_ground_truth", "odometry" or "ips".
[[nodiscard]] std::string_view ToString(PoseSource source);

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
  /// stop line in [`zone.from_stop_line_m`, `zone.to_stop_line_m`]. A vehicle's origin is
  /// what counts: widen the zone by half a car length to detect any part of a car.
  /// @throws InputError when the lane is not in the map or is not an ingress lane, or when the
  ///   zone's range is empty or not finite.
  [[nodiscard]] bool Occupied(const DetectorZone& zone, Time now) const;

  /// Forgets observations that are stale at `now`. Returns how many were forgotten.
  std::size_t DropStale(Time now);

  /// The parameters.
  [[nodiscard]] const FleetRegistryParams& params() const { return params_; }

 private:
  struct Entry {
    VehicleObservation observation;
    VehicleLocation location;
  };
  [[nodiscard]] bool Fresh(const VehicleObservation& o, Time now) const;
  // Heading compatible; any heading fits when `yaw_rad` is nothing (unknown heading).
  [[nodiscard]] bool HeadingFits(const Eigen::Vector2d& tangent,
                                 std::optional<double> yaw_rad) const;
  // The nearest lane that fits (within reach, heading-compatible) and the arc length along it.
  [[nodiscard]] std::optional<std::pair<LaneId, double>> NearestLane(
      const Eigen::Vector2d& p, std::optional<double> yaw_rad) const;
  // Calls f(entry) for the chosen entry of each vehicle fresh at `now`, in vehicle order,
  // without allocating. Caller holds the lock.
  template <typename F>
  void ForEachChosen(Time now, F&& f) const;
  [[nodiscard]] const maps::Intersection* BoxAt(const Eigen::Vector2d& p) const;
  [[nodiscard]] std::vector<const Entry*> Chosen(Time now) const;

  const maps::Map& map_;
  const FleetRegistryParams params_;
  const maps::MapIndex index_;
  std::vector<Eigen::AlignedBox2d> lane_boxes_;  // per lane: centreline box, grown by the reach
  double max_reach_m_ = 0.0;                     // the largest lane half-width plus margin
  std::vector<const maps::Intersection*> box_of_tile_;  // row-major; null where none
  // Per lane: the approach it enters its intersection by. Not `Lane::approach`, which a lane
  // that leaves one intersection and enters the next has only one of.
  std::vector<std::optional<ApproachId>> ingress_approach_;
  mutable std::mutex mutex_;
  std::map<std::pair<VehicleId, PoseSource>, Entry> entries_;
};

}  // namespace autodrive::scm
