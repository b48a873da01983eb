#pragma once
/// @file
/// For the co-simulation's unit tests: a `SumoApi` whose answers are scripted (lane lengths,
/// type sizes, routes) and whose orders are recorded, so that the parts' rules run in-process
/// without SUMO. A call nothing was scripted for throws `std::logic_error` naming it.

#include <map>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "traffic/sumo_api.h"

namespace autodrive::traffic::internal {

class ScriptedSumo final : public SumoApi {
 public:
  /// What SUMO was told, one line a call ("AddVehicle nigel_1 r_nigel_1 nigel base", ...).
  std::vector<std::string> calls;
  std::map<std::string, double> lane_lengths;              ///< SUMO metres; unlisted lanes: 100
  std::map<std::string, SumoTypeSize> types;               ///< by type name
  std::map<std::string, std::vector<std::string>> routes;  ///< by vehicle
  std::map<std::string, int> route_indices;                ///< by vehicle (0 when unlisted)
  std::map<std::string, double> lane_positions;            ///< by vehicle
  struct Move {
    std::string id, edge;
    int lane = 0;
    double x = 0, y = 0, angle_deg = 0;
    bool keep_route = false;
  };
  std::vector<Move> moves;

  void Start(const std::vector<std::string>&, int, int) override { Unscripted("Start"); }
  void Close() override {}
  void Step(double) override { Unscripted("Step"); }
  double Time() override { Unscripted("Time"); }
  SumoStepEvents Events() override { return {}; }
  void AddRoute(const std::string& id, const std::vector<std::string>& edges) override {
    routes[id] = edges;
    calls.push_back("AddRoute " + id + Joined(edges));
  }
  void AddVehicle(const std::string& id, const std::string& route, const std::string& type,
                  const std::string&, const std::string&, const std::string& pos,
                  const std::string&) override {
    routes[id] = routes[route];
    calls.push_back("AddVehicle " + id + " " + route + " " + type + " " + pos);
  }
  void SetRoute(const std::string& id, const std::vector<std::string>& edges) override {
    routes[id] = edges;
    route_indices[id] = 0;
    calls.push_back("SetRoute " + id + Joined(edges));
  }
  std::vector<std::string> Route(const std::string& id) override { return routes.at(id); }
  void MoveToXY(const std::string& id, const std::string& edge, int lane, double x, double y,
                double angle_deg, bool keep_route) override {
    moves.push_back(Move{id, edge, lane, x, y, angle_deg, keep_route});
    calls.push_back("MoveToXY " + id);
  }
  double LaneLength(const std::string& lane) override {
    const auto it = lane_lengths.find(lane);
    return it == lane_lengths.end() ? 100.0 : it->second;
  }
  void SetSpeed(const std::string& id, double) override { calls.push_back("SetSpeed " + id); }
  void SetSpeedMode(const std::string& id, int) override { calls.push_back("SetSpeedMode " + id); }
  void Remove(const std::string& id) override { calls.push_back("Remove " + id); }
  std::vector<std::string> VehicleIds() override { return {}; }
  void ReadVehicles(std::vector<SumoVehicleState>&) override { Unscripted("ReadVehicles"); }
  double LanePosition(const std::string& id) override { return lane_positions.at(id); }
  int RouteIndex(const std::string& id) override {
    const auto it = route_indices.find(id);
    return it == route_indices.end() ? 0 : it->second;
  }
  SumoTypeSize TypeSize(const std::string& type) override {
    const auto it = types.find(type);
    if (it == types.end()) throw SumoError("unknown vehicle type " + type);
    return it->second;
  }
  void SetLightState(const std::string& tls, const std::string& state) override {
    calls.push_back("SetLightState " + tls + " " + state);
  }
  std::string LightState(const std::string&) override { Unscripted("LightState"); }
  double LightNextSwitch(const std::string&) override { Unscripted("LightNextSwitch"); }
  std::vector<std::pair<std::string, std::string>> Links(const std::string&) override {
    Unscripted("Links");
  }
  std::string NextLane(const std::string&) override { Unscripted("NextLane"); }
  int HaltingNumber(const std::string&) override { Unscripted("HaltingNumber"); }

 private:
  static std::string Joined(const std::vector<std::string>& edges) {
    std::string out;
    for (const std::string& e : edges) out += " " + e;
    return out;
  }
  [[noreturn]] static void Unscripted(const char* call) {
    throw std::logic_error(std::string("ScriptedSumo: ") + call + " was not scripted");
  }
};

}  // namespace autodrive::traffic::internal
