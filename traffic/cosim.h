#pragma once
/// @file
/// The co-simulation: SUMO on the city's network with the city's demand, stepped with what the
/// lab reports (the lamps its lights show, where its own cars are), giving back SUMO's vehicles
/// in the lab's frame. No DDS here (service.h carries it), so that tests and benchmarks drive
/// it directly.
///
/// Each `Step`:
/// 1. the lamps become SUMO's link states (lights.h) where they changed;
/// 2. every lab car is placed in SUMO as an externally moved vehicle (moveToXY) at its pose, so
///    that SUMO's cars follow it, stop behind it and yield to it; a car that goes stale or
///    leaves the road network leaves SUMO. SUMO puts a moved car on the lane nearest its front
///    bumper, whatever lane the move names, and draws its body back along that lane. In an
///    intersection's box that is often another movement's (paths cross there, or pass side by
///    side), and SUMO would see the car across paths it is not on, and report collisions with
///    the cars on them that never were. So in a box a car is kept to the movement it drives
///    (`LabCarClaims::Under`): its route in SUMO is set through the movement (from its lane in,
///    where SUMO has it there), and its moves keep to its route (keepRoute 3: only the lanes in,
///    through and out); where SUMO has it on another movement's internal lane (whose route
///    cannot change there), its front is put on the movement's path for a move (keepRoute 2:
///    SUMO takes the lane under the point, and the route through it);
/// 3. the demand's departures due are added (flows);
/// 4. SUMO steps;
/// 5. a traffic light that flashes red or is dark is an all-way stop, arbitrated here (see
///    `ArbitrateAllWayStops`): its links stay red for a vehicle until it has stood at the stop
///    line, then open, first come first served, for movements that conflict with none inside;
/// 6. circulating vehicles whose route is running out get a longer one (a seeded random walk
///    over the lane graph), so that they never arrive; departures, arrivals, teleports and
///    collisions are counted (and logged);
/// 7. every SUMO vehicle but the lab's is read and mapped to the lab's frame.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <Eigen/Core>

#include "traffic/lab_claims.h"
#include "traffic/lights.h"
#include "traffic/network.h"
#include "traffic/sumo_api.h"
#include "traffic/traffic_config.h"

