#include "traffic/all_way_stops.h"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace autodrive::traffic {

class AllWayStops::Room {
 public:
  explicit Room(SumoCache& sumo) : sumo_(sumo) {}
  // What is left at the start of `lane`.
  double& Of(const std::string& lane) {
    auto it = room_.find(lane);
    if (it == room_.end()) it = room_.emplace(lane, sumo_.LaneLength(lane)).first;
    return it->second;
  }
  void Take(const std::string& lane, double length) { Of(lane) -= length; }

 private:
  SumoCache& sumo_;
  std::unordered_map<std::string, double> room_;
};

AllWayStops::AllWayStops(const LightBinding& lights, const LinkIndex& links, double scale,
                         double min_gap)
    : lights_(&lights), links_(&links), scale_(scale), min_gap_(min_gap) {
  const std::size_t n = lights.lights().size();
  running_.assign(n, false);
  occupied_.resize(n);
  for (std::size_t i = 0; i < n; ++i) occupied_[i].assign(lights.lights()[i].heads.size(), false);
  grants_.resize(n);
}

void AllWayStops::SetRunning(std::size_t light, bool running) {
  if (running == running_[light]) return;
  running_[light] = running;
  if (running) {
    ++running_count_;
  } else {
    --running_count_;
  }
}

bool AllWayStops::Near(const LaneInfo& info) const {
  return running_count_ != 0 && std::any_of(info.lights.begin(), info.lights.end(),
                                            [&](std::size_t l) { return running_[l]; });
}

bool AllWayStops::Granted(std::size_t light, const std::string& vehicle) const {
  const auto& grants = grants_[light];
  return std::any_of(grants.begin(), grants.end(),
                     [&](const Grant& g) { return g.vehicle == vehicle; });
}

void AllWayStops::Arbitrate(SumoTime now, const std::vector<SumoVehicleState>& vehicles,
                            const std::unordered_set<std::string>& lab_ids, const Lights& lights,
                            LaneLookup& lanes, SumoCache& sumo) {
  for (std::size_t i = 0; i < running_.size(); ++i) {
    if (!running_[i]) grants_[i].clear();
  }
  if (running_count_ == 0) {  // no light runs an all-way stop: nothing to arbitrate
    standing_since_.clear();
    return;
  }
  Room room(sumo);
  Survey(now, vehicles, lab_ids, lanes, sumo, room);
  const std::vector<std::string> lapsed = EndGrants(now);
  for (Waiting& w : waiting_) {
    if (std::find(lapsed.begin(), lapsed.end(), w.vehicle) == lapsed.end()) continue;
    w.since = now;
    standing_since_[w.vehicle] = now;
  }
  for (std::size_t i = 0; i < grants_.size(); ++i) {
    for (const Grant& g : grants_[i]) room.Take(links_->exit_of_link[i][g.link], g.room);
  }
  std::sort(waiting_.begin(), waiting_.end(), [](const Waiting& a, const Waiting& b) {
    return a.since != b.since ? a.since < b.since : a.vehicle < b.vehicle;
  });
  LetThrough(now, lights, sumo, room);
}

