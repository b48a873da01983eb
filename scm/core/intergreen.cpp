#include "scm/core/intergreen.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>

#include "maps/polyline.h"

namespace autodrive::scm {

namespace {

/// Rounded up to 0.1 s (a tenth, as NTCIP times clearances), with a little slack for the
/// arithmetic.
double UpToTenth(double seconds) { return std::ceil(seconds * 10.0 - 1e-6) / 10.0; }

/// Whether the point `along` metres along `path` is within `reach` of `other`.
bool Near(const maps::Polyline& path, double along, const maps::Polyline& other, double reach) {
  return maps::NearestOnPolyline(other, maps::PointAlong(path, along).first).distance_m <= reach;
}

/// The edge between `outside` and `inside` (arc lengths along `path`), to a millimetre.
double Edge(const maps::Polyline& path, double outside, double inside, const maps::Polyline& other,
            double reach) {
  while (std::abs(inside - outside) > 1e-3) {
    const double mid = (inside + outside) / 2.0;
    (Near(path, mid, other, reach) ? inside : outside) = mid;
  }
  return inside;
}

/// The first and last arc length along `path` within `reach` of `other`, or nothing when the
/// paths do not come that close. Steps of `step` metres, then bisection.
std::optional<std::pair<double, double>> Zone(const maps::Polyline& path,
                                              const maps::Polyline& other, double reach,
                                              double step) {
  const double length = maps::PolylineLength(path);
  std::optional<double> first, last;
  double previous = 0.0;
  bool previous_near = false;
  for (double s = 0.0;; s = std::min(length, s + step)) {
    const bool near = Near(path, s, other, reach);
    if (near && !first) first = s == 0.0 ? 0.0 : Edge(path, previous, s, other, reach);
    if (!near && previous_near) last = Edge(path, s, previous, other, reach);
    previous = s;
    previous_near = near;
    if (s >= length) break;
  }
  if (!first) return std::nullopt;
  if (!last) last = length;  // the paths merge: the zone runs to the box's edge
  return std::make_pair(*first, *last);
}

}  // namespace

/// Where two paths conflict: how far the clearing one runs to the far edge of the zone and the
/// entering one to its near edge.
struct IntergreenCache::Zones {
  bool meet = false;
  double clear_far = 0.0;
  double enter_near = 0.0;
};

namespace {

IntergreenCache::Zones ComputeZones(const maps::Map& map, const maps::Movement& clearing,
                                    const maps::Movement& entering) {
  // Each vehicle kept in its lane: two paths conflict where their centrelines are less than
  // half a lane width apart.
  // Paths the map finds in conflict that never come that close (a merge at an angle) meet
  // within the map's vehicle clearance.
  const double step = std::max(map.options.sample_step_m / 2.0, 0.005);
  for (const double reach : {map.lane_width_m / 2.0, map.options.vehicle_clearance_m}) {
    const auto clear_zone = Zone(clearing.path, entering.path, reach, step);
    const auto enter_zone = Zone(entering.path, clearing.path, reach, step);
    if (clear_zone && enter_zone) return {true, clear_zone->second, enter_zone->first};
  }
  return {};
}

IntergreenEntry Entry(const maps::Movement& clearing, MovementId clearing_id,
                      MovementId entering_id, const IntergreenCache::Zones& zones,
                      const ClearingVehicleConfig& vehicle, const IntergreenInputs& inputs);

}  // namespace

/// The shape of a pair of paths: every point of both, relative to the clearing path's first
/// point, in micrometres (so that equal shapes at other places of the map compare equal).
struct IntergreenCache::Table {
  std::map<std::vector<std::int64_t>, Zones> zones;
};

IntergreenCache::IntergreenCache() : table_(std::make_unique<Table>()) {}
IntergreenCache::~IntergreenCache() = default;

const IntergreenCache::Zones& IntergreenCache::Get(const maps::Map& map,
                                                   const maps::Movement& clearing,
                                                   const maps::Movement& entering) {
  std::vector<std::int64_t> key;
  key.reserve(2 * (clearing.path.size() + entering.path.size()) + 2);
  const Eigen::Vector2d origin =
      clearing.path.empty() ? Eigen::Vector2d::Zero() : clearing.path.front();
  for (const auto* path : {&clearing.path, &entering.path}) {
    key.push_back(static_cast<std::int64_t>(path->size()));
    for (const auto& p : *path) {
      key.push_back(std::llround((p.x() - origin.x()) * 1e6));
      key.push_back(std::llround((p.y() - origin.y()) * 1e6));
    }
  }
  auto it = table_->zones.find(key);
  if (it == table_->zones.end()) {
    it = table_->zones.emplace(std::move(key), ComputeZones(map, clearing, entering)).first;
  }
  return it->second;
}

IntergreenEntry MovementIntergreen(const maps::Map& map, MovementId clearing_id,
                                   MovementId entering_id, const ClearingVehicleConfig& vehicle,
                                   const IntergreenInputs& inputs) {
  const maps::Movement& clearing = map.movement(clearing_id);
  return Entry(clearing, clearing_id, entering_id,
               ComputeZones(map, clearing, map.movement(entering_id)), vehicle, inputs);
}

namespace {

IntergreenEntry Entry(const maps::Movement& clearing, MovementId clearing_id,
                      MovementId entering_id, const IntergreenCache::Zones& zones,
                      const ClearingVehicleConfig& vehicle, const IntergreenInputs& inputs) {
  const bool meet = zones.meet;
  const double clear_far = zones.clear_far, enter_near = zones.enter_near;
  IntergreenEntry e;
  e.clearing_movement = clearing_id;
  e.entering_movement = entering_id;
  e.vehicle = vehicle.name;
  e.vehicle_length_m = vehicle.length_m;
  e.clearing_speed_mps = vehicle.speed_mps;
  e.crossing_time_s = inputs.crossing_time_s;
  e.ite_s = UpToTenth((clearing.length_m + vehicle.length_m) / vehicle.speed_mps);
  if (!meet) {
    e.intergreen_s = e.ite_s;
    return e;
  }
  e.clearing_path_m = clear_far;
  e.entering_path_m = enter_near;
  e.clearing_time_s = (e.clearing_path_m + vehicle.length_m) / vehicle.speed_mps;
  e.entering_time_s = e.entering_path_m / inputs.entering_speed_mps;
  e.intergreen_s =
      UpToTenth(std::max(0.0, e.crossing_time_s + e.clearing_time_s - e.entering_time_s));
  return e;
}

}  // namespace

std::vector<std::vector<std::optional<IntergreenEntry>>> ComputeIntergreens(
    const maps::Map& map, const IntersectionModel& x, const IntergreenInputs& inputs,
    IntergreenCache* cache) {
  const std::size_t n = x.groups.size();
  std::vector<std::vector<std::optional<IntergreenEntry>>> out(
      n, std::vector<std::optional<IntergreenEntry>>(n));
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t b = 0; b < n; ++b) {
      if (a == b || !x.conflicts[a][b]) continue;
      std::optional<IntergreenEntry>& worst = out[a][b];
      const auto keep = [&](IntergreenEntry e) {
        e.clearing = a;
        e.entering = b;
        if (!worst || e.intergreen_s > worst->intergreen_s ||
            (e.intergreen_s == worst->intergreen_s && e.ite_s > worst->ite_s)) {
          worst = std::move(e);
        }
      };
      for (const MovementId ma : x.groups[a].movements) {
        for (const MovementId mb : x.groups[b].movements) {
          if (!map.Conflict(ma, mb)) continue;
          const maps::Movement& clearing = map.movement(ma);
          const maps::Movement& entering = map.movement(mb);
          const IntergreenCache::Zones zones = cache != nullptr
                                                   ? cache->Get(map, clearing, entering)
                                                   : ComputeZones(map, clearing, entering);
          for (const ClearingVehicleConfig& v : inputs.clearing_vehicles) {
            keep(Entry(clearing, ma, mb, zones, v, inputs));
          }
        }
      }
      if (worst) continue;
      // A conflict by configuration only (no two of the groups' movements meet on the map):
      // the clearing group's ITE figure, its whole path cleared.
      for (const MovementId ma : x.groups[a].movements) {
        for (const ClearingVehicleConfig& v : inputs.clearing_vehicles) {
          IntergreenEntry e;
          e.clearing_movement = ma;
          e.vehicle = v.name;
          e.vehicle_length_m = v.length_m;
          e.clearing_speed_mps = v.speed_mps;
          e.crossing_time_s = inputs.crossing_time_s;
          e.ite_s = UpToTenth((map.movement(ma).length_m + v.length_m) / v.speed_mps);
          e.intergreen_s = e.ite_s;
          keep(std::move(e));
        }
      }
    }
  }
  return out;
}

}  // namespace autodrive::scm