#include "common/time.h"
#include "maps/query.h"

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

  /// SUMO's time after the last step (s since the start).
  [[nodiscard]] double time_s() const { return time_s_; }
  [[nodiscard]] const std::vector<TrafficVehicle>& vehicles() const { return vehicles_; }
  [[nodiscard]] const CoSimStats& stats() const { return stats_; }
  [[nodiscard]] const TrafficNetwork& network() const { return *network_; }
  [[nodiscard]] SumoApi& api() { return *api_; }
  /// The link states last set on SUMO's traffic lights, by light (LightBinding order).
  [[nodiscard]] const std::vector<std::string>& light_states() const { return light_states_; }
  [[nodiscard]] const LightBinding& lights() const { return lights_; }

 private:
  struct Circulating {
    std::size_t route_length = 0;  // edges in its route (SUMO's index restarts with a new one)
  };
  struct LabCar {
    MonoTime last_seen{};
    bool in_sumo = false;
    std::string sumo_id;  // the name, then name#k after the k-th re-entry
    int entries = 0;
    std::string lane;  // SUMO's lane for it after the last step (for logs)
    LabCarPose pose;   // the last heard
    // The movement SUMO's route for it runs through (its lane in, then its lane out), when known:
    // a move that keeps to its route then puts it on that movement's lanes.
    std::optional<MovementId> route_via;
    bool kept_route = false;  // its last move kept to its route
  };
  struct Flow {
    FlowConfig config;
    std::string from_edge, to_edge;
    int sent = 0;
  };

  void StartSumo(Options& options);
  void InsertRandomVehicles();
  const std::string& PickType();
  void AddVehicle(const std::string& id, const std::string& type, std::vector<std::string> route,
                  bool circulating, const std::string& depart_pos);
  void UpdateLights(MonoTime now);
  // Lab cars: into SUMO (or out of it); then, once the claims are up to date, where they are.
  void PlaceLabCars(const std::vector<LabCarPose>& cars, MonoTime now);
  void MoveLabCars();
  // For a lab car on a lane (not in a box): where SUMO is to have its front (`front`, on its
  // lane or the next, within the lane's width) and on which SUMO lane.
  std::optional<std::pair<Eigen::Vector2d, std::string>> FrontOnItsLane(
      const LabCarPose& car, const Eigen::Vector2d& front);
  void NoteLabLane(const SumoVehicleState& v);
  // For a collision's log line: where the lab cars among `a` and `b` were.
  [[nodiscard]] std::string DescribeLabCars(const std::string& a, const std::string& b) const;
  void DepartFlows();
  void ExtendRoutes();
  void RerouteBlocked();
  void ReadVehicles();
  void IndexStopLanes();
  void ArbitrateAllWayStops();
  const SumoTypeSize& TypeSize(const std::string& type);

  const scm::City& city_;
  TrafficConfig config_;
  std::unique_ptr<TrafficNetwork> network_;
  std::unique_ptr<SumoApi> api_;
  LightBinding lights_;
  std::vector<HeadReading> heads_;         // by head id
  std::vector<std::string> light_states_;  // by light
  std::mt19937_64 rng_;
  double time_s_ = 0.0;
  double step_s_ = 0.05;
  std::int64_t next_id_ = 0;
  bool inserted_ = false;  // the random vehicles
  std::vector<std::string> expected_lab_cars_;
  double lab_car_wait_s_ = 5.0;
  std::unordered_map<std::string, Circulating> circulating_;
  std::unordered_map<std::string, LabCar> lab_cars_;
  std::unordered_set<std::string> lab_ids_;  // every SUMO id a lab car had
  std::unique_ptr<maps::MapIndex> index_;
  // The all-way stops of flashing or dark traffic lights.
  struct StopLane {  // an ingress lane of a traffic light
    std::size_t light = 0;
    double length = 0;  // SUMO metres
    struct Link {
      std::string edge;  // the next edge
      std::string lane;  // the SUMO lane it enters
      std::size_t index = 0;
    };
    std::vector<Link> links;
  };
  struct Grant {
    std::string vehicle;
    std::size_t link = 0;
    double since = 0;  // SUMO time of the grant (s)
    double room = 0;   // what it takes of its exit lane (SUMO metres)
  };
  std::unordered_map<std::string, StopLane> stop_lanes_;  // by SUMO lane id
  // Internal lanes of the traffic lights' links: (light, link).
  std::unordered_map<std::string, std::pair<std::size_t, std::size_t>> link_of_lane_;
  std::vector<std::vector<std::string>> exit_of_link_;
  // Every lane a light's link enters: the lights whose links enter it.
  std::unordered_map<std::string, std::vector<std::size_t>> exit_lights_;
  std::vector<std::string> aspect_states_;  // by light: 's' where all-way stop
  std::vector<bool> all_way_;               // by light: its aspect has an all-way stop now
  std::size_t all_way_count_ = 0;
  std::vector<std::vector<bool>> occupied_;  // by light and link: a vehicle in its lanes
  // The lab cars' claims (lab_claims.h): by light and link, SUMO's vehicles may not start it.
  std::unique_ptr<LabCarClaims> claims_;
  std::vector<std::pair<std::size_t, std::size_t>> link_of_movement_;  // by movement id
  // The internal lanes of the controlled intersections' movements: the movement.
  std::unordered_map<std::string, MovementId> movement_of_lane_;
  std::vector<std::vector<bool>> held_;
  std::vector<std::size_t> held_lights_;  // the lights with a held link
  void HoldForLabCars();
  std::vector<LabCarPose> held_for_;                      // scratch: the lab cars in SUMO
  std::unordered_map<std::string, double> lane_lengths_;  // SUMO metres, by SUMO lane id
  // What a step needs to know of a SUMO lane a vehicle is on, found once (one lookup per
  // vehicle and step): its name in the map, and the lights whose all-way stop it feeds, crosses
  // or leaves (its vehicles' lane positions matter while one of them runs an all-way stop).
  struct LaneInfo {
    const std::string* map_name = nullptr;
    std::vector<std::size_t> lights;
  };
  const LaneInfo& InfoOf(const std::string& sumo_lane);
  [[nodiscard]] bool AllWayNear(const LaneInfo& info) const;
  double LaneLength(const std::string& sumo_lane);
  std::unordered_map<std::string, LaneInfo> lane_info_;
  std::vector<MonoTime> recheck_until_;  // by light: a lamp went to or from dark lately
  std::vector<bool> relight_;            // by light: a lamp changed since the last step
  std::vector<std::vector<std::size_t>> lights_of_head_;    // by head id
  std::vector<std::vector<Grant>> grants_;                  // by light
  std::unordered_map<std::string, double> standing_since_;  // vehicle: s, at a stop line
  std::unordered_map<std::string, double> blocked_since_;   // circulating vehicle: s, standing
  std::vector<Flow> flows_;
  std::unordered_map<std::string, SumoTypeSize> type_sizes_;
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

/// SUMO's navigational angle (degrees, 0 north, clockwise) as a map yaw (rad, 0 east, CCW).
[[nodiscard]] double YawFromSumoAngle(double angle_deg);
/// A map yaw as SUMO's navigational angle.
[[nodiscard]] double SumoAngleFromYaw(double yaw_rad);

}  // namespace autodrive::traffic
