// autodrive-example-driver: drives every car of a city along its lanes over DDS, as user code on
// the real cars would: from each car's devkit topics (ips, imu, lidar) and the lights' states
// (signal_<i>/state) to its throttle and steering commands. See examples/README.md.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/dds/lockstep.h"
#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/program_options.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "common/geometry.h"
#include "common/logging.h"
#include "common/shutdown.h"
#include "examples/common/agent_options.h"
#include "maps/district_domains.h"
#include "maps/districts.h"
#include "maps/map_io.h"
#include "vehicle_sim/lane_driver.h"
#include "vehicle_sim/sim_config.h"

namespace {

using namespace autodrive;
namespace topics = dds::topics;

struct Car {
  Car(const dds::Participant& p, VehicleId id, const maps::Map& map,
      const vehicle_sim::DriverOptions& options)
      : name(VehicleName(id)),
        driver(map, options),
        ips(p, topics::Ips(id)),
        imu(p, topics::Imu(id)),
        lidar(p, topics::Lidar(id)),
        throttle(p, topics::ThrottleCommand(id)),
        steering(p, topics::SteeringCommand(id)) {}
  std::string name;
  vehicle_sim::LaneDriver driver;
  dds::Reader<msg::Point> ips;
  dds::Reader<msg::Imu> imu;
  dds::Reader<msg::LaserScan> lidar;
  dds::Writer<msg::Float32> throttle, steering;
  std::optional<Eigen::Vector2d> position;
  std::optional<double> yaw;
  std::vector<float> scan;
  vehicle_sim::DriverDecision::Reason reason = vehicle_sim::DriverDecision::Reason::kLost;
};

const char* ToString(vehicle_sim::DriverDecision::Reason r) {
  switch (r) {
    case vehicle_sim::DriverDecision::Reason::kCruise:
      return "driving";
    case vehicle_sim::DriverDecision::Reason::kRedLight:
      return "stopping at a red light";
    case vehicle_sim::DriverDecision::Reason::kStopSign:
      return "stopping at a stop sign";
    case vehicle_sim::DriverDecision::Reason::kGiveWay:
      return "giving way to a vehicle in the intersection";
    case vehicle_sim::DriverDecision::Reason::kObstacle:
      return "stopping for something ahead";
    case vehicle_sim::DriverDecision::Reason::kAdvisory:
      return "keeping to an advised speed";
    case vehicle_sim::DriverDecision::Reason::kGoal:
      return "stopped at the end of its route";
    case vehicle_sim::DriverDecision::Reason::kLost:
      return "off the lanes";
  }
  return "?";
}

// A controller of the simulator's lockstep (common/dds/lockstep.h): register once the
// simulator reads the commands, then at each step decide on the simulated time, make sure the
// commands arrived, and answer.
int Lockstep(const dds::Participant& participant, const std::string& name,
             const std::vector<std::unique_ptr<Car>>& cars,
             const std::function<void(Duration)>& decide, const std::atomic<bool>& stop) {
  dds::LockstepClient lockstep(participant, name);
  if (!lockstep.WaitForSimulator(stop)) return 0;
  for (const auto& car : cars) {
    if (!car->throttle.WaitForReaders(1, std::chrono::seconds(5)) ||
        !car->steering.WaitForReaders(1, std::chrono::seconds(5))) {
      spdlog::warn("lockstep: the simulator does not read {}'s commands", car->name);
    }
  }
  if (!lockstep.Register(stop)) return 0;
  while (const std::optional<Time> t = lockstep.NextStep(stop)) {
    decide(*t - Time{});
    // The commands are in the simulator's readers before the answer is sent.
    for (const auto& car : cars) {
      if (!car->throttle.WaitForAcks(dds::kLockstepAckTimeout) ||
          !car->steering.WaitForAcks(dds::kLockstepAckTimeout)) {
        spdlog::warn(
            "lockstep: {}'s commands were not acknowledged in {} s: this step may not be "
            "reproducible",
            car->name, dds::kLockstepAckTimeout.count());
      }
    }
    lockstep.Answer();
  }
  if (lockstep.ended()) {
    spdlog::info("lockstep: the simulator ended after {} steps", lockstep.answered());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-example-driver: drives every car of a city's sim section along its lanes over "
      "DDS (the devkit topics), stopping at red lights, at stop signs and for what its LIDAR "
      "sees ahead. Runs until SIGINT or SIGTERM."};
  std::string city_path;
  examples::AgentOptions agent("/autodrive/example_driver", 20.0);
  double throttle = 0.6;
  std::uint64_t seed = 1;
  app.add_option("--city", city_path, "city file (its map and the cars of its sim section)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--throttle", throttle, "cruising throttle (normalised)")
      ->check(CLI::Range(0.05, 1.0))
      ->capture_default_str();
  app.add_option("--seed", seed, "seed of the route choices")->capture_default_str();
  std::vector<std::string> only;
  app.add_option("--vehicles", only,
                 "drive only these cars of the sim section (NAME[,NAME...]; default: all)")
      ->delimiter(',');
  std::vector<std::string> route;
  app.add_option("--route", route,
                 "lanes to drive in order (LANE[,LANE...], as autodrive-map info names them); "
                 "past them it chooses at random. Only with one car (--vehicles)")
      ->delimiter(',');
  bool stop_at_end = false;
  app.add_flag("--stop-at-route-end", stop_at_end,
               "stop at the end of the route's last lane (its goal) instead of driving on");
  vehicle_sim::DriverOptions faults;
  app.add_flag("--ignore-lights", faults.ignore_lights,
               "fault on purpose: drive through red lights (to test what judges a driver)");
  app.add_flag("--ignore-stop-signs", faults.ignore_stop_signs,
               "fault on purpose: roll through stop signs");
  app.add_flag("--ignore-obstacles", faults.ignore_obstacles,
               "fault on purpose: ignore what the LIDAR sees ahead");
  app.add_option("--lateral-offset-m", faults.lateral_offset_m,
                 "fault on purpose: keep this far left of the lane centres (negative: right)")
      ->check(CLI::Range(-1.0, 1.0));
  agent.Add(app);
  CLI11_PARSE(app, argc, argv);
  // The signals first, before anything can start a thread (examples/common/agent_options.h).
  std::atomic<bool> stop{false};
  ShutdownSignals signals([&] { stop.store(true); });
  try {
    InitLogging("autodrive-example-driver", ParseLogLevel(agent.log_level));
    const vehicle_sim::SimCity city = vehicle_sim::LoadSimCity(city_path);
    const maps::Map map = maps::LoadMapOrLayout(city.map_path);
    dds::Participant participant(agent.dds.Participant());

    for (const std::string& name : only) {
      if (std::none_of(city.sim.vehicles.begin(), city.sim.vehicles.end(),
                       [&](const auto& v) { return v.name == name; })) {
        throw InputError("--vehicles: " + city_path + " has no car " + name +
                         " in its sim section");
      }
    }
    if (!route.empty() && only.size() != 1) {
      throw InputError("--route: give exactly one car with --vehicles (a route is one car's)");
    }
    std::vector<LaneId> route_ids;
    for (const std::string& lane : route) {
      const maps::Lane* l = map.FindLane(lane);
      if (l == nullptr) {
        throw InputError("--route: map " + map.name + " has no lane \"" + lane +
                         "\" (autodrive-map info lists them)");
      }
      route_ids.push_back(l->id);
    }
    std::vector<std::unique_ptr<Car>> cars;
    for (std::size_t i = 0; i < city.sim.vehicles.size(); ++i) {
      if (!only.empty() &&
          std::find(only.begin(), only.end(), city.sim.vehicles[i].name) == only.end()) {
        continue;
      }
      vehicle_sim::DriverOptions options = faults;
      options.route = route_ids;
      options.stop_at_route_end = stop_at_end;
      options.cruise_throttle = throttle;
      options.seed = seed + i;
      const vehicle_sim::VehicleParams& p = city.sim.vehicles[i].params;
      options.wheelbase_m = p.wheelbase_m;
      options.steering_limit_rad = p.steering_limit_rad;
      options.front_overhang_m = p.body_centre_ahead_of_rear_axle_m + p.body_length_m / 2;
      options.rear_overhang_m = p.body_length_m / 2 - p.body_centre_ahead_of_rear_axle_m;
      options.top_speed_mps = p.top_speed_mps;
      options.half_width_m = p.body_width_m / 2;
      cars.push_back(std::make_unique<Car>(participant, ParseVehicleName(city.sim.vehicles[i].name),
                                           map, options));
    }
    // In a city of districts each district's lamps are heard on its domain (docs/districts.md).
    // (Before the readers: they go first.)
    const maps::Districts districts(map, city.districts);
    const maps::DistrictDomains district_domains(participant, agent.dds.Participant(), districts);
    std::map<SignalHeadId, std::unique_ptr<dds::Reader<msg::Int32>>> lamp_readers;
    std::map<SignalHeadId, std::int32_t> lamps;
    for (const auto& h : map.signal_heads) {
      lamp_readers.emplace(h.id, std::make_unique<dds::Reader<msg::Int32>>(
                                     district_domains.ForHead(h), topics::SignalState(h.id)));
    }
    // One decision for every car: from what its topics brought since the last one.
    const auto decide = [&](Duration now) {
      for (auto& [id, reader] : lamp_readers) {
        while (auto m = reader->TakeOne()) lamps[id] = (*m)->data;
      }
      for (auto& car : cars) {
        while (auto m = car->ips.TakeOne()) car->position = Eigen::Vector2d((*m)->x, (*m)->y);
        while (auto m = car->imu.TakeOne()) {
          const auto& q = (*m)->orientation;
          car->yaw = YawFromQuaternion(Eigen::Quaterniond(q.w, q.x, q.y, q.z));
        }
        while (auto m = car->lidar.TakeOne()) {
          const auto& r = (*m)->ranges;
          car->scan.assign(r._buffer, r._buffer + r._length);
        }
        if (!car->position || !car->yaw) continue;
        const auto decision = car->driver.Step(
            RigidTransform2::FromXyYaw(car->position->x(), car->position->y(), *car->yaw),
            [&](SignalHeadId h) -> std::optional<std::int32_t> {
              const auto it = lamps.find(h);
              if (it == lamps.end()) return std::nullopt;
              return it->second;
            },
            car->scan, now);
        car->throttle.Write(msg::Float32{static_cast<float>(decision.throttle)});
        car->steering.Write(msg::Float32{static_cast<float>(decision.steering)});
        if (decision.reason != car->reason) {
          spdlog::debug("{}: {} on {}", car->name, ToString(decision.reason),
                        car->driver.lane_name());
          car->reason = decision.reason;
        }
      }
    };
    spdlog::info("driving {} cars on map {}{}", cars.size(), map.name,
                 agent.lockstep.empty() ? "" : " in lockstep as controller " + agent.lockstep);
    if (!agent.lockstep.empty()) return Lockstep(participant, agent.lockstep, cars, decide, stop);
    const auto start = std::chrono::steady_clock::now();
    const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(1.0 / agent.rate_hz));
    auto next = start;
    while (!stop.load()) {
      decide(std::chrono::steady_clock::now() - start);
      next += period;
      std::this_thread::sleep_until(next);
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-example-driver: %s\n", e.what());
    return 1;
  }
}
