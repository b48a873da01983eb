#pragma once
/// @file
/// Every tunable of the parking agent in one file (examples/parking/parking.yaml documents each,
/// with the values the agent takes when it is given none): the planner's, the tracker's, the
/// localiser's (particle filter and SLAM), the local planner's (what the LIDAR sees that is news)
/// and the arrival's. The car's own figures (wheelbase, steering lock, body, wheel radius, the
/// LIDAR's place) come from its city, not from here.

#include <string>

#include "common/config.h"
#include "examples/parking/hybrid_astar.h"
#include "examples/parking/local_planner.h"
#include "examples/parking/localiser.h"
#include "examples/parking/tracker.h"

namespace autodrive::examples {

/// At the path's end: when to correct, and how often; how long to stand before planning again.
struct ArrivalParams {
  double correct_beyond_m = 0.025;  ///< stopped further than this from the goal: a correction
  double correct_beyond_deg = 4.0;  ///< ... or turned further than this
  int corrections = 2;              ///< at most
  double replan_after_s = 0.5;      ///< standing this long before a new plan (then every s)

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("correct_beyond_m", correct_beyond_m, config::Range{0.001, 1.0});
    a.Optional("correct_beyond_deg", correct_beyond_deg, config::Range{0.1, 90.0});
    a.Optional("corrections", corrections, config::Range{0, 20});
    a.Optional("replan_after_s", replan_after_s, config::Range{0.0, 10.0});
  }
};

struct ParkingConfig {
  HybridAStarParams planner;
  TrackerParams tracker;
  LocaliserParams localiser = AgentLocaliserParams();
  ObstacleParams obstacles;
  ArrivalParams arrival;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("planner", planner);
    a.Optional("tracker", tracker);
    a.Optional("localiser", localiser);
    a.Optional("obstacles", obstacles);
    a.Optional("arrival", arrival);
  }
};

/// Reads `path` (strict: an unknown key, a wrong type or a value out of range is refused with
/// the file, line and key); what it leaves out keeps its default. Throws ConfigError.
[[nodiscard]] ParkingConfig LoadParkingConfig(const std::string& path);

}  // namespace autodrive::examples
