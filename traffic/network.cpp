#include "traffic/network.h"

#include <algorithm>
#include <deque>
#include <map>
#include <set>

#include "traffic/sumo_api.h"

#include "common/error.h"

namespace autodrive::traffic {

namespace {

maps::SumoExport Export(const maps::Map& map, const std::filesystem::path& dir, double speed_mps,
                        std::map<IntersectionId, maps::SumoSignalProgram> programs) {
  maps::SumoOptions options;
  options.speed_mps = speed_mps;
  options.programs = std::move(programs);
  return maps::ExportSumo(map, dir.string(), options);
}

}  // namespace

TrafficNetwork::TrafficNetwork(const maps::Map& map, const std::filesystem::path& dir,
                               double speed_mps,
                               std::map<IntersectionId, maps::SumoSignalProgram> programs)
    : map_(map), export_(Export(map, dir, speed_mps, std::move(programs))) {
  std::map<std::string, std::set<std::string>> next;
  std::map<std::string, std::pair<double, int>> length;  // sum, count
  for (const maps::Lane& lane : map.lanes) {
    const auto& pieces = export_.lane_pieces.at(lane.id);
    edge_of_lane_.emplace(lane.name, pieces.front().edge);
    for (std::size_t i = 0; i < pieces.size(); ++i) {
      map_name_.emplace(pieces[i].id(), lane.name);
      next[pieces[i].edge];  // every edge has an entry
      auto& [sum, n] = length[pieces[i].edge];
      sum += lane.length_m / static_cast<double>(pieces.size());
      ++n;
      if (i + 1 < pieces.size()) next[pieces[i].edge].insert(pieces[i + 1].edge);
    }
    const std::string& last = pieces.back().edge;
    for (const LaneId s : lane.successors) next[last].insert(export_.lane(s).edge);
    for (const MovementId m : lane.movements_out) {
      next[last].insert(export_.movement(m).to.edge);
    }
  }
  // Edges from which a vehicle can drive on for ever (not only into a road out of the map):
  // repeatedly drop edges whose every next edge was dropped.
  std::set<std::string> alive;
  for (const auto& [edge, following] : next) alive.insert(edge);
  for (bool changed = true; changed;) {
    changed = false;
    for (auto it = alive.begin(); it != alive.end();) {
      const auto& following = next.at(*it);
      const bool on = std::any_of(following.begin(), following.end(),
                                  [&](const std::string& e) { return alive.count(e) != 0; });
      if (on) {
        ++it;
      } else {
        it = alive.erase(it);
        changed = true;
      }
    }
  }
  alive_.insert(alive.begin(), alive.end());
  for (auto& [edge, following] : next) {
    edges_.push_back(edge);
    next_.emplace(edge, std::vector<std::string>(following.begin(), following.end()));
    const auto& [sum, n] = length.at(edge);
    length_.emplace(edge, sum / n);
  }
}

const std::vector<std::string>& TrafficNetwork::NextEdges(const std::string& edge) const {
  const auto it = next_.find(edge);
  AUTODRIVE_THROW_UNLESS(it != next_.end(), "no SUMO edge \"" << edge << "\" in the network");
  return it->second;
}

bool TrafficNetwork::Circulates(const std::string& edge) const { return alive_.count(edge) != 0; }

double TrafficNetwork::EdgeLength(const std::string& edge) const {
  const auto it = length_.find(edge);
  AUTODRIVE_THROW_UNLESS(it != length_.end(), "no SUMO edge \"" << edge << "\" in the network");
  return it->second;
}

const std::string& TrafficNetwork::EdgeOfLane(const std::string& map_lane_name) const {
  const auto it = edge_of_lane_.find(map_lane_name);
  AUTODRIVE_THROW_UNLESS(it != edge_of_lane_.end(),
                         "the map \"" << map_.name << "\" has no lane \"" << map_lane_name
                                      << "\" (lane names are tile:from>to:index, as "
                                         "autodrive-map info prints them)");
  return it->second;
}

const std::string& TrafficNetwork::MapName(const std::string& sumo_lane) const {
  static const std::string kNone;
  const auto it = map_name_.find(sumo_lane);
  return it == map_name_.end() ? kNone : it->second;
}

std::vector<std::string> TrafficNetwork::RandomWalk(const std::string& from, std::size_t edges,
                                                    std::mt19937_64& rng) const {
  std::vector<std::string> out;
  const std::string* e = &from;
  std::vector<const std::string*> choice;
  for (std::size_t i = 0; i < edges; ++i) {
    const auto& next = NextEdges(*e);
    if (next.empty()) break;
    // Roads out of the map only when there is nothing else.
    choice.clear();
    for (const std::string& n : next) {
      if (alive_.count(n) != 0) choice.push_back(&n);
    }
    if (choice.empty()) {
      for (const std::string& n : next) choice.push_back(&n);
    }
    e = choice[std::uniform_int_distribution<std::size_t>(0, choice.size() - 1)(rng)];
    out.push_back(*e);
  }
  return out;
}

std::vector<std::string> TrafficNetwork::Route(const std::string& from,
                                               const std::string& to) const {
  // Breadth-first over the lane graph.
  std::unordered_map<std::string, std::string> parent{{from, ""}};
  std::deque<std::string> queue{from};
  while (!queue.empty()) {
    const std::string e = queue.front();
    queue.pop_front();
    if (e == to) {
      std::vector<std::string> path;
      for (std::string at = to; !at.empty(); at = parent.at(at)) path.push_back(at);
      std::reverse(path.begin(), path.end());
      return path;
    }
    for (const std::string& n : NextEdges(e)) {
      if (parent.emplace(n, e).second) queue.push_back(n);
    }
  }
  return {};
}

const std::vector<std::string>& TrafficNetwork::InternalLanes(MovementId m) const {
  static const std::vector<std::string> kNone;
  const auto it = internal_lanes_.find(m);
  return it == internal_lanes_.end() ? kNone : it->second;
}

std::vector<Placement> TrafficNetwork::PlaceVehicles(
    int n, std::size_t walk, double gap, std::mt19937_64& rng,
    const std::function<const std::string&()>& pick_type,
    const std::function<double(const std::string&)>& length_of,
    const std::vector<std::tuple<std::string, double, double>>& occupied) const {
  std::vector<std::string> starts;
  std::vector<double> weights;
  for (const std::string& e : edges_) {
    if (!Circulates(e)) continue;
    starts.push_back(e);
    weights.push_back(EdgeLength(e));
  }
  std::vector<Placement> out;
  if (starts.empty()) return out;
  std::discrete_distribution<std::size_t> pick(weights.begin(), weights.end());
  std::unordered_map<std::string, std::vector<std::pair<double, double>>> taken;  // [back, front]
  for (const auto& [edge, back, front] : occupied) taken[edge].emplace_back(back, front);
  const double s = scale();
  for (int k = 0; k < n; ++k) {
    const std::string& type = pick_type();
    const double length = length_of(type);
    for (int attempt = 0; attempt < 100; ++attempt) {
      const std::string& edge = starts[pick(rng)];
      const double edge_length = EdgeLength(edge) * s;
      // Clear of the junctions at both ends by a gap.
      const double lo = length + gap, hi = edge_length - gap;
      if (hi < lo) continue;
      const double front = std::uniform_real_distribution<double>(lo, hi)(rng);
      auto& here = taken[edge];
      const bool clear = std::none_of(here.begin(), here.end(), [&](const auto& t) {
        return front - length < t.second + gap && t.first < front + gap;
      });
      if (!clear) continue;
      here.emplace_back(front - length, front);
      Placement p;
      p.route = {edge};
      for (std::string& e : RandomWalk(edge, walk, rng)) p.route.push_back(std::move(e));
      p.pos = front;
      p.type = type;
      out.push_back(std::move(p));
      break;
    }
  }
  return out;
}

void TrafficNetwork::LearnInternalLanes(SumoApi& api) {
  for (const maps::Movement& m : map_.movements) {
    const maps::SumoMovement& sm = export_.movement(m.id);
    for (const auto& [to, via] : api.Links(sm.from.id())) {
      if (to != sm.to.id()) continue;
      // A link's internal lanes: one, or two when SUMO puts a waiting point on it.
      std::string lane = via;
      for (int i = 0; i < 8 && !lane.empty() && lane.front() == ':'; ++i) {
        map_name_.emplace(lane, m.name);
        internal_lanes_[m.id].push_back(lane);
        lane = api.NextLane(lane);
      }
    }
  }
}

}  // namespace autodrive::traffic
