#include "traffic/links.h"

#include <algorithm>

#include "maps/map.h"

namespace autodrive::traffic {

LinkIndex IndexLinks(const LightBinding& lights, const TrafficNetwork& network,
                     const std::function<double(const std::string&)>& lane_length) {
  const maps::Map& map = network.map();
  LinkIndex out;
  out.link_of_movement.assign(map.movements.size() + 1, {LinkIndex::kNoLight, 0});
  std::unordered_map<std::string, std::size_t> light_of;
  for (std::size_t i = 0; i < lights.lights().size(); ++i) {
    light_of.emplace(lights.lights()[i].tls, i);
  }
  for (const maps::Intersection& x : map.intersections) {
    if (x.control != maps::Control::kSignal && x.control != maps::Control::kStop) continue;
    for (const MovementId mid : x.movements) {
      const maps::SumoMovement& sm = network.files().movement(mid);
      const std::size_t light = light_of.at(sm.junction);
      const auto link = static_cast<std::size_t>(sm.tls_link_index.value_or(0));
      out.link_of_movement[mid.value()] = {light, link};
      LinkIndex::StopLane& lane = out.stop_lanes[sm.from.id()];
      lane.light = light;
      lane.links.push_back(LinkIndex::StopLane::Link{sm.to.edge, sm.to.id(), link});
      out.exit_of_link.resize(std::max(out.exit_of_link.size(), light + 1));
      auto& exits = out.exit_of_link[light];
      exits.resize(std::max(exits.size(), link + 1));
      exits[link] = sm.to.id();
      auto& exit_lights = out.exit_lights[sm.to.id()];
      if (std::find(exit_lights.begin(), exit_lights.end(), light) == exit_lights.end()) {
        exit_lights.push_back(light);
      }
      for (const std::string& internal : network.InternalLanes(mid)) {
        out.link_of_lane.emplace(internal, LightLink{light, link});
        out.movement_of_lane.emplace(internal, mid);
      }
    }
  }
  for (auto& [id, lane] : out.stop_lanes) lane.length = lane_length(id);
  return out;
}

const LaneInfo& LaneLookup::Of(const std::string& sumo_lane) {
  auto it = info_.find(sumo_lane);
  if (it != info_.end()) return it->second;
  LaneInfo info;
  info.map_name = &map_name_(sumo_lane);
  const auto add = [&](std::size_t light) {
    if (std::find(info.lights.begin(), info.lights.end(), light) == info.lights.end()) {
      info.lights.push_back(light);
    }
  };
  if (const auto stop = links_.stop_lanes.find(sumo_lane); stop != links_.stop_lanes.end()) {
    add(stop->second.light);
  }
  if (const auto link = links_.link_of_lane.find(sumo_lane); link != links_.link_of_lane.end()) {
    add(link->second.first);
  }
  if (const auto exit = links_.exit_lights.find(sumo_lane); exit != links_.exit_lights.end()) {
    for (const std::size_t light : exit->second) add(light);
  }
  return info_.emplace(sumo_lane, std::move(info)).first->second;
}

}  // namespace autodrive::traffic
