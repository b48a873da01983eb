#include "traffic/lab_claims.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/geometry.h"

namespace autodrive::traffic {

LabCarClaims::LabCarClaims(const maps::Map& map, const maps::MapIndex& index, Options options)
    : map_(map), index_(index), options_(options) {
  for (const maps::Lane& l : map.lanes)
    max_half_width_m_ = std::max(max_half_width_m_, l.width_m / 2);
  foes_.resize(map.movements.size() + 1);
  for (const maps::Intersection& x : map.intersections) {
    for (const auto& [a, b] : x.conflicts) {
      foes_[a.value()].push_back(b);
      foes_[b.value()].push_back(a);
    }
  }
}

std::optional<maps::LaneMatch> LabCarClaims::LaneUnder(const Eigen::Vector2d& p, double yaw) const {
  const auto match = index_.NearestLaneHeading(p, yaw, max_half_width_m_, kAlignedRad);
  if (!match || match->distance_m > map_.lane(match->lane).width_m / 2) return std::nullopt;
  return match;
}

bool LabCarClaims::Aligned(const PolylinePoint& q, double yaw) const {
  return std::abs(WrapAngle(q.direction_rad - yaw)) < options_.on_path_rad;
}

void LabCarClaims::Follow(Car& car, const LabCarPose& pose) {
  const Eigen::Vector2d heading(std::cos(pose.yaw_rad), std::sin(pose.yaw_rad));
  const Eigen::Vector2d centre = pose.position + heading * options_.body_centre_ahead_m;
  const Eigen::Vector2d rear = centre - heading * (options_.length_m / 2);
  const auto on = LaneUnder(centre, pose.yaw_rad);
  const maps::Lane* lane = on ? &map_.lane(on->lane) : nullptr;
  // In a box until its rear is on a lane out of it (or it is far from it).
  if (car.box) {
    const maps::Intersection& x = map_.intersection(*car.box);
    const auto behind = LaneUnder(rear, pose.yaw_rad);
    const bool out =
        behind && map_.lane(behind->lane).egress_of == car.box && behind->along_m > 0.01;
    if (out || (centre - x.centre).lpNorm<Eigen::Infinity>() > map_.tile_size_m) {
      car.box.reset();
      car.entry.reset();
    }
  }
  // On its way into an intersection: near the stop line, or over it (then in the box). In a box,
  // the centre may come near the end of another of its ingress lanes: that is not a new entry.
  car.approaching.reset();
  if (lane != nullptr && lane->ingress_of && lane->stop_line &&
      !(car.box == lane->ingress_of && car.entry && car.entry != lane->id)) {
    const double to_line = lane->length_m - on->along_m - options_.length_m / 2;
    if (to_line < 0) {
      car.box = lane->ingress_of;
      car.entry = lane->id;
    } else if (to_line < options_.approach_m) {
      car.approaching = lane->id;
    }
  }
  // First seen inside a controlled intersection's tile and on no lane: in that box.
  if (car.seen || lane != nullptr || car.box) return;
  for (const maps::Intersection& x : map_.intersections) {
    if (x.control != maps::Control::kSignal && x.control != maps::Control::kStop) continue;
    if ((centre - x.centre).lpNorm<Eigen::Infinity>() < map_.tile_size_m / 2) {
      car.box = x.id;
      car.entry.reset();
      return;
    }
  }
}

void LabCarClaims::Claim(Car& car, const LabCarPose& pose,
                         const std::function<bool(MovementId)>& may_enter) {
  const auto controlled = [&](IntersectionId id) {
    const maps::Control c = map_.intersection(id).control;
    return c == maps::Control::kSignal || c == maps::Control::kStop;
  };
  const auto add_with_foes = [&](MovementId m, bool itself) {
    if (itself) held_.push_back(m);
    held_.insert(held_.end(), foes_[m.value()].begin(), foes_[m.value()].end());
  };
  if (car.approaching && controlled(*map_.lane(*car.approaching).ingress_of)) {
    for (const MovementId m : map_.lane(*car.approaching).movements_out) {
      if (may_enter(m)) add_with_foes(m, false);
    }
  }
  car.under.reset();
  if (!car.box || !controlled(*car.box)) return;
  const maps::Intersection& x = map_.intersection(*car.box);
  const Eigen::Vector2d heading(std::cos(pose.yaw_rad), std::sin(pose.yaw_rad));
  const Eigen::Vector2d centre = pose.position + heading * options_.body_centre_ahead_m;
  const std::vector<MovementId>& candidates =
      car.entry ? map_.lane(*car.entry).movements_out : x.movements;
  std::vector<MovementId> on;
  // The path it is on (the first, where several still run together), else the nearest that
  // runs its way.
  std::optional<std::pair<MovementId, PolylinePoint>> under;
  for (const MovementId m : candidates) {
    const PolylinePoint q = NearestOnPolyline(map_.movement(m).path, centre);
    if (!Aligned(q, pose.yaw_rad)) continue;
    if (q.distance_m < options_.on_path_m) {
      if (on.empty()) under = std::pair{m, q};
      on.push_back(m);
    } else if (on.empty() && (!under || q.distance_m < under->second.distance_m)) {
      under = std::pair{m, q};
    }
  }
  if (under) {
    const PolylinePoint& q = under->second;
    car.under = std::pair{under->first, q.length_m > 0 ? q.along_m / q.length_m : 0.0};
  }
  // The movements it may be on, and what conflicts with them; and every movement from its lane
  // (a vehicle behind it cannot pass it, and SUMO may not see it in the box as its leader).
  for (const MovementId m : on.empty() ? candidates : on) add_with_foes(m, true);
  if (car.entry) {
    for (const MovementId m : candidates) held_.push_back(m);
  }
}

void LabCarClaims::Update(const std::vector<LabCarPose>& cars,
                          const std::function<bool(MovementId)>& may_enter) {
  held_.clear();
  std::unordered_map<std::string, Car> now;
  for (const LabCarPose& pose : cars) {
    Car car;
    if (const auto it = cars_.find(pose.name); it != cars_.end()) car = it->second;
    Follow(car, pose);
    car.seen = true;
    Claim(car, pose, may_enter);
    now[pose.name] = car;
  }
  cars_ = std::move(now);
  std::sort(held_.begin(), held_.end());
  held_.erase(std::unique(held_.begin(), held_.end()), held_.end());
}

std::optional<LaneId> LabCarClaims::Approaching(const std::string& name) const {
  const auto it = cars_.find(name);
  return it == cars_.end() ? std::nullopt : it->second.approaching;
}

std::optional<IntersectionId> LabCarClaims::InBox(const std::string& name) const {
  const auto it = cars_.find(name);
  return it == cars_.end() ? std::nullopt : it->second.box;
}

std::optional<std::pair<MovementId, double>> LabCarClaims::Under(const std::string& name) const {
  const auto it = cars_.find(name);
  return it == cars_.end() ? std::nullopt : it->second.under;
}

}  // namespace autodrive::traffic
