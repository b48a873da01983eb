#pragma once
/// @file
/// The metrics of a run, computed from what the world was (`RunWorld`, the run folder's
/// `logs/world.json`) and the raw logs (ground truth, lamps, SPaT, traffic, requests), never
/// from anything an agent reports. Every metric's definition, its 1:14 scaling and the
/// reference it follows are in docs/scenarios.md ("Metrics").

#include <cmath>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace autodrive::scenarios {

using Points = std::vector<Eigen::Vector2d>;

/// What the world was during a run: everything the metrics measure against, from the map, the
/// simulator's section (perturbed walls, unmapped obstacles, the cars' bodies) and the
/// scenario (routes). Written as `logs/world.json` so that another tool can recompute.
struct RunWorld {
  struct Car {
    std::string name;
    double length_m = 0.318;  ///< the body's footprint (its collision box)
    double width_m = 0.175;
    double centre_ahead_m = 0.07077;  ///< the footprint's centre ahead of the rear axle
    double top_speed_mps = 0.26;      ///< free-flow speed for delay and time loss
    Points route;  ///< the route's centre line (lanes and movements); empty: none
    double goal_tolerance_m = 0.15;
    /// A goal pose (x, y, yaw of the rear axle) instead of the route's end, and its heading
    /// tolerance (its distance tolerance is `goal_tolerance_m`).
    std::optional<Eigen::Vector3d> goal_pose{};
    double goal_tolerance_rad = 0.0873;
    /// With laps: the distance along `route` at which each lap ends (the last: its length).
    std::vector<double> lap_ends_m{};
    /// Whether it has a goal (a route, or a goal pose).
    [[nodiscard]] bool HasGoal() const { return goal_pose.has_value() || !route.empty(); }
    /// Whether the car with its rear axle at (x, y) heading `yaw` is at its goal (standing still
    /// there is for the caller to say): its front within `goal_tolerance_m` of the route's end,
    /// or its rear axle within `goal_tolerance_m` and `goal_tolerance_rad` of the goal pose.
    [[nodiscard]] bool AtGoal(double x_m, double y_m, double yaw_rad) const {
      if (goal_pose) {
        return (Eigen::Vector2d(x_m, y_m) - goal_pose->head<2>()).norm() <= goal_tolerance_m &&
               std::abs(std::remainder(yaw_rad - goal_pose->z(), 2 * 3.14159265358979323846)) <=
                   goal_tolerance_rad;
      }
      return !route.empty() &&
             (FrontAt(x_m, y_m, yaw_rad) - route.back()).norm() <= goal_tolerance_m;
    }
    /// The middle of its front bumper for its rear axle at (x, y) heading `yaw` (map frame).
    [[nodiscard]] Eigen::Vector2d FrontAt(double x_m, double y_m, double yaw_rad) const {
      return Eigen::Vector2d(x_m, y_m) + (centre_ahead_m + length_m / 2) *
                                             Eigen::Vector2d(std::cos(yaw_rad), std::sin(yaw_rad));
    }
  };
  struct Static {
    std::string kind;  ///< "wall", "box" (the map's), "pole" (a signal head's or a sign's) or
                       ///< "obstacle" (unmapped)
    std::string name;
    Points footprint;  ///< counter-clockwise
    /// It stands from `from_s` until `until_s` (simulated seconds; none: to the end): an
    /// unmapped obstacle placed or removed by the scenario's events.
    double from_s = 0.0;
    std::optional<double> until_s{};
    /// Whether it stands at `t` (to a nanosecond: the simulator's clock).
    [[nodiscard]] bool StandsAt(double t) const {
      return t + 1e-9 >= from_s && (!until_s || t + 1e-9 < *until_s);
    }
  };
  struct StopLine {
    std::string lane;
    std::string intersection;
    std::string control;          ///< "signal" or "stop"
    std::vector<int> heads;       ///< the heads facing this lane's approach (signal)
    Eigen::Vector2d left, right;  ///< the line's ends as seen driving along the lane
    Eigen::Vector2d direction;    ///< unit, the lane's direction of travel at its end
  };
  struct Lane {
    std::string name;  ///< a lane, or a movement through an intersection
    double width_m = 0.0;
    Points centreline;
  };
  /// The heads that show a signal group (for SPaT's prediction error against the lamps).
  struct GroupHeads {
    int intersection = 0;
    int group = 0;
    std::vector<int> heads;
  };
  struct Request {
    int intersection = 0;
    int in_lane = 0;         ///< MAP lane id (the map's lane id)
    std::vector<int> heads;  ///< the heads facing that lane's approach
  };
  std::vector<Car> cars;
  std::vector<Static> statics;
  std::vector<StopLine> stop_lines;
  std::vector<Lane> lanes;
  /// Floors without lanes, where a car may drive anywhere (the map's open and parking tiles, as
  /// axis-aligned squares): a car on one is on no lane, and departs none.
  struct Floor {
    Eigen::Vector2d min, max;
    [[nodiscard]] bool Contains(const Eigen::Vector2d& p) const {
      return p.x() >= min.x() && p.y() >= min.y() && p.x() <= max.x() && p.y() <= max.y();
    }
  };
  std::vector<Floor> open_floors;
  std::vector<GroupHeads> groups;
  /// Each ingress lane by (intersection id, its lane id in the intersection's MAP message):
  /// the heads facing it.
  std::map<std::pair<int, int>, Request> ingress;
  double end_s = 0.0;  ///< the run's last step

