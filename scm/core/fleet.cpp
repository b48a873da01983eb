#include "scm/core/fleet.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "autodrive_msgs/msg/TrackedVehicle.h"

#include "common/dds/conversions.h"
#include "common/error.h"
#include "maps/polyline.h"

namespace autodrive::scm {
namespace {

// Preference among fresh sources: lower is preferred (see PoseSource).
int Rank(PoseSource source) {
  switch (source) {
    case PoseSource::kSimGroundTruth:
      return 0;
    case PoseSource::kEye:
      return 1;
    case PoseSource::kIps:
      return 2;
    case PoseSource::kOdometry:
      return 3;
  }
  return 4;
}

const FleetRegistryParams& Validated(const FleetRegistryParams& params) {
  params.Validate();
  return params;
}

// Background vehicles are placed on lanes and movements simplified to within this (m).
constexpr double kCoarseTolerance_m = 0.001;

// Douglas-Peucker: the points of line[first..last] to keep so that no point left out is
// farther than `tolerance_m` from the simplified line; appends them after line[first].
void Simplify(const maps::Polyline& line, std::size_t first, std::size_t last, double tolerance_m,
              maps::Polyline& out) {
  const Eigen::Vector2d a = line[first];
  const Eigen::Vector2d ab = line[last] - a;
  const double length2 = ab.squaredNorm();
  double worst = -1.0;
  std::size_t worst_i = first;
  for (std::size_t i = first + 1; i < last; ++i) {
    const double t = length2 > 0 ? std::clamp((line[i] - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
    const double d = (a + t * ab - line[i]).norm();
    if (d > worst) {
      worst = d;
      worst_i = i;
    }
  }
  if (worst > tolerance_m) {
    Simplify(line, first, worst_i, tolerance_m, out);
    Simplify(line, worst_i, last, tolerance_m, out);
  } else {
    out.push_back(line[last]);
  }
}

maps::Polyline Simplified(const maps::Polyline& line, double tolerance_m) {
  if (line.size() < 3) return line;
  maps::Polyline out{line.front()};
  Simplify(line, 0, line.size() - 1, tolerance_m, out);
  return out;
}

}  // namespace

// The domain's values are the wire's: checked here, the one place that converts.
static_assert(static_cast<int>(PoseSource::kEye) ==
              autodrive_msgs_msg_TrackedVehicle_Constants_EYE);
static_assert(static_cast<int>(PoseSource::kSimGroundTruth) ==
              autodrive_msgs_msg_TrackedVehicle_Constants_SIM_GROUND_TRUTH);
static_assert(static_cast<int>(PoseSource::kOdometry) ==
              autodrive_msgs_msg_TrackedVehicle_Constants_ODOMETRY);
static_assert(static_cast<int>(PoseSource::kIps) ==
              autodrive_msgs_msg_TrackedVehicle_Constants_IPS);

std::uint8_t ToWire(PoseSource source) { return static_cast<std::uint8_t>(source); }

std::optional<PoseSource> PoseSourceFromWire(std::uint8_t value) {
  switch (value) {
    case autodrive_msgs_msg_TrackedVehicle_Constants_EYE:
      return PoseSource::kEye;
    case autodrive_msgs_msg_TrackedVehicle_Constants_SIM_GROUND_TRUTH:
      return PoseSource::kSimGroundTruth;
    case autodrive_msgs_msg_TrackedVehicle_Constants_ODOMETRY:
      return PoseSource::kOdometry;
    case autodrive_msgs_msg_TrackedVehicle_Constants_IPS:
      return PoseSource::kIps;
    default:
      return std::nullopt;
  }
}

std::string_view ToString(PoseSource source) {
  switch (source) {
    case PoseSource::kEye:
      return "eye";
    case PoseSource::kSimGroundTruth:
      return "sim_ground_truth";
    case PoseSource::kOdometry:
      return "odometry";
    case PoseSource::kIps:
      return "ips";
  }
  return "?";
}

void FleetRegistryParams::Validate() const {
  AUTODRIVE_THROW_UNLESS(staleness > Duration::zero(),
                         "staleness_s must be > 0, got " << ToSeconds(staleness));
  AUTODRIVE_THROW_UNLESS(std::isfinite(lane_margin_m) && lane_margin_m >= 0 && lane_margin_m <= 1,
                         "lane_margin_m must be in [0, 1], got " << lane_margin_m);
  AUTODRIVE_THROW_UNLESS(std::isfinite(max_heading_error_rad) && max_heading_error_rad >= 0 &&
                             max_heading_error_rad <= kPi,
                         "max_heading_error_rad must be in [0, pi], got " << max_heading_error_rad);
}

FleetRegistry::FleetRegistry(const maps::Map& map, FleetRegistryParams params)
    : map_(map), params_(Validated(params)), index_(map) {
  for (const auto& lane : map_.lanes) {
    const double reach = lane.width_m / 2 + params_.lane_margin_m;
    Eigen::AlignedBox2d box;
    for (const auto& p : lane.centreline) box.extend(p);
    box.min().array() -= reach;
    box.max().array() += reach;
    lane_boxes_.push_back(box);
    max_reach_m_ = std::max(max_reach_m_, reach);
  }
  box_of_tile_.assign(static_cast<std::size_t>(map_.rows * map_.cols), nullptr);
  for (const auto& x : map_.intersections) {
    box_of_tile_[static_cast<std::size_t>(x.tile.row * map_.cols + x.tile.col)] = &x;
  }
  places_.reserve(map_.lanes.size() + map_.movements.size());
  for (const auto& lane : map_.lanes) {
    Place p;
    p.line = Simplified(lane.centreline, kCoarseTolerance_m);
    p.length_m = maps::PolylineLength(p.line);
    p.lane = lane.id;
    if (lane.ingress_of && lane.ingress_approach) {
      p.intersection = lane.ingress_of;
      p.approach = *lane.ingress_approach;
    }
    places_.push_back(std::move(p));
  }
  for (const auto& mv : map_.movements) {
    Place p;
    p.line = Simplified(mv.path, kCoarseTolerance_m);
    p.length_m = maps::PolylineLength(p.line);
    p.lane = mv.from;
    p.intersection = mv.intersection;
    p.approach = mv.from_approach;
    p.movement = true;
    places_.push_back(std::move(p));
  }
  place_of_name_.reserve(places_.size());
  for (std::size_t i = 0; i < map_.lanes.size(); ++i) {
    place_of_name_.emplace(map_.lanes[i].name, static_cast<std::uint32_t>(i));
  }
  for (std::size_t i = 0; i < map_.movements.size(); ++i) {
    place_of_name_.emplace(map_.movements[i].name,
                           static_cast<std::uint32_t>(map_.lanes.size() + i));
  }
  lane_first_.assign(map_.lanes.size() + 1, 0);
  lane_fill_.assign(map_.lanes.size(), 0);
}

bool FleetRegistry::HeadingFits(double direction_rad, std::optional<double> yaw_rad) const {
  if (!yaw_rad) return true;
  const double error = std::abs(WrapAngle(*yaw_rad - direction_rad));
  return error <= params_.max_heading_error_rad;
}

const maps::Intersection* FleetRegistry::BoxAt(const Eigen::Vector2d& p) const {
  const double T = map_.tile_size_m;
  const double col = std::floor(p.x() / T);
  const double row_from_south = std::floor(p.y() / T);
  if (!(col >= 0 && col < map_.cols && row_from_south >= 0 && row_from_south < map_.rows)) {
    return nullptr;
  }
  const int row = map_.rows - 1 - static_cast<int>(row_from_south);
  const maps::Intersection* x =
      box_of_tile_[static_cast<std::size_t>(row * map_.cols + static_cast<int>(col))];
  if (x == nullptr) return nullptr;
  // Strictly inside (by more than rounding): a vehicle on the box's edge is still on its lane,
  // at the stop line.
  constexpr double kEdge = 1e-9;
  const Eigen::Vector2d d = (p - x->centre).cwiseAbs();
  return d.x() < T / 2 - kEdge && d.y() < T / 2 - kEdge ? x : nullptr;
}

std::optional<std::pair<LaneId, double>> FleetRegistry::NearestLane(
    const Eigen::Vector2d& p, std::optional<double> yaw_rad) const {
  const auto fits = [&](const maps::Lane& lane, const maps::PolylinePoint& q) {
    return q.distance_m <= lane.width_m / 2 + params_.lane_margin_m &&
           HeadingFits(q.direction_rad, yaw_rad);
  };
  // The common case: the nearest lane (CGAL's AABB tree) is the one.
  if (const auto m = index_.NearestLane(p, max_reach_m_)) {
    const maps::Lane& lane = map_.lane(m->lane);
    const maps::PolylinePoint q = maps::NearestOnPolyline(lane.centreline, p);
    if (fits(lane, q)) return std::pair{lane.id, q.along_m};
  } else {
    return std::nullopt;  // no lane within reach at all
  }
  // The nearest lane runs the other way (the car is near the road's centreline, or on the
  // opposing lane): look at every lane within reach for the nearest that fits.
  std::optional<std::pair<LaneId, double>> best;
  double best_distance_m = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < map_.lanes.size(); ++i) {
    if (!lane_boxes_[i].contains(p)) continue;
    const maps::Lane& lane = map_.lanes[i];
    const maps::PolylinePoint q = maps::NearestOnPolyline(lane.centreline, p);
    if (!fits(lane, q)) continue;
    if (q.distance_m < best_distance_m) {
      best = std::pair{lane.id, q.along_m};
      best_distance_m = q.distance_m;
    }
  }
  return best;
}

VehicleLocation FleetRegistry::Locate(const RigidTransform2& X_MV, bool heading_known) const {
  const Eigen::Vector2d& p = X_MV.translation();
  const std::optional<double> yaw =
      heading_known ? std::optional<double>(X_MV.yaw()) : std::nullopt;
  VehicleLocation loc;
  if (const maps::Intersection* x = BoxAt(p)) {
    loc.intersection = x->id;
    const maps::Movement* best = nullptr;
    maps::PolylinePoint best_q;
    for (const MovementId id : x->movements) {
      const maps::Movement& mv = map_.movement(id);
      const maps::PolylinePoint q = maps::NearestOnPolyline(mv.path, p);
      const double reach = map_.lane(mv.from).width_m / 2 + params_.lane_margin_m;
      if (q.distance_m > reach || !HeadingFits(q.direction_rad, yaw)) continue;
      if (best == nullptr || q.distance_m < best_q.distance_m) {
        best = &mv;
        best_q = q;
      }
    }
    if (best != nullptr) {
      loc.movement = best->id;
      loc.lane = best->from;
      loc.approach = best->from_approach;
      loc.distance_to_stop_line_m = -best_q.along_m;
    }
    return loc;
  }
  const auto match = NearestLane(p, yaw);
  if (!match) return loc;
  const maps::Lane& lane = map_.lane(match->first);
  loc.lane = lane.id;
  if (lane.ingress_of && lane.ingress_approach) {
    loc.intersection = lane.ingress_of;
    loc.approach = lane.ingress_approach;
    loc.distance_to_stop_line_m = lane.length_m - match->second;
  }
  return loc;
}

bool FleetRegistry::Observe(const VehicleObservation& o) {
  AUTODRIVE_THROW_UNLESS(o.source == PoseSource::kEye || o.source == PoseSource::kSimGroundTruth ||
                             o.source == PoseSource::kOdometry || o.source == PoseSource::kIps,
                         "an observation of " << VehicleName(o.vehicle) << " has an unknown source "
                                              << static_cast<int>(o.source)
                                              << " (expected 1 eye, 2 sim ground "
                                              << "truth, 3 odometry or 5 ips)");
  AUTODRIVE_THROW_UNLESS(std::isfinite(o.speed_mps), "an observation of " << VehicleName(o.vehicle)
                                                                          << " has speed "
                                                                          << o.speed_mps);
  for (std::size_t i = 0; i < o.pose_covariance.size(); ++i) {
    AUTODRIVE_THROW_UNLESS(std::isfinite(o.pose_covariance[i]),
                           "an observation of " << VehicleName(o.vehicle) << " has covariance[" << i
                                                << "] = " << o.pose_covariance[i]);
  }
  // Outside the lock: the map is const.
  Entry entry{o, Locate(o.X_MV.ToRigidTransform2(), o.heading_known)};
  std::lock_guard lock(mutex_);
  const auto key = std::pair{o.vehicle, o.source};
  const auto it = entries_.find(key);
  if (it != entries_.end()) {
    const Time stored = it->second.observation.observed;
    if (o.observed < stored && stored - o.observed <= params_.staleness) return false;
    it->second = std::move(entry);
  } else {
    entries_.emplace(key, std::move(entry));
  }
  return true;
}

bool FleetRegistry::Fresh(const VehicleObservation& o, Time now) const {
  return FreshAt(o.observed, now);
}

template <typename F>
void FleetRegistry::ForEachChosen(Time now, F&& f) const {
  // entries_ is ordered by (vehicle, source): one run per vehicle.
  for (auto it = entries_.begin(); it != entries_.end();) {
    const VehicleId vehicle = it->first.first;
    const Entry* best = nullptr;
    for (; it != entries_.end() && it->first.first == vehicle; ++it) {
      const Entry& e = it->second;
      if (!Fresh(e.observation, now)) continue;
      if (best == nullptr || Rank(e.observation.source) < Rank(best->observation.source)) {
        best = &e;
      }
    }
    if (best != nullptr) f(*best);
  }
}

std::vector<const FleetRegistry::Entry*> FleetRegistry::Chosen(Time now) const {
  std::vector<const Entry*> out;
  ForEachChosen(now, [&](const Entry& e) { out.push_back(&e); });
  return out;
}

std::vector<FleetVehicle> FleetRegistry::Vehicles(Time now) const {
  std::lock_guard lock(mutex_);
  std::vector<FleetVehicle> out;
  for (const Entry* e : Chosen(now)) out.push_back({e->observation, e->location});
  return out;
}

FleetStateMessage FleetRegistry::State(Time now) const {
  FleetStateMessage m;
  StateInto(now, m);
  return m;
}

void FleetRegistry::StateInto(Time now, FleetStateMessage& m) const {
  m->header.stamp = dds::ToMsg(now);
  dds::UpdateString(m->header.frame_id, "map");
  std::lock_guard lock(mutex_);
  std::uint32_t n = 0;
  ForEachChosen(now, [&](const Entry&) { ++n; });
  dds::SetLengthKeepingCapacity(m->vehicles, n);
  std::uint32_t i = 0;
  char name[32];
  ForEachChosen(now, [&](const Entry& e) {
    const VehicleObservation& o = e.observation;
    const VehicleLocation& loc = e.location;
    auto& v = dds::Elements(m->vehicles)[i++];
    const int len =
        std::snprintf(name, sizeof name, "nigel_%u", static_cast<unsigned>(o.vehicle.value()));
    dds::UpdateString(v.vehicle_id, std::string_view(name, static_cast<std::size_t>(len)));
    v.tag_id = o.tag ? o.tag->value() : 0;
    v.source = ToWire(o.source);
    v.observed = dds::ToMsg(o.observed);
    v.pose.pose = dds::ToMsg(o.X_MV);
    std::copy(o.pose_covariance.begin(), o.pose_covariance.end(), v.pose.covariance);
    v.twist.twist = msg::Twist{};
    v.twist.twist.linear.x = o.speed_mps;
    dds::UpdateString(v.map_lane_id, loc.lane ? std::string_view(map_.lane(*loc.lane).name) : "");
    v.intersection_id = loc.intersection ? loc.intersection->value() : 0;
    v.approach_id = loc.approach ? loc.approach->value() : 0;
    v.distance_to_stop_line_m = loc.distance_to_stop_line_m.value_or(0.0);
  });
}

bool FleetRegistry::Occupied(const DetectorZone& zone, Time now) const {
  AUTODRIVE_THROW_UNLESS(zone.lane.value() >= 1 && zone.lane.value() <= map_.lanes.size(),
                         "detector zone on " << zone.lane << ", which is not in map \"" << map_.name
                                             << "\" (it has " << map_.lanes.size() << " lanes)");
  const maps::Lane& lane = map_.lane(zone.lane);
  AUTODRIVE_THROW_UNLESS(lane.ingress_of.has_value(),
                         "detector zone on lane " << lane.name
                                                  << ", which is not an ingress lane of an "
                                                     "intersection (no stop line to measure from)");
  AUTODRIVE_THROW_UNLESS(
      std::isfinite(zone.from_stop_line_m) && std::isfinite(zone.to_stop_line_m) &&
          zone.from_stop_line_m <= zone.to_stop_line_m,
      "detector zone on lane " << lane.name << " has an empty range [" << zone.from_stop_line_m
                               << ", " << zone.to_stop_line_m << "] m");
  std::lock_guard lock(mutex_);
  bool occupied = false;
  ForEachChosen(now, [&](const Entry& e) {
    const VehicleLocation& loc = e.location;
    if (loc.lane != zone.lane || !loc.distance_to_stop_line_m) return;
    const double d = *loc.distance_to_stop_line_m;
    if (d >= zone.from_stop_line_m && d <= zone.to_stop_line_m) occupied = true;
  });
  if (occupied) return true;
  const std::size_t l = zone.lane.value();
  for (std::uint32_t i = lane_first_[l - 1]; i < lane_first_[l]; ++i) {
    const ZoneEntry& z = zone_entries_[i];
    if (z.nearest_m <= zone.to_stop_line_m && z.farthest_m >= zone.from_stop_line_m &&
        FreshAt(z.observed, now)) {
      return true;
    }
  }
  return false;
}

std::optional<std::uint32_t> FleetRegistry::FindPlace(std::string_view name) const {
  const auto it = place_of_name_.find(name);
  if (it == place_of_name_.end()) return std::nullopt;
  return it->second;
}

void FleetRegistry::PlaceBackground(const TrafficObservation& o, std::uint32_t place,
                                    Background& b) const {
  const Place& p = places_[place];
  b.place = place;
  b.half_length_m = o.length_m / 2;
  b.distance_to_stop_line_m = 0.0;
  if (!p.intersection) return;  // a lane that enters no intersection: no stop line
  const double along = maps::NearestOnPolyline(p.line, o.p_MC).along_m;
  b.distance_to_stop_line_m = p.movement ? -along : p.length_m - along;
}

TrafficUpdate FleetRegistry::ObserveTraffic(Time observed,
                                            std::span<const TrafficObservation> objects) {
  TrafficUpdate u;
  std::lock_guard lock(mutex_);
  for (const TrafficObservation& o : objects) {
    if (o.id.empty() || o.id.size() > kMaxTrafficIdBytes || !o.p_MC.allFinite() ||
        !std::isfinite(o.length_m) || o.length_m < 0) {
      ++u.refused;
      continue;
    }
    const auto it = background_.find(o.id);
    if (it == background_.end()) {
      const auto place = FindPlace(o.map_lane);
      if (!place) {
        ++u.elsewhere;
        continue;
      }
      if (background_.size() >= kMaxTrafficVehicles) {
        ++u.refused;
        continue;
      }
      Background& b = background_.emplace(std::string(o.id), Background{}).first->second;
      b.observed = observed;
      b.place_name = o.map_lane;
      PlaceBackground(o, *place, b);
      ++u.recorded;
      continue;
    }
    Background& b = it->second;
    if (observed < b.observed && b.observed - observed <= params_.staleness) {
      ++u.ignored;
      continue;
    }
    // Still on the same lane or movement (the common case): no lookup.
    std::optional<std::uint32_t> place = b.place;
    if (o.map_lane != b.place_name) {
      place = FindPlace(o.map_lane);
      if (!place) {
        // It left this map (or every lane): its newest observation says it is not here.
        background_.erase(it);
        ++u.elsewhere;
        continue;
      }
      b.place_name = o.map_lane;
    }
    b.observed = observed;
    PlaceBackground(o, *place, b);
    ++u.recorded;
  }
  u.dropped = DropStaleBackground(observed);
  IndexBackground();
  return u;
}

bool FleetRegistry::FreshAt(Time observed, Time now) const {
  const Duration age = now - observed;
  return age <= params_.staleness && -age <= params_.staleness;
}

std::size_t FleetRegistry::DropStaleBackground(Time now) {
  return std::erase_if(background_,
                       [&](const auto& kv) { return !FreshAt(kv.second.observed, now); });
}

void FleetRegistry::IndexBackground() {
  // A counting sort by lane: counts, then starts, then fill.
  std::fill(lane_first_.begin(), lane_first_.end(), 0);
  for (const auto& [id, b] : background_) {
    const Place& p = places_[b.place];
    if (p.intersection) ++lane_first_[p.lane.value()];
  }
  for (std::size_t l = 1; l < lane_first_.size(); ++l) lane_first_[l] += lane_first_[l - 1];
  zone_entries_.resize(lane_first_.back());
  std::copy(lane_first_.begin(), lane_first_.end() - 1, lane_fill_.begin());
  for (const auto& [id, b] : background_) {
    const Place& p = places_[b.place];
    if (!p.intersection) continue;
    zone_entries_[lane_fill_[p.lane.value() - 1]++] =
        ZoneEntry{b.distance_to_stop_line_m - b.half_length_m,
                  b.distance_to_stop_line_m + b.half_length_m, b.observed};
  }
}

std::size_t FleetRegistry::BackgroundVehicles(Time now) const {
  std::lock_guard lock(mutex_);
  return static_cast<std::size_t>(
      std::count_if(background_.begin(), background_.end(),
                    [&](const auto& kv) { return FreshAt(kv.second.observed, now); }));
}

std::vector<ApproachCount> FleetRegistry::ApproachCounts(IntersectionId x, Time now) const {
  std::vector<ApproachCount> out;
  if (x.value() < 1 || x.value() > map_.intersections.size()) return out;
  for (const auto& a : map_.intersection(x).approaches) out.push_back({a.id, 0, 0});
  const auto slot = [&](ApproachId a) -> ApproachCount* {
    for (auto& c : out) {
      if (c.approach == a) return &c;
    }
    return nullptr;
  };
  std::lock_guard lock(mutex_);
  ForEachChosen(now, [&](const Entry& e) {
    if (e.location.intersection != x || !e.location.approach) return;
    if (ApproachCount* c = slot(*e.location.approach)) ++c->lab;
  });
  for (const auto& [id, b] : background_) {
    const Place& p = places_[b.place];
    if (p.intersection != x || !FreshAt(b.observed, now)) continue;
    if (ApproachCount* c = slot(p.approach)) ++c->background;
  }
  return out;
}

std::size_t FleetRegistry::DropStale(Time now) {
  std::lock_guard lock(mutex_);
  const std::size_t lab =
      std::erase_if(entries_, [&](const auto& kv) { return !Fresh(kv.second.observation, now); });
  const std::size_t background = DropStaleBackground(now);
  if (background > 0) IndexBackground();
  return lab + background;
}

}  // namespace autodrive::scm
