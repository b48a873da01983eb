#include "traffic/demand.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "common/error.h"

namespace autodrive::traffic {

Demand::Demand(const TrafficConfig& config, const TrafficNetwork& network)
    : network_(&network), mix_(config.mix), vehicles_(config.vehicles), rng_(config.seed) {
  for (const TypeShare& t : mix_) {
    AUTODRIVE_THROW_UNLESS(!t.type.empty(), "traffic.mix: a type without a name");
  }
  for (const FlowConfig& f : config.flows) {
    Flow flow{f, network.EdgeOfLane(f.from), "", 0};
    if (!f.to.empty()) {
      flow.to_edge = network.EdgeOfLane(f.to);
      AUTODRIVE_THROW_UNLESS(!network.Route(flow.from_edge, flow.to_edge).empty(),
                             "traffic.flows: no route from " << f.from << " to " << f.to);
    }
    flows_.push_back(std::move(flow));
  }
}

const std::string& Demand::PickType() {
  double total = 0;
  for (const TypeShare& t : mix_) total += t.weight;
  if (total <= 0) return mix_.front().type;
  double r = std::uniform_real_distribution<double>(0.0, total)(rng_);
  for (const TypeShare& t : mix_) {
    if (r < t.weight) return t.type;
    r -= t.weight;
  }
  return mix_.back().type;
}

Departure Demand::Depart(std::string id, std::string type, std::vector<std::string> route,
                         bool circulating, std::string depart_pos) {
  if (circulating) circulating_[id] = route.size();
  return Departure{std::move(id), std::move(type), std::move(route), std::move(depart_pos)};
}

std::vector<Departure> Demand::RandomVehicles(
    const std::vector<std::tuple<std::string, double, double>>& occupied, SumoCache& sumo) {
  const double gap = network_->scale() * 0.05;
  const std::vector<Placement> placed = network_->PlaceVehicles(
      vehicles_, kWalkEdges, gap, rng_, [this]() -> const std::string& { return PickType(); },
      [&](const std::string& type) { return sumo.TypeSize(type).length; }, occupied);
  if (placed.size() < static_cast<std::size_t>(vehicles_)) {
    spdlog::warn("traffic: room for {} of the {} vehicles only", placed.size(), vehicles_);
  }
  std::vector<Departure> out;
  for (const Placement& p : placed) {
    out.push_back(Depart("bg_" + std::to_string(next_id_++), p.type, p.route, true,
                         fmt::format("{:.3f}", p.pos)));
  }
  return out;
}

std::vector<Departure> Demand::DueFlows(SumoTime now) {
  // The flows' periods are seconds a vehicle (3600 / per_hour), not whole nanoseconds: the due
  // times are compared in seconds, as they always were.
  const double now_s = ToSeconds(now);
  std::vector<Departure> out;
  for (std::size_t i = 0; i < flows_.size(); ++i) {
    Flow& f = flows_[i];
    const double period = 3600.0 / f.config.per_hour;
    while ((f.config.count == 0 || f.sent < f.config.count) &&
           autodrive::ToSeconds(f.config.begin_s) + f.sent * period <= now_s + 1e-9) {
      const bool circulating = f.to_edge.empty();
      std::vector<std::string> route = circulating ? std::vector<std::string>{f.from_edge}
                                                   : network_->Route(f.from_edge, f.to_edge);
      if (circulating) {
        for (std::string& e : network_->RandomWalk(f.from_edge, kWalkEdges, rng_)) {
          route.push_back(std::move(e));
        }
      }
      out.push_back(Depart("flow" + std::to_string(i) + "_" + std::to_string(f.sent), f.config.type,
                           std::move(route), circulating, "base"));
      ++f.sent;
    }
  }
  return out;
}

void Demand::ExtendRoutes(std::int64_t step, std::vector<SumoVehicleState>& vehicles,
                          SumoApi& api) {
  // Routes hold four edges ahead at least when extended: checking twice a second is enough.
  if (step % 10 != 0) return;
  for (SumoVehicleState& v : vehicles) {
    const auto it = circulating_.find(v.id);
    if (it == circulating_.end()) continue;
    // Inside a junction SUMO's route index still names the edge before it: extend once the
    // vehicle is on an edge again.
    if (!v.lane.empty() && v.lane.front() == ':') continue;
    v.route_index = api.RouteIndex(v.id);
    std::size_t& length = it->second;
    const auto index = static_cast<std::size_t>(std::max(0, v.route_index));
    if (length > index + kExtendAt) continue;
    // SUMO's own route (it is the truth; a replacement restarts its index).
    const std::vector<std::string> route = api.Route(v.id);
    if (index >= route.size()) continue;
    std::vector<std::string> ahead(route.begin() + static_cast<std::ptrdiff_t>(index), route.end());
    const std::size_t before = ahead.size();
    for (std::string& e : network_->RandomWalk(ahead.back(), kWalkEdges, rng_)) {
      ahead.push_back(std::move(e));
    }
    if (ahead.size() == before) continue;  // a road out of the map: it will arrive there
    api.SetRoute(v.id, ahead);
    length = ahead.size();
    ++route_extensions_;
  }
}

void Demand::RerouteBlocked(std::int64_t step, SumoTime now,
                            const std::vector<SumoVehicleState>& vehicles, const LinkIndex& links,
                            const AllWayStops& stops, SumoCache& sumo) {
  // Once a second: a wait of seconds needs no finer look, and the look costs a lookup by name
  // per vehicle.
  if (step % 20 != 0) return;
  const double s = network_->scale();
  const double gap = network_->files().scale * 0.05;
  // Circulating vehicles standing on a lane into an intersection, and since when.
  std::unordered_map<std::string, SumoTime> blocked;
  std::vector<const SumoVehicleState*> waited;  // long enough
  for (const SumoVehicleState& v : vehicles) {
    if (v.speed_mps > 0.01 * s || links.stop_lanes.count(v.lane) == 0 ||
        circulating_.count(v.id) == 0) {
      continue;
    }
    const SumoTime since = blocked_since_.try_emplace(v.id, now).first->second;
    blocked.emplace(v.id, since);
    if (now - since >= kBlocked) waited.push_back(&v);
  }
  blocked_since_ = std::move(blocked);
  if (waited.empty()) return;
  // What the vehicles take of each lane: those on it, and those in a junction on their way in.
  std::unordered_map<std::string, double> taken;
  for (const SumoVehicleState& v : vehicles) {
    const double length = sumo.TypeSize(v.type).length + gap;
    if (const auto link = links.link_of_lane.find(v.lane); link != links.link_of_lane.end()) {
      taken[links.exit_of_link[link->second.first][link->second.second]] += length;
    } else {
      taken[v.lane] += length;
    }
  }
  const auto room = [&](const std::string& lane) {
    const auto it = taken.find(lane);
    return sumo.LaneLength(lane) - (it == taken.end() ? 0.0 : it->second);
  };
  SumoApi& api = sumo.api();
  for (const SumoVehicleState* v : waited) {
    const LinkIndex::StopLane& lane = links.stop_lanes.at(v->lane);
    if (stops.Granted(lane.light, v->id)) continue;
    const double length = sumo.TypeSize(v->type).length + gap;
    // Only a lane with a full exit can hold a vehicle up (most stand at a red light): its
    // route, a call each, is read only then.
    if (std::all_of(lane.links.begin(), lane.links.end(),
                    [&](const LinkIndex::StopLane::Link& l) { return room(l.lane) >= length; })) {
      continue;
    }
    const Duration waited_for = now - blocked_since_.at(v->id);
    if (api.LanePosition(v->id) < lane.length - 0.1 * s) continue;  // not the first
    const std::vector<std::string> route = api.Route(v->id);
    const int index = api.RouteIndex(v->id);
    const auto next = static_cast<std::size_t>(index) + 1;
    if (index < 0 || next >= route.size()) continue;
    const auto current = std::find_if(lane.links.begin(), lane.links.end(),
                                      [&](const auto& l) { return l.edge == route[next]; });
    if (current == lane.links.end() || room(current->lane) >= length) continue;
    std::vector<const LinkIndex::StopLane::Link*> open;
    for (const LinkIndex::StopLane::Link& l : lane.links) {
      if (&l != &*current && network_->Circulates(l.edge) && room(l.lane) >= length) {
        open.push_back(&l);
      }
    }
    if (open.empty()) continue;
    const LinkIndex::StopLane::Link& to =
        *open[std::uniform_int_distribution<std::size_t>(0, open.size() - 1)(rng_)];
    std::vector<std::string> ahead{route[static_cast<std::size_t>(index)], to.edge};
    for (std::string& e : network_->RandomWalk(to.edge, kWalkEdges, rng_)) {
      ahead.push_back(std::move(e));
    }
    api.SetRoute(v->id, ahead);
    circulating_[v->id] = ahead.size();
    taken[to.lane] += length;
    blocked_since_.erase(v->id);
    ++reroutes_;
    spdlog::debug("traffic: {} waited {:.0f} s for {} (full): turns to {} instead", v->id,
                  autodrive::ToSeconds(waited_for), current->edge, to.edge);
  }
}

}  // namespace autodrive::traffic
