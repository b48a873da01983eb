#pragma once
/// @file
/// A small driver that keeps a car moving on the map's lanes: pure pursuit along the lane
/// centrelines and the movements through intersections (a random choice at each, from a seeded
/// engine), stopping at the stop line when its light is red or on a yellow it cannot clear
/// (from the lamps, or from SPaT through a `SignalLookup`), stopping at stop signs
/// and at flashing red lights (a stop sign by law) and going on once nothing is in the
/// intersection's box, and stopping for whatever its LIDAR sees close ahead. It knows only what a
/// user's code on the real car would: the map, its pose (IPS position and IMU heading), the lamps'
/// states and its LIDAR scan. `autodrive-example-driver` runs it over DDS for every car of a
/// city; the main job (`scripts/run-city`) uses it so that the simulated city is alive with no
/// user code.

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "common/geometry.h"
#include "common/ids.h"
#include "common/time.h"
#include "maps/map.h"

namespace autodrive::vehicle_sim {

/// What a signal shows the car's movement: read off its lamps, or from SPaT (V2I).
struct SignalIndication {
  enum class State { kDark, kRed, kYellow, kGreen, kFlashingRed, kFlashingYellow };
  State state = State::kRed;
  /// Seconds from now, when known: the earliest end of this state (SPaT's min_end_time), its
  /// likely end (likely_time), and the start of the movement's next green (next_time).
  std::optional<double> min_end_s, likely_end_s, next_green_s;
};

/// The indication for the movement from lane `ingress` along `movement` (null while the route
/// does not reach past the stop line yet); nothing when unknown (the driver stops, as at red).
using SignalLookup = std::function<std::optional<SignalIndication>(const maps::Lane& ingress,
                                                                   const maps::Movement* movement)>;

/// The next stop line on the car's route, as the driver last saw it.
struct StopLineAhead {
  const maps::Intersection* intersection = nullptr;
  const maps::Lane* ingress = nullptr;
  const maps::Movement* movement = nullptr;  ///< null while the route does not reach past it
  const maps::Lane* egress = nullptr;        ///< the movement's lane out, when known
  double to_line_m = 0.0;                    ///< from the car's front bumper, along the route
};

struct DriverOptions {
  double cruise_throttle = 0.6;  ///< normalised throttle on open road (0.6 x 0.26 m/s)
  double lookahead_m = 0.25;     ///< pure pursuit's lookahead distance
  /// How far ahead of the car its route is planned (and `NextStopLine` sees).
  double plan_ahead_m = 2.0;
  double wheelbase_m = 0.14154;
  double steering_limit_rad = 0.5236;
  double front_overhang_m = 0.2297;  ///< rear axle to the front of the body
  double rear_overhang_m = 0.0883;   ///< rear axle to the back of the body
  /// Speed at full throttle (NIGEL.md): a speed limit becomes a throttle by it.
  double top_speed_mps = 0.26;
  double stop_gap_m = 0.03;  ///< the front stops this far before a stop line
  double slow_down_m = 0.3;  ///< throttle falls linearly over this distance to a stop
  /// ... but not below this fraction of the cruising throttle until the car is at the line.
  double creep_fraction = 0.3;
  /// What its LIDAR sees on its own path ahead (within its half width plus `path_margin_m` of
  /// the route it drives): it slows down from twice this gap (front bumper to the obstacle,
  /// along the path) and stops under it.
  double obstacle_stop_m = 0.15;
  double half_width_m = 0.0875;  ///< half the body's width
  double path_margin_m = 0.04;
  Duration stop_sign_wait = std::chrono::seconds(1);
  /// A head seen both red and dark within this long is flashing red (the lights flash once a
  /// second by default): the driver treats it as a stop sign, and goes only while it still
  /// flashes (a steady red after it holds the car again).
  Duration flash_window = std::chrono::milliseconds(800);
  /// At a stop sign it goes only when its LIDAR sees nothing in the intersection's box (its
  /// tile, less this margin): a vehicle crossing has the right of way. At a green light it
  /// gives way the same way to what is in the box before it crosses the stop line.
  double box_margin_m = 0.03;
  double lidar_x_m = 0.1445;  ///< the LIDAR ahead of the rear axle (NIGEL.md)
  std::uint64_t seed = 1;
  /// A route: lanes in the order it should drive them. At each choice it takes the movement
  /// or successor onto the next lane of the route it has not reached yet; past the route (or
  /// where no choice leads to that lane) it chooses at random as without one.
  std::vector<LaneId> route;
  /// With a route: stop at the end of its last lane (the goal) instead of driving on.
  bool stop_at_route_end = false;
  /// Faults on purpose, so that what judges a driver (the scenario runner's metrics) can be
  /// tested against a driver known to commit them: drive through red lights (and without
  /// giving way at green), roll through stop signs, ignore what the LIDAR sees ahead, and
  /// keep this far left of the lane centres (negative: right).
  bool ignore_lights = false;
  bool ignore_stop_signs = false;
  bool ignore_obstacles = false;
  double lateral_offset_m = 0.0;
};

/// What the driver decided, and why (for logs and tests).
struct DriverDecision {
  double throttle = 0.0;  ///< normalised
  double steering = 0.0;  ///< normalised, positive left
  enum class Reason {
    kCruise,
    kRedLight,
    kStopSign,
    kGiveWay,  ///< at a green light, for what is in the intersection's box
    kObstacle,
    kAdvisory,  ///< held to the speed asked of `Step` (e.g. GLOSA's)
    kGoal,      ///< at the end of its route (`stop_at_route_end`)
    kLost
  } reason = Reason::kCruise;
};

/// One car's driver. Copy: yes (value type over a borrowed map); the map must outlive it.
class LaneDriver {
 public:
  LaneDriver(const maps::Map& map, const DriverOptions& options);

