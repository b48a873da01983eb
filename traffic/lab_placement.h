#pragma once
/// @file
/// The lab's cars in SUMO: every car heard from is placed in SUMO as an externally moved vehicle
/// (moveToXY) at its pose, so that SUMO's cars follow it, stop behind it and yield to it; a car
/// that goes stale or leaves the road network leaves SUMO until it is back.
///
/// SUMO puts a moved car on the lane nearest its front bumper, whatever lane the move names, and
/// draws its body back along that lane. In an intersection's box that is often another
/// movement's (paths cross there, or pass side by side), and SUMO would see the car across paths
/// it is not on, and report collisions with the cars on them that never were. So in a box a car
/// is kept to the movement it drives (`LabCarClaims::Under`): its route in SUMO is set through
/// the movement (from its lane in, where SUMO has it there), and its moves keep to its route
/// (keepRoute 3); where SUMO has it on another movement's internal lane (whose route cannot
/// change there), its front is put on the movement's path for a move (keepRoute 2: SUMO takes
/// the lane under the point, and the route through it). On a lane, its front goes to SUMO on
/// that lane (or the next, once past its end), within the lane's width, with the lane named.
///
/// The rules (which car is in SUMO, where its front goes, on which lane) are on the control
/// timeline (`MonoTime`: when a car was heard from) and the map; SUMO is told through the
/// `SumoApi` each call is given.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "traffic/lab_claims.h"
#include "traffic/links.h"
#include "traffic/network.h"
#include "traffic/sumo_api.h"
#include "traffic/sumo_cache.h"
#include "traffic/sumo_time.h"
#include "traffic/traffic_config.h"

#include "common/time.h"
#include "maps/query.h"

namespace autodrive::traffic {

class LabCarPlacement {
 public:
  /// `network` must outlive it (and its map). `length_sumo`: the lab car's type's length (SUMO
  /// metres). Not copyable (the claims refer to its map index).
  LabCarPlacement(const TrafficNetwork& network, const LabCarsConfig& config, double length_sumo);
  ~LabCarPlacement();
  LabCarPlacement(const LabCarPlacement&) = delete;
  LabCarPlacement& operator=(const LabCarPlacement&) = delete;

  /// The cars heard from at `now`: into SUMO (or out of it, off the road); cars not heard from
  /// for `staleness_s` leave SUMO.
  void Place(const std::vector<LabCarPose>& cars, MonoTime now, SumoApi& api);
  /// Every lab car in SUMO where it was last heard of (the Eye or the fleet may skip a step),
  /// sorted by name: what the claims are updated with, and what `Move` moves.
  const std::vector<LabCarPose>& InSumo();
  /// The claims on the movements (lab_claims.h), to update after `InSumo`.
  [[nodiscard]] LabCarClaims& claims() { return *claims_; }
  /// Moves the cars of the last `InSumo` to their poses in SUMO (`now`: SUMO's time, for logs).
  void Move(SumoTime now, SumoCache& sumo);

  /// After a step: where SUMO has lab car `v` (when `v` is one).
  void NoteLane(const SumoVehicleState& v, const LinkIndex& links, SumoTime now);
  /// SUMO ended the trip of `id` (at its route's end): when it is a lab car's, it goes in again
  /// at the next step (counted as a miss) and true is returned.
  bool Arrived(const std::string& id, SumoTime now);

  /// Whether SUMO id `id` is (or was) a lab car's.
  [[nodiscard]] bool IsLab(const std::string& id) const {
    return !ids_.empty() && ids_.count(id) != 0;
  }
  /// Every SUMO id a lab car had.
  [[nodiscard]] const std::unordered_set<std::string>& ids() const { return ids_; }
  /// Whether every car of `names` is in SUMO, as `vehicles` (SUMO's report) say.
  [[nodiscard]] bool AllIn(const std::vector<std::string>& names,
                           const std::vector<SumoVehicleState>& vehicles) const;
  /// Where the lab cars on edges are in `vehicles`: (edge, back, front) in SUMO metres, with
  /// `gap` either side.
  [[nodiscard]] std::vector<std::tuple<std::string, double, double>> Footprints(
      const std::vector<SumoVehicleState>& vehicles, double gap, SumoCache& sumo) const;
  /// For a collision's log line: where the lab cars among SUMO ids `a` and `b` were.
  [[nodiscard]] std::string Describe(const std::string& a, const std::string& b) const;

  /// Lab cars in SUMO now.
  [[nodiscard]] std::int64_t placed() const { return placed_; }
  /// Placements SUMO refused, and trips it ended, since the start.
  [[nodiscard]] std::int64_t misses() const { return misses_; }

 private:
  struct LabCar {
    MonoTime last_seen{};
    bool in_sumo = false;
    std::string sumo_id;  // the name, then name#k after the k-th re-entry
    int entries = 0;
    std::string lane;  // SUMO's lane for it after the last step (for logs)
    LabCarPose pose;   // the last heard
    // The movement SUMO's route for it runs through (its lane in, then its lane out), when known:
    // a move that keeps to its route then puts it on that movement's lanes.
    std::optional<MovementId> route_via;
    bool kept_route = false;  // its last move kept to its route
  };
  // Where SUMO is to have a car's front, on which lane, and whether the move keeps its route.
  struct Target {
    Eigen::Vector2d at;
    std::string edge;
    int lane = -1;
    bool keep_route = false;
  };
  void Enter(LabCar& lab, const LabCarPose& car, const maps::LaneMatch& match, SumoApi& api);
  Target TargetOf(LabCar& lab, const LabCarPose& car, const Eigen::Vector2d& front, SumoTime now,
                  SumoCache& sumo);
  // In a box: on the movement under it.
  Target InBox(LabCar& lab, const LabCarPose& car, MovementId m, const Eigen::Vector2d& front,
               SumoTime now, SumoApi& api);
  // For a car on a lane (not in a box): where SUMO is to have its front (`front`, on its lane or
  // the next, within the lane's width) and on which SUMO lane.
  std::optional<std::pair<Eigen::Vector2d, std::string>> FrontOnItsLane(
      const LabCarPose& car, const Eigen::Vector2d& front, SumoCache& sumo) const;

  const maps::Map& map_;
  const TrafficNetwork& network_;
  LabCarsConfig config_;
  std::unique_ptr<maps::MapIndex> index_;
  std::unique_ptr<LabCarClaims> claims_;
  std::unordered_map<std::string, LabCar> cars_;
  std::unordered_set<std::string> ids_;  // every SUMO id a lab car had
  std::vector<LabCarPose> in_sumo_;      // of the last `InSumo`
  std::int64_t placed_ = 0;
  std::int64_t misses_ = 0;
};

}  // namespace autodrive::traffic