void AllWayStops::Survey(SumoTime now, const std::vector<SumoVehicleState>& vehicles,
                         const std::unordered_set<std::string>& lab_ids, LaneLookup& lanes,
                         SumoCache& sumo, Room& room) {
  // Occupied links (a vehicle on their internal lanes) and vehicles standing at a line, of the
  // lights that run an all-way stop (only theirs are read).
  for (std::size_t i = 0; i < occupied_.size(); ++i) {
    if (running_[i]) std::fill(occupied_[i].begin(), occupied_[i].end(), false);
  }
  waiting_.clear();
  lane_of_.clear();
  for (const SumoVehicleState& v : vehicles) {
    // Only the vehicles about the all-way stops running now (and the lab's cars) matter.
    const bool lab = !lab_ids.empty() && lab_ids.count(v.id) != 0;
    if (!lab && !Near(lanes.Of(v.lane))) {
      standing_since_.erase(v.id);
      continue;
    }
    lane_of_.emplace(v.id, v.lane);
    const double length = sumo.TypeSize(v.type).length;
    if (const auto it = links_->link_of_lane.find(v.lane); it != links_->link_of_lane.end()) {
      occupied_[it->second.first][it->second.second] = true;
      room.Take(links_->exit_of_link[it->second.first][it->second.second], length + min_gap_);
      continue;
    }
    if (!v.lane.empty() && v.lane.front() != ':') {
      double& r = room.Of(v.lane);
      r = std::min(r, v.lane_pos - length - min_gap_);
    }
    // A lab car goes whenever its driver decides: what SUMO's vehicles must not start
    // meanwhile is held (`Lights::held`).
    if (lab) continue;
    const auto lane = links_->stop_lanes.find(v.lane);
    const bool at_line = lane != links_->stop_lanes.end() && v.speed_mps < 0.01 * scale_ &&
                         v.lane_pos > lane->second.length - 0.1 * scale_;
    if (!at_line) {
      standing_since_.erase(v.id);
      continue;
    }
    const auto since = standing_since_.try_emplace(v.id, now).first;
    if (running_[lane->second.light]) {
      waiting_.push_back(Waiting{since->second, v.id, &lane->second, v.type});
    }
  }
}

std::vector<std::string> AllWayStops::EndGrants(SumoTime now) {
  // Grants end once the vehicle is in the junction (or gone), or when it did not take its
  // turn within a few seconds (blocked by a vehicle SUMO put in the box: the next one goes).
  std::vector<std::string> lapsed;
  for (std::size_t i = 0; i < grants_.size(); ++i) {
    std::erase_if(grants_[i], [&](const Grant& g) {
      const auto it = lane_of_.find(g.vehicle);
      if (it == lane_of_.end() || links_->stop_lanes.count(it->second) == 0) return true;
      // It did not go (SUMO saw no way through): it goes to the back of the queue, and the
      // others may go first (granted again at once, it would hold the intersection for good).
      if (now - g.since <= kGrant) return false;
      lapsed.push_back(g.vehicle);
      ++lapsed_count_;
      spdlog::debug("traffic: {} did not take its turn at {} in {:.0f} s", g.vehicle,
                    lights_->lights()[i].tls, ToSeconds(kGrant));
      return true;
    });
  }
  return lapsed;
}

void AllWayStops::LetThrough(SumoTime now, const Lights& lights, SumoCache& sumo, Room& room) {
  for (const Waiting& w : waiting_) {
    if (now - w.since < kStand) continue;
    const std::size_t light = w.lane->light;
    auto& grants = grants_[light];
    if (Granted(light, w.vehicle)) continue;
    // Its movement: the link to the next edge of its route.
    const int route_index = sumo.api().RouteIndex(w.vehicle);
    const std::vector<std::string> route = sumo.api().Route(w.vehicle);
    const auto next = static_cast<std::size_t>(route_index) + 1;
    if (route_index < 0 || next >= route.size()) continue;
    const auto link = std::find_if(w.lane->links.begin(), w.lane->links.end(),
                                   [&](const auto& l) { return l.edge == route[next]; });
    if (link == w.lane->links.end()) continue;
    const std::size_t k = link->index;
    if (lights.held[light][k]) continue;  // a lab car is on its way
    // Only into a lane with room for it: a vehicle waiting in the box for room would hold up
    // every movement it conflicts with (and a grid of all-way stops would lock up).
    const double length = sumo.TypeSize(w.type).length;
    double& room_left = room.Of(link->lane);
    if (room_left < length + min_gap_) continue;
    if (lights.aspects[light][k] != 's') continue;
    const auto& foes = lights_->lights()[light].foes[k];
    const bool clear = std::none_of(foes.begin(), foes.end(), [&](std::size_t f) {
      return occupied_[light][f] ||
             std::any_of(grants.begin(), grants.end(), [&](const Grant& g) { return g.link == f; });
    });
    if (!clear) continue;
    grants.push_back(Grant{w.vehicle, k, now, length + min_gap_});
    spdlog::debug("traffic: {:.2f} s: {} may go at {} (link {})", ToSeconds(now), w.vehicle,
                  lights_->lights()[light].tls, k);
    room_left -= length + min_gap_;
    ++granted_count_;
  }
}

}  // namespace autodrive::traffic