  [[nodiscard]] nlohmann::json ToJson() const;
  [[nodiscard]] static RunWorld FromJson(const nlohmann::json& j);
};

/// The constants the metrics use (docs/scenarios.md gives each its source and scaling).
struct MetricConstants {
  double contact_m = 0.005;    ///< bodies this close touch
  double separation_m = 0.02;  ///< a contact ends once this far apart for `rearm_s`
  double rearm_s = 0.5;
  double stopped_mps = 0.01;       ///< below: stopped (CARLA 0.1 m/s / 14)
  double moving_mps = 0.05;        ///< above: moving again (a new stop may begin)
  double stop_zone_m = 0.3;        ///< a full stop must be within this of the stop line (4 m / 14)
  double departure_rearm_s = 0.5;  ///< a lane departure ends after this long back on a lane
  double scale = 14.0;             ///< lab to full scale (infractions per km)
  /// A route point counts as passed within this distance (CARLA's 10 m / 14).
  double route_tolerance_m = 10.0 / 14.0;
  /// The goal at a route's end counts only with the route passed to within this of its end (a
  /// closed route driven in laps passes its end point every lap).
  double goal_progress_m = 1.0;
  double rolling_resistance = 0.02;  ///< energy proxy's rolling term
};

/// A car's progress along its route as the metrics measure it (`route_completion`): the
/// furthest point of the route its rear axle passed within `route_tolerance_m`, moving at most
/// 0.5 m ahead at a time; and whether it is at its goal, which needs the route driven to within
/// `goal_progress_m` of its end (a closed route driven in laps passes its end every lap). The
/// runner ends a run by it as the metrics judge it.
class RouteProgress {
 public:
  RouteProgress(const RunWorld::Car& car, const MetricConstants& k);
  /// The car's rear axle is at (x, y).
  void Update(double x_m, double y_m);
  [[nodiscard]] double progress_m() const { return progress_; }
  [[nodiscard]] double length_m() const { return length_; }
  /// At the route's end, having driven it; the car at (x, y) heading `yaw`.
  [[nodiscard]] bool AtGoal(double x_m, double y_m, double yaw_rad) const;

 private:
  const RunWorld::Car* car_;
  double tolerance_m_;
  double goal_progress_m_;
  double length_;
  double progress_ = 0.0;
};

/// Computes every metric: `{"vehicles": {name: {...}}, "run": {...}, "v2i": {...}}`.
/// @throws InputError for a log that cannot be read or parsed (naming the file and line).
[[nodiscard]] nlohmann::json ComputeMetrics(const RunWorld& world,
                                            const std::filesystem::path& logs_dir,
                                            const MetricConstants& k = {});

/// SUMO's trip statistics of the background cars (its `--tripinfo-output`, every car that
/// departed, those still driving at the end included), in a run's logs folder.
inline constexpr std::string_view kTripinfoFile = "sumo_tripinfo.xml";

/// SUMO's own trip statistics of the background cars, from its `--tripinfo-output` file (the
/// lab's cars, which SUMO also drives as stand-ins, named in `lab_cars`, left out):
/// `{"trips", "arrived", "waiting_time_s": {"mean", "max"}, "waiting_count", "time_loss_s":
/// {"mean", "max"}, "per_car": {id: {...}}}` (SUMO's definitions, seconds of simulated time; a
/// car still driving at the end counts with what it had so far). Null when the file is absent
/// (no SUMO in the run); `{"unfinished": why}` when SUMO did not finish it (killed).
/// @throws InputError for a file that is not SUMO's tripinfo XML (naming it and the fault).
[[nodiscard]] nlohmann::json SumoTripStatistics(const std::filesystem::path& tripinfo_file,
                                                const std::set<std::string>& lab_cars);

/// The corners of a rectangle (counter-clockwise) of `length` along `yaw` and `width` across,
/// centred at `centre`.
[[nodiscard]] Points Rectangle(const Eigen::Vector2d& centre, double yaw, double length,
                               double width);

/// The distance between two convex polygons (0 when they overlap).
[[nodiscard]] double PolygonDistance(const Points& a, const Points& b);

}  // namespace autodrive::scenarios
