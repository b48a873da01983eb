#pragma once
/// @file
/// The traffic of the intergreen collision oracle (collision_oracle.h, research/controller.md
/// §4.3 M8): SUMO vehicles that test a city's clearances at its signalised intersections.
///
/// Two vehicle types, both trusting the signal: they ignore foes already in the junction
/// (`jmIgnoreJunctionFoeProb` 1) and foes with right of way (`jmIgnoreFoeProb` 1), and drive
/// through the whole yellow (`jmDriveAfterYellowTime` = the longest yellow shown), so that a
/// vehicle may cross its stop line on the last instant of yellow and another start on the first
/// instant of a conflicting green, as the intergreen assumes:
/// - **clearing**: the city's slowest declared clearing vehicle (`safety.clearing_vehicles`:
///   its length and speed), the one the intergreen waits for;
/// - **entering**: a Nigel at the city's declared entering speed (`safety.entering_speed_mps`),
///   the one that reaches the conflict first.
/// Both accelerate at the fastest acceleration the co-simulation declares for its vehicle types
/// (maps/sumo.h: Nigel 0.5 m/s^2) and drive without imperfection (sigma 0, no speed deviation).
/// Sizes, speeds and accelerations are the lab's times the network's scale (x14), as the
/// co-simulation runs them.
///
/// Flows: for every movement of a signalised intersection whose group conflicts with another
/// group, one flow of each type from a little upstream of its stop line (`approach_m`) to its
/// egress edge, so that the
/// movements of one approach share its arrivals (a vehicle every `headway` on average, random:
/// SUMO's `probability` flows, from its seed). With the lab's short greens the approaches are
/// saturated: a queue discharges through each green and yellow, so that a vehicle crosses the
/// stop line late in nearly every yellow and one waits at the line for every green.

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "common/ids.h"
#include "common/time.h"
#include "maps/sumo.h"
#include "scm/core/city.h"

namespace autodrive::traffic::nema {

/// One vehicle type of the oracle, in SUMO's units (the lab's x the network's scale).
struct OracleVehicleType {
  std::string id;   ///< "clearing" or "entering"
  std::string why;  ///< where its figures come from, for the report
  double length_m = 0.0;
  double width_m = 0.0;
  double max_speed_mps = 0.0;
  double accel_mps2 = 0.0;
  double decel_mps2 = 0.0;
  double emergency_decel_mps2 = 0.0;
  double min_gap_m = 0.0;
  Duration drive_after_yellow{0};  ///< jmDriveAfterYellowTime
};

/// One flow: vehicles of one type through one movement.
struct OracleFlow {
  std::string id;            ///< SUMO's flow id (its vehicles are "<id>.<n>")
  std::string intersection;  ///< the intersection's name (its junction)
  MovementId movement{0};
  std::string movement_name;       ///< the map's ("r2c2:E>N:0>0")
  std::size_t group = 0;           ///< the movement's group (index in the intersection)
  std::string type;                ///< an `OracleVehicleType::id`
  std::string from_edge, to_edge;  ///< the route: the movement's ingress and egress edges
  int depart_lane = 0;             ///< SUMO lane index on `from_edge`
  double probability_per_s = 0.0;  ///< SUMO's `probability`: a vehicle each second with it
};

/// What the oracle's traffic is made of.
struct OracleTrafficParams {
  /// Mean time between two vehicles of one approach (the movements and the two types share it).
  Duration headway = std::chrono::seconds(6);
  Duration begin{0};  ///< first departures
  Duration end{0};    ///< last departures
  /// Only this intersection's movements (its name or id); none: every signalised intersection.
  std::optional<std::string> intersection;
};

/// The oracle's vehicle types and flows.
struct OracleTraffic {
  double scale = 0.0;               ///< SUMO metres per lab metre
  double road_speed_mps = 0.0;      ///< lab m/s: every road's limit, above both types' speeds
  std::string clearing_vehicle;     ///< the name of the slowest declared clearing vehicle
  double fastest_accel_mps2 = 0.0;  ///< lab m/s^2: the co-simulation's fastest declared
  std::vector<OracleVehicleType> types;
  std::vector<OracleFlow> flows;
  Duration begin{0}, end{0};
  Duration headway{0};

  /// The flow with SUMO id `id`, or null.
  [[nodiscard]] const OracleFlow* FindFlow(const std::string& id) const;
  /// The flow of a vehicle ("<flow>.<n>"), or null.
  [[nodiscard]] const OracleFlow* FlowOfVehicle(const std::string& vehicle) const;
};

/// The vehicle types of the oracle for `city` (the slowest of its clearing vehicles, its
/// entering speed, the longest yellow of its groups) at `scale`, and the road speed (lab m/s)
/// that lets both run at their own speed. Throws `InputError` when the city declares no
/// clearing vehicle.
[[nodiscard]] OracleTraffic OracleTypesOf(const scm::City& city, double scale);

/// The oracle's types and flows for `city` on its exported network `net` (the co-simulation's
/// export: the movements' SUMO lanes). Throws `InputError` for an unknown `params.intersection`,
/// a headway that is not positive, or an end before the begin.
[[nodiscard]] OracleTraffic OracleTrafficOf(const scm::City& city, const maps::SumoExport& net,
                                            const OracleTrafficParams& params);

/// A SUMO route file with `traffic`'s vehicle types and flows.
[[nodiscard]] std::string OracleRoutesXml(const OracleTraffic& traffic);

}  // namespace autodrive::traffic::nema