  /// The command for now. `X_MV`: the car's rear axle in the map frame. `lamp(head)`: what a
  /// signal head shows (0 off, 1 red, 2 yellow, 3 green), absent when unknown (treated as
  /// red). `lidar`: the newest scan's ranges, beam i at i degrees counter-clockwise from the
  /// car's front (Nigel's LIDAR as published), empty when there is none.
  DriverDecision Step(const RigidTransform2& X_MV,
                      const std::function<std::optional<std::int32_t>(SignalHeadId)>& lamp,
                      std::span<const float> lidar, Duration now);

  /// The same, with the signals from `signal` (e.g. SPaT): a yellow is crossed when the car's
  /// tail can pass the line before it ends (at its present speed) or it is too close to stop,
  /// and stopped at otherwise; dark is a stop sign, as flashing red is; flashing yellow is a
  /// green that gives way. `speed_limit_mps`, when given, caps its speed (an advisory).
  DriverDecision Step(const RigidTransform2& X_MV, const SignalLookup& signal,
                      std::span<const float> lidar, Duration now,
                      std::optional<double> speed_limit_mps = std::nullopt);

  /// The next stop line on its route (within `plan_ahead_m`), as of the last step.
  [[nodiscard]] std::optional<StopLineAhead> NextStopLine() const;
  /// Whether the car's body (rear to front bumper) overlaps a path through `x`, as of the
  /// last step.
  [[nodiscard]] bool InIntersection(IntersectionId x) const;
  /// Its speed along the route (m/s), from its progress over the last steps.
  [[nodiscard]] double speed_mps() const { return speed_mps_; }

  /// The lane the car is on or heading to (for logs), empty before the first step.
  [[nodiscard]] std::string lane_name() const;

 private:
  struct Piece {
    const maps::Polyline* path = nullptr;
    const maps::Lane* lane = nullptr;          ///< a lane, or
    const maps::Movement* movement = nullptr;  ///< a movement through an intersection
    double start_s = 0.0;                      ///< arc length of the route where this piece starts
  };
  void Localise(const RigidTransform2& X_MV);
  void Extend();
  // Appends a lane to the route, counting it when it is the next lane of options_.route.
  void PushLane(const maps::Lane& lane, double start_s);
  // The lane of options_.route to make for next, if any.
  [[nodiscard]] std::optional<LaneId> NextRouteLane() const;
  // Whether the route's last lane is the last piece and the car is to stop at its end.
  [[nodiscard]] bool AtRouteEnd() const;
  // Point of the route at arc length s, and the arc length of the route point nearest to p.
  [[nodiscard]] Eigen::Vector2d PointAt(double s) const;
  [[nodiscard]] double Project(const Eigen::Vector2d& p) const;
  [[nodiscard]] double PieceLength(const Piece& piece) const;
  [[nodiscard]] bool BoxClear(const maps::Intersection& x, const RigidTransform2& X_MV,
                              std::span<const float> lidar) const;
  // The gap from its front bumper, along its route, to the nearest LIDAR point on its path
  // within `range` of it (infinity when there is none).
  [[nodiscard]] double GapAhead(const RigidTransform2& X_MV, std::span<const float> lidar,
                                double front_s, double range) const;

  const maps::Map* map_;
  DriverOptions options_;
  std::mt19937_64 rng_;
  std::deque<Piece> route_;
  double progress_s_ = 0.0;  // arc length of the rear axle along the route
  // A full stop at the stop line at route arc length `line_s` (a stop sign, or a flashing
  // red): waits, then marks the line done once the box is clear. Whether to stop still.
  bool StopSign(double line_s, const maps::Intersection& x, double to_line,
                const RigidTransform2& X_MV, std::span<const float> lidar, Duration now);
  // Notes what head `h` shows now; whether it is flashing red (red and dark within
  // `flash_window`).
  bool FlashingRed(SignalHeadId h, std::optional<std::int32_t> wire, Duration now);

  std::optional<Duration> stopped_at_sign_since_;
  // The stop line (its route arc length) already stopped at: each pass past a line is its own.
  std::optional<double> sign_done_at_s_;
  struct LampSeen {
    std::optional<Duration> red, dark;  // when last seen red, dark
  };
  std::map<SignalHeadId, LampSeen> seen_;
  std::size_t route_next_ = 0;  // index of the next lane of options_.route
  // For the speed: the progress and time of the last step.
  std::optional<Duration> last_step_;
  double last_progress_s_ = 0.0;
  double speed_mps_ = 0.0;
  std::optional<StopLineAhead> next_line_;
};

}  // namespace autodrive::vehicle_sim
