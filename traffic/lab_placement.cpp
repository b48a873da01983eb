#include "traffic/lab_placement.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "traffic/sumo_frame.h"

namespace autodrive::traffic {

LabCarPlacement::LabCarPlacement(const TrafficNetwork& network, const LabCarsConfig& config,
                                 double length_sumo)
    : map_(network.map()),
      network_(network),
      config_(config),
      index_(std::make_unique<maps::MapIndex>(network.map())) {
  LabCarClaims::Options claims;
  claims.length_m = length_sumo / network.scale();
  claims.body_centre_ahead_m = config_.body_centre_ahead_m;
  claims_ = std::make_unique<LabCarClaims>(map_, *index_, claims);
}

LabCarPlacement::~LabCarPlacement() = default;

void LabCarPlacement::Place(const std::vector<LabCarPose>& cars, MonoTime now, SumoApi& api) {
  for (const LabCarPose& car : cars) {
    LabCar& lab = cars_[car.name];
    lab.last_seen = now;
    lab.pose = car;
    const Eigen::Vector2d heading(std::cos(car.yaw_rad), std::sin(car.yaw_rad));
    const Eigen::Vector2d centre = car.position + heading * config_.body_centre_ahead_m;
    const auto match = index_->NearestLane(centre, config_.max_lane_distance_m);
    // Inside an intersection's box a car is far from every lane's centreline (its paths there
    // are movements, not lanes): one in SUMO stays, moved where it is, as long as it is on the
    // road (out of SUMO, SUMO's cars would drive through it in the box).
    const bool on_road = match || (lab.in_sumo && index_->IsDrivable(centre));
    if (!on_road) {
      if (lab.in_sumo) {
        api.Remove(lab.sumo_id);
        lab.in_sumo = false;
        spdlog::info("traffic: {} is off the road: removed from SUMO until it is back", car.name);
      }
      continue;
    }
    if (!lab.in_sumo) Enter(lab, car, *match, api);
  }
  // Cars not heard from for too long leave SUMO.
  for (auto& [name, lab] : cars_) {
    if (lab.in_sumo && now - lab.last_seen > config_.staleness_s) {
      api.Remove(lab.sumo_id);
      lab.in_sumo = false;
      spdlog::info("traffic: {} is stale: removed from SUMO until it is heard again", name);
    }
  }
  placed_ =
      std::count_if(cars_.begin(), cars_.end(), [](const auto& kv) { return kv.second.in_sumo; });
}

void LabCarPlacement::Enter(LabCar& lab, const LabCarPose& car, const maps::LaneMatch& match,
                            SumoApi& api) {
  lab.sumo_id = car.name + (lab.entries == 0 ? "" : "#" + std::to_string(lab.entries));
  ++lab.entries;
  ids_.insert(lab.sumo_id);
  const std::string& edge = network_.EdgeOfLane(map_.lane(match.lane).name);
  const std::string route_id = "r_" + lab.sumo_id;
  api.AddRoute(route_id, {edge});
  api.AddVehicle(lab.sumo_id, route_id, network_.files().vehicle_type, "now", "best", "base", "0");
  api.SetSpeedMode(lab.sumo_id, 0);
  lab.in_sumo = true;
  lab.route_via.reset();
  lab.kept_route = false;
}

const std::vector<LabCarPose>& LabCarPlacement::InSumo() {
  in_sumo_.clear();
  for (const auto& [name, lab] : cars_) {
    if (lab.in_sumo) in_sumo_.push_back(lab.pose);
  }
  std::sort(in_sumo_.begin(), in_sumo_.end(),
            [](const LabCarPose& a, const LabCarPose& b) { return a.name < b.name; });
  return in_sumo_;
}

void LabCarPlacement::Move(SumoTime now, SumoCache& sumo) {
  const double s = network_.scale();
  const SumoTypeSize& nigel = sumo.TypeSize(network_.files().vehicle_type);
  // Every lab car in SUMO, also one not heard from this step: where it was last heard of (left
  // to itself, SUMO would drive it on along its route, and remove it at the route's end).
  for (const LabCarPose& car : in_sumo_) {
    LabCar& lab = cars_.at(car.name);
    const Eigen::Vector2d heading(std::cos(car.yaw_rad), std::sin(car.yaw_rad));
    // SUMO's position is the front bumper's middle.
    const Eigen::Vector2d front =
        car.position + heading * (config_.body_centre_ahead_m + nigel.length / s / 2);
    const Target t = TargetOf(lab, car, front, now, sumo);
    try {
      sumo.api().MoveToXY(lab.sumo_id, t.edge, t.lane, t.at.x() * s, t.at.y() * s,
                          SumoAngleFromYaw(car.yaw_rad), t.keep_route);
      lab.kept_route = t.keep_route;
    } catch (const SumoError& e) {
      ++misses_;
      spdlog::warn("traffic: {} could not be placed in SUMO: {}", car.name, e.what());
    }
  }
}

namespace {

// A SUMO lane id as its edge and index (the lane hint of a move).
void SplitLane(const std::string& sumo_lane, std::string& edge, int& lane) {
  const auto k = sumo_lane.rfind('_');
  edge = sumo_lane.substr(0, k);
  lane = std::stoi(sumo_lane.substr(k + 1));
}

}  // namespace

LabCarPlacement::Target LabCarPlacement::TargetOf(LabCar& lab, const LabCarPose& car,
                                                  const Eigen::Vector2d& front, SumoTime now,
                                                  SumoCache& sumo) {
  if (const auto under = claims_->Under(car.name)) {
    return InBox(lab, car, under->first, front, now, sumo.api());
  }
  Target t{front, "", -1, false};  // the lane is a hint only: SUMO takes the one nearest the point
  if (const auto on = FrontOnItsLane(car, front, sumo)) {
    // On a lane: its front on that lane's SUMO lane (or the next's, once past its end). SUMO
    // takes a move's lane when the point is beside that lane; else it weighs the lanes near
    // the point, and at a tile's join (where lanes end) that weighing has put a car on the
    // lane beside it that runs the other way.
    t.at = on->first;
    SplitLane(on->second, t.edge, t.lane);
    return t;
  }
  const Eigen::Vector2d heading(std::cos(car.yaw_rad), std::sin(car.yaw_rad));
  if (const auto match = index_->NearestLane(car.position + heading * config_.body_centre_ahead_m,
                                             config_.max_lane_distance_m)) {
    t.edge = network_.EdgeOfLane(map_.lane(match->lane).name);
    t.lane = 0;
  }
  return t;
}

LabCarPlacement::Target LabCarPlacement::InBox(LabCar& lab, const LabCarPose& car, MovementId m,
                                               const Eigen::Vector2d& front, SumoTime now,
                                               SumoApi& api) {
  // In a box, on a movement's path. The lane nearest its front may be another movement's
  // (paths cross there, or pass side by side): SUMO is to keep it on this one's lanes.
  Target t{front, "", -1, false};
  if (lab.route_via != m && (lab.lane.empty() || lab.lane.front() != ':')) {
    // Its route through the movement: SUMO takes it while the car is on the lane in (not
    // on another movement's internal lane, "leading elsewhere").
    const maps::SumoMovement& sm = network_.files().movement(m);
    try {
      api.SetRoute(lab.sumo_id, {sm.from.edge, sm.to.edge});
      lab.route_via = m;
    } catch (const SumoError& e) {
      spdlog::debug("traffic: {:.2f} s: {} keeps its route in SUMO: {}", ToSeconds(now), car.name,
                    e.what());
    }
  }
  if (lab.route_via == m) {
    t.keep_route = true;  // SUMO's route runs through it: at its pose, on the route's lanes
    return t;
  }
  // SUMO has it on another movement's internal lane: its front on this one's path (or, past the
  // box, on its lane out), where the nearest lane is the movement's own. SUMO takes it, and the
  // route through it.
  const maps::Movement& mv = map_.movement(m);
  const PolylinePoint q = NearestOnPolyline(mv.path, front);
  if (q.along_m < q.length_m) {
    t.at = q.point;
    const std::vector<std::string>& internal = network_.InternalLanes(m);
    if (!internal.empty()) {
      const auto k = std::min(
          internal.size() - 1,
          static_cast<std::size_t>(q.along_m / q.length_m * static_cast<double>(internal.size())));
      SplitLane(internal[k], t.edge, t.lane);
    }
  } else {
    t.at = NearestOnPolyline(map_.lane(mv.to).centreline, front).point;
    SplitLane(network_.files().movement(m).to.id(), t.edge, t.lane);
  }
  return t;
}

std::optional<std::pair<Eigen::Vector2d, std::string>> LabCarPlacement::FrontOnItsLane(
    const LabCarPose& car, const Eigen::Vector2d& front, SumoCache& sumo) const {
  // Its lane: the nearest to its body's centre that runs its way (the lane beside it runs the
  // other way, and may be nearer where it cuts a curve).
  const Eigen::Vector2d heading(std::cos(car.yaw_rad), std::sin(car.yaw_rad));
  const auto on =
      index_->NearestLaneHeading(car.position + heading * config_.body_centre_ahead_m, car.yaw_rad,
                                 config_.max_lane_distance_m, LabCarClaims::kAlignedRad);
  if (!on) return std::nullopt;
  const maps::Lane* lane = &map_.lane(on->lane);
  PolylinePoint q = NearestOnPolyline(lane->centreline, front);
  // SUMO's lanes end where the map's do (a join between tiles is a junction of no size): a
  // front at or past its lane's end is on the next one.
  constexpr double kInside = 0.002;  // metres from a lane's ends (SUMO: 2.8 cm)
  if (q.along_m > q.length_m - kInside) {
    if (lane->successors.size() != 1) return std::nullopt;  // into an intersection
    lane = &map_.lane(lane->successors.front());
    q = NearestOnPolyline(lane->centreline, front);
  }
  // The point beside the lane, within its width: where SUMO's weighing never decides.
  const double along = std::clamp(q.along_m, kInside, std::max(kInside, q.length_m - kInside));
  const auto [p, direction] = PointAlong(lane->centreline, along);
  const Eigen::Vector2d left(-std::sin(direction), std::cos(direction));
  const double half = std::max(0.0, lane->width_m / 2 - 0.01);
  const Eigen::Vector2d at = p + left * std::clamp((front - q.point).dot(left), -half, half);
  // The SUMO lane of the map lane there (a turning loop runs along two).
  const std::vector<maps::SumoLaneRef>& pieces = network_.files().lane_pieces.at(lane->id);
  std::size_t k = 0;
  double start = 0;
  const double s = network_.scale();
  while (k + 1 < pieces.size() && along > start + sumo.LaneLength(pieces[k].id()) / s) {
    start += sumo.LaneLength(pieces[k].id()) / s;
    ++k;
  }
  return std::pair{at, pieces[k].id()};
}

void LabCarPlacement::NoteLane(const SumoVehicleState& v, const LinkIndex& links, SumoTime now) {
  for (auto& [name, lab] : cars_) {
    if (lab.sumo_id != v.id) continue;
    // On a movement's internal lane, SUMO's route for it runs through that movement (a move
    // that may leave its route, and SUMO put it there, makes its route the movement's lanes in
    // and out). Anywhere else, after such a move, its route is whatever SUMO made it.
    if (const auto m = links.movement_of_lane.find(v.lane); m != links.movement_of_lane.end()) {
      lab.route_via = m->second;
    } else if (!lab.kept_route) {
      lab.route_via.reset();
    }
    if (lab.lane != v.lane) {
      spdlog::debug("traffic: {:.2f} s: {} is on {} in SUMO", ToSeconds(now), name, v.lane);
      lab.lane = v.lane;
    }
    return;
  }
}

bool LabCarPlacement::Arrived(const std::string& id, SumoTime now) {
  if (ids_.count(id) == 0) return false;
  // SUMO ends a vehicle's trip at its route's end, a moved one too: in again at the next step
  // (a lab car leaves SUMO only off the road or stale).
  for (auto& [name, lab] : cars_) {
    if (lab.sumo_id != id || !lab.in_sumo) continue;
    lab.in_sumo = false;
    ++misses_;
    spdlog::warn("traffic: SUMO ended {}'s trip at {:.2f} s: it goes in again", name,
                 ToSeconds(now));
  }
  return true;
}

bool LabCarPlacement::AllIn(const std::vector<std::string>& names,
                            const std::vector<SumoVehicleState>& vehicles) const {
  return std::all_of(names.begin(), names.end(), [&](const auto& n) {
    const auto it = cars_.find(n);
    return it != cars_.end() && it->second.in_sumo &&
           std::any_of(vehicles.begin(), vehicles.end(),
                       [&](const SumoVehicleState& v) { return v.id == it->second.sumo_id; });
  });
}

std::vector<std::tuple<std::string, double, double>> LabCarPlacement::Footprints(
    const std::vector<SumoVehicleState>& vehicles, double gap, SumoCache& sumo) const {
  std::vector<std::tuple<std::string, double, double>> out;
  for (const SumoVehicleState& v : vehicles) {
    if (ids_.count(v.id) == 0 || v.lane.empty() || v.lane.front() == ':') continue;
    const double length = sumo.TypeSize(v.type).length;
    out.emplace_back(v.lane.substr(0, v.lane.rfind('_')), v.lane_pos - length - gap,
                     v.lane_pos + gap);
  }
  return out;
}

std::string LabCarPlacement::Describe(const std::string& a, const std::string& b) const {
  std::string out;
  for (const auto& [name, lab] : cars_) {
    if (lab.sumo_id != a && lab.sumo_id != b) continue;
    out +=
        fmt::format("; {} was at ({:.3f}, {:.3f}) heading {:.2f} rad, on {} in SUMO before", name,
                    lab.pose.position.x(), lab.pose.position.y(), lab.pose.yaw_rad, lab.lane);
    if (claims_->InBox(name)) out += fmt::format(", in a box");
  }
  return out;
}

}  // namespace autodrive::traffic
