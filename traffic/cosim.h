#pragma once
/// @file
/// The co-simulation: SUMO on the city's network with the city's demand, stepped with what the
/// lab reports (the lamps its lights show, where its own cars are), giving back SUMO's vehicles
/// in the lab's frame. No DDS here (service.h carries it), so that tests and benchmarks drive
/// it directly.
///
/// Each `Step`, in this order:
/// 1. every lab car is placed in SUMO at its pose, or taken out of it (`LabCarPlacement`),
///    after the links SUMO's vehicles must leave to the lab's cars are held (`LabCarClaims`);
/// 2. the lamps become SUMO's link states where they changed (`LampMapping`, lights.h);
/// 3. the demand's vehicles due go in (`Demand`: the circulating ones once the lab's cars are
///    in, then the flows');
/// 4. SUMO steps; departures, arrivals, teleports and collisions are counted (and logged);
/// 5. every SUMO vehicle but the lab's is read and mapped to the lab's frame;
/// 6. the all-way stops are arbitrated (`AllWayStops`): their links stay red for a vehicle
///    until it has stood at the stop line, then open, first come first served, for movements
///    that conflict with none inside;
/// 7. circulating vehicles whose route is running out get a longer one, and those held up by a
///    full road turn elsewhere (`Demand`).

#include <cstdint>
#include <filesystem>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "traffic/all_way_stops.h"
#include "traffic/demand.h"
#include "traffic/lab_claims.h"
#include "traffic/lab_placement.h"
#include "traffic/lamp_mapping.h"
#include "traffic/lights.h"
#include "traffic/links.h"
#include "traffic/network.h"
#include "traffic/sumo_api.h"
#include "traffic/sumo_cache.h"
#include "traffic/sumo_frame.h"
#include "traffic/sumo_time.h"
#include "traffic/traffic_config.h"

#include "common/time.h"

namespace autodrive::scm {
struct City;
}

namespace autodrive::traffic {

/// One of SUMO's vehicles in the lab's frame (see autodrive_msgs/TrafficObject).
struct TrafficVehicle {
  std::string id;
  std::uint8_t object_class = 1;  ///< TrafficObject_Constants (CAR 1, BUS 2, EMERGENCY 7)
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  ///< footprint centre, map frame
  double yaw_rad = 0.0;
  double length_m = 0.0, width_m = 0.0, height_m = 0.0;
  double speed_mps = 0.0;
  std::string map_lane;      ///< map lane or movement name; empty on neither
  std::uint8_t signals = 0;  ///< bit 0 left, 1 right, 2 brake
};

/// Counts since the start.
struct CoSimStats {
  std::int64_t steps = 0;
  std::int64_t departed = 0;         ///< background vehicles that entered the network
  std::int64_t arrived_planned = 0;  ///< left where their route ends (route files, flows with `to`)
  std::int64_t arrived_unplanned = 0;  ///< circulating vehicles that left: must stay 0
  std::int64_t teleports = 0;          ///< must stay 0 (SUMO runs with teleports off)
  std::int64_t collisions = 0;         ///< pairs of vehicles that started to overlap
  std::int64_t lab_overlaps = 0;       ///< of two lab cars as SUMO placed them (not collisions)
  std::int64_t lab_cars_placed = 0;    ///< lab cars in SUMO now
  std::int64_t lab_car_misses = 0;  ///< placements SUMO refused (car off the roads), trips it ended
  std::int64_t route_extensions = 0;
  std::int64_t reroutes = 0;        ///< circulating vehicles that turned elsewhere, their road full
  std::int64_t all_way_grants = 0;  ///< vehicles let through flashing or dark lights
  std::int64_t all_way_lapsed = 0;  ///< of them, those that did not go in time (SUMO saw no way)
  double sumo_step_cpu_s = 0.0;     ///< CPU time inside SUMO's own step (for the overhead figure)
};

/// The co-simulation: a thin composition of its parts, which it steps in order and connects to
/// SUMO (the one place where SUMO's seconds become `SumoTime`):
/// - `LampMapping` (lamp_mapping.h): the lamps as SUMO's link states;
/// - `AllWayStops` (all_way_stops.h): the arbitration of flashing, dark and stop-controlled
///   intersections;
/// - `LabCarPlacement` (lab_placement.h) and `LabCarClaims` (lab_claims.h): the lab's cars in
///   SUMO, and what SUMO's vehicles must leave to them;
/// - `Demand` (demand.h): the background vehicles and their never-ending routes;
/// - the read-back here: SUMO's vehicles in the lab's frame, its events counted.
class CoSimulation {
 public:
  struct Options {
    std::filesystem::path work_dir;  ///< where the network and logs go (created)
    /// The SUMO backend (libsumo when null, or TraCI when the config asks for a port).
    std::unique_ptr<SumoApi> api;
    /// SUMO runs with junction collision checks (SUMO's `collision.check-junctions`).
    bool check_junction_collisions = true;
    /// The lab cars expected: the random vehicles go in once each is placed (so that none is
    /// put where a lab car stands), or after `lab_car_wait` at the latest.
    std::vector<std::string> expected_lab_cars;
    Duration lab_car_wait = std::chrono::seconds(5);
  };

