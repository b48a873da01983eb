#include "examples/v2i/agent.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/program_options.h"
#include "common/error.h"
#include "common/geometry.h"
#include "common/logging.h"
#include "common/shutdown.h"
#include "examples/common/agent_options.h"
#include "examples/common/car_io.h"
#include "examples/v2i/glosa.h"
#include "examples/v2i/requests.h"
#include "examples/v2i/v2i_view.h"
#include "maps/map_io.h"
#include "vehicle_sim/lane_driver.h"
#include "vehicle_sim/sim_config.h"

namespace autodrive::examples {

namespace {

using Reason = vehicle_sim::DriverDecision::Reason;

struct Names {
  const char* program;
  const char* enclave;
  const char* what;
};

Names NamesOf(AgentKind kind) {
  switch (kind) {
    case AgentKind::kFollower:
      return {"autodrive-example-follower", "/autodrive/example_follower",
              "a signal-aware lane follower: drives one car along its route on the map's lanes, "
              "stopping at red and at a yellow it cannot clear as SPaT gives them"};
    case AgentKind::kGlosa:
      return {"autodrive-example-glosa", "/autodrive/example_glosa",
              "the lane follower with green-light optimal speed advice (GLOSA): from SPaT's times "
              "it slows down ahead of a red to arrive as the green starts"};
    case AgentKind::kEmergency:
      return {"autodrive-example-emergency", "/autodrive/example_emergency",
              "an emergency vehicle: the lane follower asking every signal on its route for "
              "pre-emption as it comes near, and cancelling once through"};
    case AgentKind::kTransit:
      return {"autodrive-example-transit", "/autodrive/example_transit",
              "a bus: the lane follower asking every signal on its route for priority (a green "
              "extended or brought forward) as it comes near, and cancelling once through"};
  }
  return {"?", "?", "?"};
}

const char* ToString(Reason r) {
  switch (r) {
    case Reason::kCruise:
      return "driving";
    case Reason::kRedLight:
      return "stopping at a red light";
    case Reason::kStopSign:
      return "stopping as at a stop sign";
    case Reason::kGiveWay:
      return "giving way to a vehicle in the intersection";
    case Reason::kObstacle:
      return "keeping its distance to what is ahead";
    case Reason::kAdvisory:
      return "slowing down for the next green (GLOSA)";
    case Reason::kGoal:
      return "stopped at the end of its route";
    case Reason::kLost:
      return "off the lanes";
  }
  return "?";
}

}  // namespace

int RunAgent(int argc, char** argv, AgentKind kind) {
  const Names names = NamesOf(kind);
  CLI::App app{std::string(names.program) + ": " + names.what +
               ". Uses only public topics: the car's devkit topics (ips, imu, lidar; "
               "throttle_command, steering_command) and the SCM's map and spat" +
               (kind == AgentKind::kEmergency || kind == AgentKind::kTransit
                    ? ", signal_request and signal_request_status"
                    : "") +
               ". See examples/README.md."};
  std::string city_path, vehicle;
  std::vector<std::string> route;
  bool stop_at_end = false;
  double throttle = 0.6;
  std::uint64_t seed = 1;
  GlosaParams glosa;
  RequestParams requests;
  requests.kind = kind == AgentKind::kEmergency ? RequestParams::Kind::kPreemption
                                                : RequestParams::Kind::kPriority;
  AgentOptions agent(names.enclave, 20.0);
  app.add_option("--city", city_path,
                 "city file: its map, and the car's figures from its sim section when it has "
                 "the car (else Nigel's)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--vehicle", vehicle, "the car to drive: nigel_<n>")->required();
  app.add_option("--route", route,
                 "lanes to drive in order (LANE[,LANE...], as autodrive-map info names them); "
                 "past them it chooses at random")
      ->delimiter(',');
  app.add_flag("--stop-at-route-end", stop_at_end,
               "stop at the end of the route's last lane (its goal) instead of driving on");
  app.add_option("--throttle", throttle, "cruising throttle (normalised)")
      ->check(CLI::Range(0.05, 1.0))
      ->capture_default_str();
  app.add_option("--seed", seed, "seed of the choices past its route")->capture_default_str();
  if (kind == AgentKind::kGlosa) {
    app.add_option("--horizon-m", glosa.horizon_m,
                   "advise from this far before a signalised stop line (front bumper)")
        ->check(CLI::Range(0.2, 50.0))
        ->capture_default_str();
    app.add_option("--min-speed-mps", glosa.min_speed_mps, "the slowest speed advised")
        ->check(CLI::Range(0.0, 5.0))
        ->capture_default_str();
    app.add_option("--margin-s", glosa.margin_s,
                   "arrive this long after the green is expected to start")
        ->check(CLI::Range(0.0, 30.0))
        ->capture_default_str();
  }
  if (kind == AgentKind::kEmergency || kind == AgentKind::kTransit) {
    app.add_option("--request-horizon-m", requests.horizon_m,
                   "ask a signal when the front is this close to its stop line")
        ->check(CLI::Range(0.1, 50.0))
        ->capture_default_str();
  }
  std::string pose_source = "ips";
  app.add_option("--pose", pose_source,
                 "where its pose comes from: ips (its devkit ips and imu topics: the lab's "
                 "positioning system, the simulator's ground truth in the twin) or eye (the Eye's "
                 "fleet, /autodrive/eye/fleet: the overhead camera's measurement)")
      ->check(CLI::IsMember({"ips", "eye"}))
      ->capture_default_str();
  agent.Add(app);
  CLI11_PARSE(app, argc, argv);
  // The signals first, before anything can start a thread (agent_options.h).
  std::atomic<bool> stop{false};
  ShutdownSignals signals([&] { stop.store(true); });

  try {
    InitLogging(names.program, ParseLogLevel(agent.log_level));
    const VehicleId id = ParseVehicleName(vehicle);
    const vehicle_sim::SimCity city = vehicle_sim::LoadSimCity(city_path);
    const maps::Map map = maps::LoadMapOrLayout(city.map_path);
    vehicle_sim::VehicleParams params;
    const auto in_sim = std::find_if(city.sim.vehicles.begin(), city.sim.vehicles.end(),
                                     [&](const auto& v) { return v.name == vehicle; });
    if (in_sim != city.sim.vehicles.end()) {
      params = in_sim->params;
    } else {
      spdlog::info("{} is not in {}'s sim section: Nigel's figures", vehicle, city_path);
    }
    vehicle_sim::DriverOptions options;
    for (const std::string& lane : route) {
      const maps::Lane* l = map.FindLane(lane);
      if (l == nullptr) {
        throw InputError("--route: map " + map.name + " has no lane \"" + lane +
                         "\" (autodrive-map info lists them)");
      }
      options.route.push_back(l->id);
    }
    options.stop_at_route_end = stop_at_end;
    options.cruise_throttle = throttle;
    options.seed = seed;
    options.wheelbase_m = params.wheelbase_m;
    options.steering_limit_rad = params.steering_limit_rad;
    options.front_overhang_m = params.body_centre_ahead_of_rear_axle_m + params.body_length_m / 2;
    options.rear_overhang_m = params.body_length_m / 2 - params.body_centre_ahead_of_rear_axle_m;
    options.half_width_m = params.body_width_m / 2;
    options.top_speed_mps = params.top_speed_mps;
    glosa.cruise_mps = throttle * params.top_speed_mps;
    if (kind == AgentKind::kGlosa) options.plan_ahead_m = glosa.horizon_m + 0.5;
    glosa.body_length_m = params.body_length_m;
    requests.cruise_mps = throttle * params.top_speed_mps;

    dds::Participant participant(agent.dds.Participant());
    vehicle_sim::LaneDriver driver(map, options);
    V2iView v2i(participant);
    std::unique_ptr<SignalRequester> requester;
    if (kind == AgentKind::kEmergency || kind == AgentKind::kTransit) {
      requester = std::make_unique<SignalRequester>(participant, vehicle, requests);
    }
    CarIo io(participant, id, pose_source == "eye" ? PoseSource::kEye : PoseSource::kIps);
    Reason reason = Reason::kLost;
    bool map_checked = false;
    bool advising = false;  // GLOSA's advice in force at the last step

    // One decision from what the topics brought since the last; `now` is the system time.
    const auto decide = [&](Time now) {
      v2i.Poll();
      if (!map_checked && v2i.has_map()) {
        map_checked = true;
        if (v2i.map_name() != map.name) {
          spdlog::warn("the SCM's MAP is of map \"{}\", this car drives on \"{}\"", v2i.map_name(),
                       map.name);
        }
      }
      io.Take();
      const std::optional<RigidTransform2> X = io.pose();
      if (!X) return;
      const vehicle_sim::SignalLookup spat = [&](const maps::Lane& ingress,
                                                 const maps::Movement* movement) {
        return v2i.Indication(ingress, movement, now);
      };
      // GLOSA's advice for the next signalised line (as of the last step).
      std::optional<double> advice;
      if (kind == AgentKind::kGlosa) {
        if (const auto ahead = driver.NextStopLine();
            ahead && ahead->intersection->control == maps::Control::kSignal) {
          if (const auto shown = v2i.Indication(*ahead->ingress, ahead->movement, now)) {
            advice = GlosaSpeed(glosa, ahead->to_line_m, *shown);
            if (advice.has_value() != advising) {
              spdlog::debug(
                  "{}: {:.2f} m before the line of {}, green in {} s: {}", vehicle,
                  ahead->to_line_m, ahead->ingress->name,
                  GreenStartsIn(*shown) ? fmt::format("{:.1f}", *GreenStartsIn(*shown))
                                        : std::string("?"),
                  advice ? fmt::format("advising {:.3f} m/s", *advice) : std::string("no advice"));
            }
          }
        }
        advising = advice.has_value();
      }
      const auto decision = driver.Step(*X, spat, io.scan(), now - Time{}, advice);
      io.Command(decision.throttle, decision.steering);
      if (requester) requester->Step(driver, v2i, now);
      if (decision.reason != reason) {
        std::string line;
        if (const auto ahead = driver.NextStopLine()) {
          const auto shown = v2i.Indication(*ahead->ingress, ahead->movement, now);
          line = fmt::format(" ({:.3f} m before the line of {}, {:.3f} m/s, signal {})",
                             ahead->to_line_m, ahead->ingress->name, driver.speed_mps(),
                             shown ? static_cast<int>(shown->state) : -1);
        }
        spdlog::debug("{}: {} on {} at {:.2f} s{}", vehicle, ToString(decision.reason),
                      driver.lane_name(), ToSeconds(now - Time{}), line);
        reason = decision.reason;
      }
    };
    spdlog::info("{} drives {} on map {}{}", names.program, vehicle, map.name,
                 agent.lockstep.empty() ? "" : " in lockstep as controller " + agent.lockstep);
    const int code = io.Run(participant, agent.lockstep, agent.rate_hz, decide, stop);
    if (requester) {
      const RequestCounts& c = requester->counts();
      spdlog::info(
          "{}: requests sent {}, updates {}, cancels {}; answers: granted {}, rejected "
          "{}, completed {}, cancelled {}",
          vehicle, c.sent, c.updates, c.cancels, c.granted, c.rejected, c.completed, c.cancelled);
    }
    return code;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", names.program, e.what());
    return 1;
  }
}

}  // namespace autodrive::examples
