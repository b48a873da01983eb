#pragma once
/// @file
/// The background traffic's demand: the circulating vehicles placed at the start, the flows'
/// departures as they fall due, and the routes of circulating vehicles, which never end: a
/// seeded random walk over the lane graph (never into a road that only leads out of the map),
/// extended as they go, and turned elsewhere where a vehicle stands at the head of its lane
/// waiting for a road that is full while another has room (a circulating vehicle has no
/// destination; without it random walks in a small closed town run into gridlock).
///
/// Every random draw comes from one engine seeded with `TrafficConfig::seed`, in a fixed order,
/// so the same seed gives the same demand. Times are on SUMO's clock (`SumoTime`). New vehicles
/// are returned as `Departure`s for the co-simulation to add; the routes of vehicles running are
/// read and set through SUMO's API (a scripted one in tests).

#include <cstddef>
#include <cstdint>
#include <random>
#include <string>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "traffic/all_way_stops.h"
#include "traffic/links.h"
#include "traffic/network.h"
#include "traffic/sumo_api.h"
#include "traffic/sumo_cache.h"
#include "traffic/sumo_time.h"
#include "traffic/traffic_config.h"

namespace autodrive::traffic {

/// A vehicle for SUMO to add now: its route `r_<id>`, lane "best", speed 0.
struct Departure {
  std::string id;
  std::string type;
  std::vector<std::string> route;
  std::string depart_pos;  ///< "base" or SUMO metres
  bool operator==(const Departure&) const = default;
};

class Demand {
 public:
  /// Edges a circulating vehicle's route holds ahead of it after an extension.
  static constexpr std::size_t kWalkEdges = 16;
  /// A route is extended when it has this many edges left.
  static constexpr std::size_t kExtendAt = 4;
  /// A circulating vehicle standing this long at the head of its lane, its road full, turns.
  static constexpr Duration kBlocked = std::chrono::seconds(3);

  /// `network` must outlive it. @throws InputError for a mix type without a name, a flow from or
  /// to an unknown lane, or a flow whose `to` cannot be reached. Copyable and movable.
  Demand(const TrafficConfig& config, const TrafficNetwork& network);

  /// `config.vehicles` circulating vehicles, each wholly on one edge, clear of each other, of the
  /// junctions and of `occupied` ((edge, back, front) in SUMO metres: the lab's cars); fewer
  /// when the network has no room. Types drawn from the mix (sizes from `sumo`).
  [[nodiscard]] std::vector<Departure> RandomVehicles(
      const std::vector<std::tuple<std::string, double, double>>& occupied, SumoCache& sumo);
  /// The flows' departures due at `now` (SUMO's time after the last step).
  [[nodiscard]] std::vector<Departure> DueFlows(SumoTime now);

  /// After step number `step` (1 on the first): circulating vehicles whose route is running
  /// out get a longer one (every 10th step; reads `route_index` into `vehicles`).
  void ExtendRoutes(std::int64_t step, std::vector<SumoVehicleState>& vehicles, SumoApi& api);
  /// After step number `step`, at `now`: a circulating vehicle that stood `kBlocked` at the head
  /// of its lane into an intersection, its next road full and not let through by `stops`, turns
  /// to a road with room (every 20th step).
  void RerouteBlocked(std::int64_t step, SumoTime now,
                      const std::vector<SumoVehicleState>& vehicles, const LinkIndex& links,
                      const AllWayStops& stops, SumoCache& sumo);

  /// A vehicle left the network: true when it was a circulating one (it must not).
  bool Arrived(const std::string& id) { return circulating_.erase(id) != 0; }
  /// Whether `id` is a circulating vehicle of ours.
  [[nodiscard]] bool circulating(const std::string& id) const {
    return circulating_.count(id) != 0;
  }

  [[nodiscard]] std::int64_t route_extensions() const { return route_extensions_; }
  [[nodiscard]] std::int64_t reroutes() const { return reroutes_; }

 private:
  struct Flow {
    FlowConfig config;
    std::string from_edge, to_edge;
    int sent = 0;
  };
  const std::string& PickType();
  Departure Depart(std::string id, std::string type, std::vector<std::string> route,
                   bool circulating, std::string depart_pos);

  const TrafficNetwork* network_;
  std::vector<TypeShare> mix_;
  int vehicles_ = 0;
  std::mt19937_64 rng_;
  std::int64_t next_id_ = 0;
  std::vector<Flow> flows_;
  // Edges in each circulating vehicle's route (SUMO's index restarts with a new one).
  std::unordered_map<std::string, std::size_t> circulating_;
  std::unordered_map<std::string, SumoTime> blocked_since_;  // standing, at a stop line
  std::int64_t route_extensions_ = 0;
  std::int64_t reroutes_ = 0;
};

}  // namespace autodrive::traffic