  /// Exports the network, starts SUMO and inserts the demand. `city` must outlive this.
  /// @throws InputError for a bad demand (unknown lane, type), SumoError when SUMO fails.
  CoSimulation(const scm::City& city, const TrafficConfig& config, Options options);
  ~CoSimulation();
  CoSimulation(const CoSimulation&) = delete;
  CoSimulation& operator=(const CoSimulation&) = delete;

  /// A head's lamp report (`signal_<i>/state`) at control time `now`.
  void ReportLamp(SignalHeadId head, int lamp, MonoTime now);
  /// Advances SUMO by one step (`config.step_s`), with the lab cars where `lab_cars` says
  /// (the cars not listed are stale once `staleness_s` passed since they were) and the lamps at
  /// `now`. Returns the background vehicles after the step.
  const std::vector<TrafficVehicle>& Step(const std::vector<LabCarPose>& lab_cars, MonoTime now);

  /// SUMO's time after the last step.
  [[nodiscard]] SumoTime time() const { return time_; }
  /// SUMO's time after the last step (s since the start).
  [[nodiscard]] double time_s() const { return ToSeconds(time_); }
  [[nodiscard]] const std::vector<TrafficVehicle>& vehicles() const { return vehicles_; }
  [[nodiscard]] const CoSimStats& stats() const { return stats_; }
  [[nodiscard]] const TrafficNetwork& network() const { return *network_; }
  [[nodiscard]] SumoApi& api() { return *api_; }
  /// The link states last set on SUMO's traffic lights, by light (LightBinding order).
  [[nodiscard]] const std::vector<std::string>& light_states() const { return lamps_.states(); }
  [[nodiscard]] const LightBinding& lights() const { return lights_; }

 private:
  void StartSumo(Options& options);
  void Add(const std::vector<Departure>& departures);
  void SetLights(MonoTime now);
  void HoldForLabCars();
  // The random vehicles go in once the lab's cars are in the network (placed in the last step),
  // so that none is put where a lab car stands.
  void InsertRandomVehicles();
  void CountEvents();
  void ReadVehicles();

  const scm::City& city_;
  TrafficConfig config_;
  std::unique_ptr<TrafficNetwork> network_;
  std::unique_ptr<SumoApi> api_;
  std::unique_ptr<SumoCache> sumo_;
  LightBinding lights_;
  LampMapping lamps_;
  std::unique_ptr<Demand> demand_;
  std::unique_ptr<LinkIndex> links_;
  std::unique_ptr<LaneLookup> lanes_;
  std::unique_ptr<AllWayStops> all_way_;
  std::unique_ptr<LabCarPlacement> lab_;
  SumoTime time_{};
  bool inserted_ = false;  // the random vehicles
  std::vector<std::string> expected_lab_cars_;
  Duration lab_car_wait_;
  std::vector<SumoVehicleState> states_;
  std::vector<TrafficVehicle> vehicles_;
  struct ReadCache {  // by index in vehicles_: what the last step's vehicle there was on
    std::string sumo_lane;
    const LaneInfo* info = nullptr;
    const SumoTypeSize* size = nullptr;
    std::uint8_t object_class = 0;
    bool lane_changed = true;
  };
  std::vector<ReadCache> read_cache_;
  CoSimStats stats_;
  std::set<std::pair<std::string, std::string>> colliding_;  // in the last step
};

}  // namespace autodrive::traffic
