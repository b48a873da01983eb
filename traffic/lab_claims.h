#pragma once
/// @file
/// Where the lab's cars are about the intersections, so that SUMO's vehicles give way to them.
///
/// SUMO knows a lab car only as a vehicle moved to a position (moveToXY, keepRoute 2): on the
/// lane nearest its front bumper. Inside an intersection's box (a 1:14 box at 14x, full of
/// crossing internal lanes) that lane jumps from one movement to another from step to step, so
/// SUMO's own right-of-way rules, and the co-simulation's all-way arbitration, cannot tell what
/// the car is doing there. This class tells it from the map instead: each lab car is followed
/// from its ingress lane, over its stop line and through the box until its rear is on an egress
/// lane, and the movements SUMO's vehicles must not start meanwhile are:
/// - while it approaches (its front within `approach_m` of the stop line, its light not red):
///   the movements that conflict with any movement out of its lane (it may take any of them;
///   a SUMO vehicle ahead of it on its own lane may still go: diverging movements never
///   conflict);
/// - while it is in the box: the movements out of its lane that agree with its pose (all of
///   them when none does) and every movement that conflicts with them, and every movement out
///   of its lane (a SUMO vehicle behind it waits at the line, since SUMO may not see it in the
///   box as its leader).
/// A lab car that starts inside a box claims the movements whose paths pass under it.

#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/ids.h"
#include "maps/map.h"
#include "maps/polyline.h"
#include "maps/query.h"

namespace autodrive::traffic {

// The polyline helpers this component uses (maps/polyline.h).
using maps::NearestOnPolyline;
using maps::PointAlong;
using maps::PolylinePoint;

/// A lab car's pose: its origin (the middle of its rear axle) in the map frame.
struct LabCarPose {
  std::string name;  ///< "nigel_1": also its SUMO id
  Eigen::Vector2d position = Eigen::Vector2d::Zero();
  double yaw_rad = 0.0;
  double speed_mps = 0.0;
};

class LabCarClaims {
 public:
  struct Options {
    double length_m = 0.318;               ///< the lab car's body
    double body_centre_ahead_m = 0.07077;  ///< the body's centre ahead of the car's origin
    double approach_m = 0.45;              ///< front to stop line under which a car claims
    double on_path_m = 0.1;                ///< a movement's path this near the body's centre...
    double on_path_rad = 0.7;              ///< ... and this well aligned is the one it is on
  };

  /// How far a car's heading may turn from its lane's and the car still run along that lane.
  static constexpr double kAlignedRad = 1.2;

  /// `map` and `index` must outlive it.
  LabCarClaims(const maps::Map& map, const maps::MapIndex& index, Options options);

  /// Each step: the lab cars' poses (a car not listed is forgotten). `may_enter(m)`: whether
  /// the light of movement `m` lets a vehicle in now (anything but red).
  void Update(const std::vector<LabCarPose>& cars,
              const std::function<bool(MovementId)>& may_enter);

  /// The movements no SUMO vehicle may start now, sorted, each once.
  [[nodiscard]] const std::vector<MovementId>& held() const { return held_; }

  /// For tests and logs: the ingress lane whose stop line car `name` approaches, and the
  /// intersection whose box it is in (a car on a short link can be in one and approach the next).
  [[nodiscard]] std::optional<LaneId> Approaching(const std::string& name) const;
  [[nodiscard]] std::optional<IntersectionId> InBox(const std::string& name) const;
  /// For a car in a box: the movement whose path is under it (the first, where several still
  /// run together; where it strays from them all, the one whose path is nearest, if one runs
  /// its way) and how far along that path its body's centre is (0 to 1). What SUMO is to have
  /// it on (cosim.h).
  [[nodiscard]] std::optional<std::pair<MovementId, double>> Under(const std::string& name) const;

 private:
  struct Car {
    std::optional<LaneId> approaching;  // the ingress lane whose stop line is near its front
    std::optional<IntersectionId> box;  // the intersection whose box it is in
    std::optional<LaneId> entry;        // by this lane (unknown for a car that started there)
    std::optional<std::pair<MovementId, double>> under;  // in the box: its path, how far along
    bool seen = false;
  };
  void Follow(Car& car, const LabCarPose& pose);
  void Claim(Car& car, const LabCarPose& pose, const std::function<bool(MovementId)>& may_enter);
  // Whether a car heading along yaw runs the way of the path at q.
  [[nodiscard]] bool Aligned(const PolylinePoint& q, double yaw) const;
  // The lane under point p (within its half width) that runs its way (kAlignedRad),
  // if any.
  [[nodiscard]] std::optional<maps::LaneMatch> LaneUnder(const Eigen::Vector2d& p,
                                                         double yaw) const;

  const maps::Map& map_;
  const maps::MapIndex& index_;
  Options options_;
  double max_half_width_m_ = 0.0;              // of the map's widest lane
  std::vector<std::vector<MovementId>> foes_;  // by movement id
  std::unordered_map<std::string, Car> cars_;
  std::vector<MovementId> held_;
};

}  // namespace autodrive::traffic
