#pragma once
/// @file
/// The links of the city's SUMO traffic lights as the co-simulation's parts need them (built
/// once, when SUMO runs): which lane feeds which light's links and where each link leads, which
/// internal lane belongs to which link and movement, which light shows which map movement. And
/// `LaneLookup`: what a step needs to know of a SUMO lane a vehicle is on, found once a lane.

#include <cstddef>
#include <functional>
#include <limits>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "traffic/lights.h"
#include "traffic/network.h"

#include "common/ids.h"

namespace autodrive::traffic {

/// A light's link: (light index in LightBinding order, link index).
using LightLink = std::pair<std::size_t, std::size_t>;

/// The links of the traffic lights (an immutable model of the network, built by `IndexLinks`).
struct LinkIndex {
  /// `LightLink::first` of a movement of no traffic light.
  static constexpr std::size_t kNoLight = std::numeric_limits<std::size_t>::max();

  /// An ingress lane of a traffic light.
  struct StopLane {
    std::size_t light = 0;
    double length = 0;  ///< SUMO metres
    struct Link {
      std::string edge;  ///< the next edge
      std::string lane;  ///< the SUMO lane it enters
      std::size_t index = 0;
    };
    std::vector<Link> links;
  };
  /// By SUMO lane id.
  std::unordered_map<std::string, StopLane> stop_lanes;
  /// The internal lanes of the lights' links: their link.
  std::unordered_map<std::string, LightLink> link_of_lane;
  /// By light and link: the SUMO lane it enters.
  std::vector<std::vector<std::string>> exit_of_link;
  /// Every lane a light's link enters: the lights whose links enter it.
  std::unordered_map<std::string, std::vector<std::size_t>> exit_lights;
  /// By movement id: its light and link (`kNoLight` for a movement of no light).
  std::vector<LightLink> link_of_movement;
  /// The internal lanes of the controlled intersections' movements: the movement.
  std::unordered_map<std::string, MovementId> movement_of_lane;
};

/// Indexes the links of `lights` (signalised and stop-controlled intersections) on `network`
/// (its internal lanes learnt). `lane_length(lane)`: a SUMO lane's length (SUMO metres).
[[nodiscard]] LinkIndex IndexLinks(const LightBinding& lights, const TrafficNetwork& network,
                                   const std::function<double(const std::string&)>& lane_length);

/// What a step needs to know of a SUMO lane a vehicle is on: its name in the map, and the lights
/// whose links it feeds, runs through or leaves (its vehicles matter while one of them runs an
/// all-way stop).
struct LaneInfo {
  const std::string* map_name = nullptr;
  std::vector<std::size_t> lights;
};

/// `LaneInfo` by SUMO lane, found at the first ask (one lookup per vehicle and step after).
class LaneLookup {
 public:
  /// The name of the map lane or movement a SUMO lane lies on (`TrafficNetwork::MapName`); the
  /// reference must stay valid.
  using MapName = std::function<const std::string&(const std::string& sumo_lane)>;
  /// `links` must outlive it. Not copyable (it hands out references into it).
  LaneLookup(const LinkIndex& links, MapName map_name)
      : links_(links), map_name_(std::move(map_name)) {}
  LaneLookup(const LaneLookup&) = delete;
  LaneLookup& operator=(const LaneLookup&) = delete;

  const LaneInfo& Of(const std::string& sumo_lane);

 private:
  const LinkIndex& links_;
  MapName map_name_;
  std::unordered_map<std::string, LaneInfo> info_;
};

}  // namespace autodrive::traffic
