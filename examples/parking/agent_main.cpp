// autodrive-example-parking: the parking case study as a driving agent: plans a path to a goal
// pose with hybrid A* on the map's occupancy grid, tracks it (tracker.h), and, when its LIDAR
// sees something the map does not have on the path ahead, stops, adds it to the grid and plans
// again. Its pose from the car's ips and imu (the lab's positioning system) or the Eye. See
// README.md.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/dds/conversions.h"
#include "common/dds/participant.h"
#include "common/dds/program_options.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/error.h"
#include "common/logging.h"
#include "common/shutdown.h"
#include "examples/common/agent_options.h"
#include "examples/common/car_io.h"
#include "examples/parking/hybrid_astar.h"
#include "examples/parking/local_planner.h"
#include "examples/parking/localiser.h"
#include "examples/parking/parking_config.h"
#include "examples/parking/tracker.h"
#include "maps/map_io.h"
#include "maps/occupancy.h"
#include "vehicle_sim/sensors.h"
#include "vehicle_sim/sim_config.h"

using namespace autodrive;

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-example-parking: drives one car to a goal pose (e.g. into a parking bay, "
      "backwards if need be): hybrid A* on the map's occupancy grid, pure-pursuit tracking, and "
      "a new plan round what its LIDAR sees that the map has not. Public topics only: the car's "
      "ips, imu (or the Eye's fleet), lidar, throttle_command and steering_command. See "
      "examples/parking/README.md."};
  std::string city_path, vehicle, pose_source = "ips";
  std::vector<double> goal_v;
  std::string config_path;
  std::optional<double> margin, throttle;
  examples::AgentOptions agent("/autodrive/example_parking", 20.0);
  app.add_option("--city", city_path, "city file: its map, the car's figures from its sim section")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--vehicle", vehicle, "the car to drive: nigel_<n>")->required();
  app.add_option("--goal", goal_v, "the goal: the rear axle's pose X,Y,YAW (m, m, rad)")
      ->required()
      ->delimiter(',');
  std::string trace_path, slam_prefix;
  app.add_option("--pose", pose_source,
                 "ips (its ips and imu), eye (the Eye's fleet), or pf (its own: a particle filter "
                 "on its encoders, imu and LIDAR, started from the first ips fix)")
      ->check(CLI::IsMember({"ips", "eye", "pf"}))
      ->capture_default_str();
  std::string filter_map = "built";
  app.add_option("--filter-map", filter_map,
                 "with --pose pf, what the filter weighs the LIDAR against: built (the map its "
                 "SLAM builds from the config's localiser.mapping_scans scans at the first fix "
                 "before it drives: the world as it stands) or city (the city map's grid)")
      ->check(CLI::IsMember({"built", "city"}))
      ->capture_default_str();
  app.add_option("--config", config_path,
                 "its tunables (planner, tracker, localiser, obstacles, arrival) from this YAML "
                 "file; what it leaves out keeps the defaults, which are "
                 "examples/parking/parking.yaml's")
      ->check(CLI::ExistingFile);
  app.add_option("--trace", trace_path,
                 "with --pose pf: a CSV of its estimates at each decision (t_s, the filter's "
                 "and SLAM's poses, the particles), to compare with the ground truth");
  app.add_option("--slam-map", slam_prefix,
                 "with --pose pf: at the end, SLAM's map as PREFIX.pgm and PREFIX.yaml (ROS "
                 "map_server's format) and its agreement with the map's grid on the log");
  app.add_option("--margin", margin,
                 "kept clear round the body (m), over the config's planner.margin_m (0.03)")
      ->check(CLI::Range(0.0, 0.3));
  app.add_option("--throttle", throttle,
                 "cruising throttle (normalised), over the config's tracker.cruise_throttle (0.5)")
      ->check(CLI::Range(0.1, 1.0));
  agent.Add(app);
  CLI11_PARSE(app, argc, argv);
  // The signals first, before anything can start a thread (agent_options.h).
  std::atomic<bool> stop{false};
  ShutdownSignals signals([&] { stop.store(true); });
  try {
    InitLogging("autodrive-example-parking", ParseLogLevel(agent.log_level));
    if (goal_v.size() != 3) throw InputError("--goal: give X,Y,YAW (m, m, rad)");
    examples::ParkingConfig tuning =
        config_path.empty() ? examples::ParkingConfig{} : examples::LoadParkingConfig(config_path);
    if (margin) tuning.planner.margin_m = *margin;
    if (throttle) tuning.tracker.cruise_throttle = *throttle;
    examples::HybridAStarParams& plan_params = tuning.planner;
    examples::TrackerParams& track_params = tuning.tracker;
    const examples::ObstacleParams& seen_params = tuning.obstacles;
    const examples::ArrivalParams& arrival = tuning.arrival;
    const RigidTransform2 goal = RigidTransform2::FromXyYaw(goal_v[0], goal_v[1], goal_v[2]);
    const VehicleId id = ParseVehicleName(vehicle);
    const vehicle_sim::SimCity city = vehicle_sim::LoadSimCity(city_path);
    const maps::Map map = maps::LoadMapOrLayout(city.map_path);
    vehicle_sim::VehicleParams car;
    double lidar_x = vehicle_sim::LidarConfig{}.x_m;  // the LIDAR ahead of the rear axle
    for (const auto& v : city.sim.vehicles) {
      if (v.name != vehicle) continue;
      car = v.params;
      lidar_x = v.sensors.lidar.x_m;
    }
    if (pose_source != "pf" && (!trace_path.empty() || !slam_prefix.empty())) {
      throw InputError("--trace and --slam-map go with --pose pf");
    }
    plan_params.wheelbase_m = track_params.wheelbase_m = car.wheelbase_m;
    plan_params.steering_limit_rad = track_params.steering_limit_rad = car.steering_limit_rad;
    plan_params.length_m = car.body_length_m;
    plan_params.width_m = car.body_width_m;
    plan_params.centre_ahead_m = car.body_centre_ahead_of_rear_axle_m;
    const maps::OccupancyGrid mapped = maps::MakeOccupancyGrid(map, 0.025, false);
    examples::HybridAStar planner(mapped, plan_params);
    examples::PathTracker tracker(track_params);

    dds::Participant participant(agent.dds.Participant());
    examples::CarIo io(
        participant, id,
        pose_source == "eye" ? examples::PoseSource::kEye : examples::PoseSource::kIps);
    // Its own localisation (--pose pf): encoders and the imu's heading for odometry, the LIDAR.
    std::unique_ptr<examples::Localiser> localiser;
    std::unique_ptr<dds::Reader<msg::JointState>> left_encoder, right_encoder;
    std::optional<double> left_angle, right_angle;
    std::optional<Time> encoder_time;
    const maps::OccupancyGrid* built = nullptr;  // the map it built at its first fix
    std::ofstream trace;
    if (pose_source == "pf") {
      examples::LocaliserParams lp = tuning.localiser;
      lp.wheel_radius_m = car.wheel_radius_m;
      lp.filter.lidar_x_m = lidar_x;
      if (filter_map == "city") lp.mapping_scans = 0;
      localiser = std::make_unique<examples::Localiser>(mapped, lp);
      left_encoder =
          std::make_unique<dds::Reader<msg::JointState>>(participant, dds::topics::LeftEncoder(id));
      right_encoder = std::make_unique<dds::Reader<msg::JointState>>(participant,
                                                                     dds::topics::RightEncoder(id));
      if (!trace_path.empty()) {
        trace.open(trace_path);
        if (!trace) throw InputError(trace_path + ": cannot write the trace");
        trace << "t_s,x_m,y_m,yaw_rad,slam_x_m,slam_y_m,slam_yaw_rad,particles\n";
      }
    }

    enum class Phase { kWaiting, kDriving, kBlocked, kParked } phase = Phase::kWaiting;
    std::optional<RigidTransform2> last_pose;
    std::optional<Time> last_time, blocked_since;
    double speed = 0.0;
    int replans = 0;
    int corrections = 0;
    float last_first = -1.0f;  // a new scan, told by its first range (a cheap change test)
    const auto plan = [&](const RigidTransform2& from) {
      examples::PlanResult p = planner.Plan(from, goal);
      if (p.path.empty()) {
        // Stopped close to something it has just seen, the car may have no way out with the
        // whole margin: half of it, for this plan only.
        planner.SetMargin(plan_params.margin_m / 2);
        p = planner.Plan(from, goal);
        planner.SetMargin(plan_params.margin_m);
        if (!p.path.empty()) {
          spdlog::info("{}: no path with a {:.0f} mm margin; with {:.0f} mm:", vehicle,
                       plan_params.margin_m * 1000, plan_params.margin_m * 500);
        }
      }
      if (p.path.empty()) {
        spdlog::warn("{}: no path to the goal: {}", vehicle, p.failure);
        return false;
      }
      spdlog::info("{}: a path of {:.2f} m with {} gear changes ({} expansions)", vehicle,
                   p.length_m, p.gear_changes, p.expansions);
      tracker.SetPath(p.path);
      return true;
    };
    const auto decide = [&](Time now) {
      io.Take();
      const auto scan = io.scan();
      const bool new_scan = !scan.empty() && scan[0] != last_first;
      if (new_scan) last_first = scan[0];
      std::optional<RigidTransform2> X = io.pose();
      if (localiser) {
        // The filter's pose, started from the first ips fix; the ips is not used after.
        if (!X && !localiser->started()) return;
        if (!localiser->started()) localiser->Start(*X);
        const auto angle = [&](dds::Reader<msg::JointState>& r, std::optional<double>& out) {
          while (auto m = r.TakeOne()) {
            if ((*m)->position._length == 0) continue;
            out = (*m)->position._buffer[0];
            encoder_time =
                std::max(encoder_time.value_or(Time{}), dds::FromMsg((*m)->header.stamp));
          }
        };
        angle(*left_encoder, left_angle);
        angle(*right_encoder, right_angle);
        if (left_angle && right_angle && X)
          localiser->Odometry(*encoder_time, *left_angle, *right_angle, X->yaw());
        if (new_scan) localiser->Scan(io.scan_stamp(), io.scan_increment_s(), scan);
        if (!localiser->ready()) {  // standing while it maps
          io.Command(0.0, 0.0);
          return;
        }
        if (localiser->built_map() && !built) {
          // What it saw standing at the fix goes into the planner's grid (the walls where they
          // stand, the boxes in sight), and is not news when the LIDAR sees it again.
          built = &*localiser->built_map();
          std::vector<Eigen::Vector2d> seen;
          for (int r = 0; r < built->height; ++r) {
            for (int c = 0; c < built->width; ++c) {
              if (!built->IsFree(c, r)) seen.push_back(built->CellCentre(c, r));
            }
          }
          planner.AddObstacles(seen, 0.0);
          spdlog::info("{}: mapped {} occupied cells standing at its first fix{}", vehicle,
                       seen.size(),
                       localiser->mapping_restarts() == 0
                           ? ""
                           : fmt::format(" (begun again {} times: it moved while mapping)",
                                         localiser->mapping_restarts()));
        }
        X = localiser->Estimate();
        if (trace.is_open()) {
          const RigidTransform2& S = localiser->SlamPose();
          trace << fmt::format("{:.3f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{}\n",
                               ToSeconds(now.time_since_epoch()), X->translation().x(),
                               X->translation().y(), X->yaw(), S.translation().x(),
                               S.translation().y(), S.yaw(), localiser->filter().size());
        }
      }
      if (!X) return;
      if (last_pose && last_time && now > *last_time) {
        const double v =
            (X->translation() - last_pose->translation()).norm() / ToSeconds(now - *last_time);
        speed += 0.3 * (v - speed);
      }
      last_pose = X;
      last_time = now;
      if (phase == Phase::kWaiting) {
        phase = plan(*X) ? Phase::kDriving : Phase::kBlocked;
        blocked_since = now;
      }
      // A new scan: anything the map has not on the path's next metres stops the car and is
      // planned round.
      if (phase == Phase::kDriving && new_scan) {
        std::vector<Eigen::Vector2d> unmapped =
            examples::NewObstacles(scan, *X, lidar_x, mapped, built, seen_params);
        const std::vector<examples::PathPose> ahead = tracker.Ahead();
        const bool in_way = examples::InTheWay(unmapped, ahead, plan_params, seen_params.ahead_m);
        if (in_way) {
          Eigen::Vector2d lo = unmapped.front(), hi = unmapped.front();
          for (const Eigen::Vector2d& q : unmapped) {
            lo = lo.cwiseMin(q);
            hi = hi.cwiseMax(q);
          }
          spdlog::info(
              "{}: something unmapped on the path ahead ({} points in x {:.2f}..{:.2f}, y "
              "{:.2f}..{:.2f}): planning round it",
              vehicle, unmapped.size(), lo.x(), hi.x(), lo.y(), hi.y());
          // Not what lies against its own body (the LIDAR's noise, or a box it passes close by:
          // it is not touching it, and marking it would leave it no way out).
          std::erase_if(unmapped, [&](const Eigen::Vector2d& q) {
            return examples::AgainstBody(q, *X, plan_params, seen_params.body_clear_m);
          });
          planner.AddObstacles(unmapped, seen_params.mark_radius_m);
          phase = Phase::kBlocked;
          blocked_since = now;
        }
      }
      if (phase == Phase::kBlocked) {
        io.Command(0.0, 0.0);
        // Once standing, plan again (every second until a path is found).
        if (speed < track_params.stand_mps && blocked_since &&
            now - *blocked_since >= FromSeconds(arrival.replan_after_s)) {
          ++replans;
          if (plan(*X)) {
            phase = Phase::kDriving;
          } else {
            blocked_since = now + std::chrono::seconds(1) - FromSeconds(arrival.replan_after_s);
          }
        }
        return;
      }
      if (phase == Phase::kParked) {
        io.Command(0.0, 0.0);
        return;
      }
      const examples::TrackCommand c = tracker.Step(*X, speed);
      io.Command(c.throttle, c.steering);
      if (c.done) {
        // Further than the arrival's figures from the goal at the end: a correction.
        const double off_m = (X->translation() - goal.translation()).norm();
        const double off_rad = std::abs(WrapAngle(X->yaw() - goal.yaw()));
        if ((off_m > arrival.correct_beyond_m ||
             off_rad > arrival.correct_beyond_deg * std::numbers::pi / 180) &&
            corrections < arrival.corrections) {
          ++corrections;
          spdlog::info("{}: {:.1f} mm and {:.2f} deg from the goal: a correction", vehicle,
                       off_m * 1000, off_rad * 180 / std::numbers::pi);
          if (plan(*X)) return;
        }
        phase = Phase::kParked;
        spdlog::info("{}: parked {:.1f} mm and {:.2f} deg from the goal ({} new plans){}", vehicle,
                     (X->translation() - goal.translation()).norm() * 1000,
                     std::abs(WrapAngle(X->yaw() - goal.yaw())) * 180 / std::numbers::pi, replans,
                     localiser ? " by its own localisation" : "");
      }
    };
    spdlog::info("autodrive-example-parking drives {} to ({:.3f}, {:.3f}, {:.3f}) on map {}{}",
                 vehicle, goal_v[0], goal_v[1], goal_v[2], map.name,
                 agent.lockstep.empty() ? "" : " in lockstep as controller " + agent.lockstep);
    const int code = io.Run(participant, agent.lockstep, agent.rate_hz, decide, stop);
    if (localiser && localiser->started()) {
      const examples::MapAgreement a = examples::CompareMaps(localiser->slam(), mapped);
      spdlog::info("{}: SLAM's map: {:.1f}% of the {} cells it saw agree with the map's grid",
                   vehicle, a.share() * 100, a.seen);
      if (!slam_prefix.empty()) examples::WriteMapServerMap(localiser->slam(), slam_prefix);
    }
    return code;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-example-parking: %s\n", e.what());
    return 1;
  }
}
