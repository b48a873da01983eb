#pragma once
/// @file
/// The city's road network as SUMO sees it: the map exported by `maps::ExportSumo` (full-size
/// frame, `maps::kSumoScale`), and the mapping between SUMO's ids and the map's in both
/// directions: a SUMO lane (an internal one inside a junction too) to the map lane or movement
/// it lies on, a map lane to its SUMO edge, and the edges that may follow an edge (the map's
/// lane graph: successors across tile edges and movements through intersections).

#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "maps/map.h"
#include "maps/sumo.h"

namespace autodrive::traffic {

class SumoApi;

/// Where a circulating vehicle starts: on `route[0]` with its front `pos` SUMO metres from the
/// edge's start, wholly on the edge, clear of every other vehicle placed.
struct Placement {
  std::vector<std::string> route;
  double pos = 0;
  std::string type;
};

class TrafficNetwork {
 public:
  /// Exports `map` into `dir` (created) with every road's speed limit `speed_mps` (lab m/s),
  /// and `programs` in place of the default fixed-time programs of those intersections.
  /// @throws InputError as `maps::ExportSumo`.
  TrafficNetwork(const maps::Map& map, const std::filesystem::path& dir, double speed_mps,
                 std::map<IntersectionId, maps::SumoSignalProgram> programs = {});

  [[nodiscard]] const maps::Map& map() const { return map_; }
  [[nodiscard]] const maps::SumoExport& files() const { return export_; }
  /// SUMO metres per lab metre.
  [[nodiscard]] double scale() const { return export_.scale; }

  /// Every SUMO edge (not internal), sorted.
  [[nodiscard]] const std::vector<std::string>& edges() const { return edges_; }
  /// The edges a vehicle on `edge` may drive onto next, sorted; empty for an edge that leaves
  /// the map. @throws InputError for an unknown edge.
  [[nodiscard]] const std::vector<std::string>& NextEdges(const std::string& edge) const;
  /// True when a vehicle on `edge` can drive on for ever (its roads do not all leave the map).
  [[nodiscard]] bool Circulates(const std::string& edge) const;
  /// An edge's length (lab metres: the mean of its lanes').
  [[nodiscard]] double EdgeLength(const std::string& edge) const;
  /// The SUMO edge a map lane (by name) starts on. @throws InputError naming the lane.
  [[nodiscard]] const std::string& EdgeOfLane(const std::string& map_lane_name) const;

  /// `edges` edges after `from`, each picked uniformly among those that may follow the last and
  /// circulate (roads out of the map only when nothing else follows; the walk is shorter when
  /// it reaches one).
  [[nodiscard]] std::vector<std::string> RandomWalk(const std::string& from, std::size_t edges,
                                                    std::mt19937_64& rng) const;
  /// The route from `from` to `to` with the fewest edges (both included); empty when `to`
  /// cannot be reached.
  [[nodiscard]] std::vector<std::string> Route(const std::string& from,
                                               const std::string& to) const;

  /// `n` circulating vehicles at random (edges weighted by length, types from `pick_type`,
  /// routes of `walk` edges), none overlapping another (with `gap` SUMO metres between) nor
  /// reaching into a junction; fewer when the network has no room for them all.
  /// `occupied`: (edge, back, front) of vehicles already there (SUMO metres).
  [[nodiscard]] std::vector<Placement> PlaceVehicles(
      int n, std::size_t walk, double gap, std::mt19937_64& rng,
      const std::function<const std::string&()>& pick_type,
      const std::function<double(const std::string&)>& length_of,
      const std::vector<std::tuple<std::string, double, double>>& occupied = {}) const;

  /// The name of the map lane (or, inside an intersection, the movement) a SUMO lane lies on;
  /// empty for a lane of neither (the short links at tile edges). Internal lanes are known
  /// once `LearnInternalLanes` ran.
  [[nodiscard]] const std::string& MapName(const std::string& sumo_lane) const;
  /// Reads from the running SUMO which internal lanes each movement's link runs along.
  void LearnInternalLanes(SumoApi& api);
  /// A movement's internal lanes (after `LearnInternalLanes`).
  [[nodiscard]] const std::vector<std::string>& InternalLanes(MovementId m) const;

 private:
  const maps::Map& map_;
  maps::SumoExport export_;
  std::vector<std::string> edges_;
  std::unordered_map<std::string, std::vector<std::string>> next_;
  std::unordered_set<std::string> alive_;
  std::unordered_map<std::string, double> length_;
  std::unordered_map<std::string, std::string> edge_of_lane_;
  std::unordered_map<std::string, std::string> map_name_;
  std::unordered_map<MovementId, std::vector<std::string>> internal_lanes_;
};

}  // namespace autodrive::traffic
