#include "vehicle_sim/service.h"

#include <spdlog/spdlog.h>

#include <cmath>
#include <memory>
#include <ostream>
#include <string>
#include <thread>
#include <vector>

#include "common/dds/conversions.h"
#include "common/dds/lockstep.h"
#include "common/dds/messages.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "vehicle_sim/internal/background_traffic.h"
#include "vehicle_sim/internal/camera_publisher.h"
#include "vehicle_sim/internal/car_endpoints.h"
#include "vehicle_sim/replay.h"
#include "vehicle_sim/sensors.h"
#include "vehicle_sim/variability.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim {

struct SimService::Impl {
  ServiceOptions options;
  World world;
  std::vector<std::unique_ptr<internal::CarEndpoints>> cars;  // the world's cars, by index
  std::vector<SensorSuite> suites;                            // ... their sensors
  dds::Writer<msg::Clock> clock;
  std::unique_ptr<internal::CameraPublisher> cameras;
  std::unique_ptr<internal::SignalLamps> lamps;
  std::unique_ptr<internal::BackgroundTraffic> traffic;
  // Lockstep only: the protocol's server side (common/dds/lockstep.h).
  std::unique_ptr<dds::LockstepServer> lockstep;
  Time origin;  // the ROS time of simulated time 0
  std::int64_t steps_per_period = 1;
  std::vector<DynamicBox> car_boxes;  // every car's box after a step (id: its index)
  // What car i's LIDAR sees: the background boxes it may reach in this period (the head,
  // `lidar_traffic[i]` of them, chosen at the period's start), then `car_boxes` (each step).
  std::vector<std::vector<DynamicBox>> lidar_boxes;
  std::vector<std::size_t> lidar_traffic;
  SensorReadings readings;
  std::ostream* log = nullptr;

  // Districts: the city's, and a participant on each one's domain (in the same order).
  maps::Districts districts;
  DistrictParticipants district_participants;

  Impl(const dds::Participant& participant, const SimCity& city, const maps::Map& map,
       const ServiceOptions& o, const DistrictParticipants& dp)
      : options(o),
        world(SimulatedMap(city.sim, map), city.sim.world),
        clock(participant, dds::topics::Clock()),
        districts(map, city.districts),
        district_participants(dp) {
    AUTODRIVE_THROW_UNLESS(dp.size() == districts.all().size(),
                           "the city has " << districts.all().size() << " districts, " << dp.size()
                                           << " participants were given for them");
    AUTODRIVE_THROW_UNLESS(o.control_period >= world.options().step,
                           "the control period " << ToSeconds(o.control_period)
                                                 << " s is shorter than the physics step "
                                                 << ToSeconds(world.options().step) << " s");
    AUTODRIVE_THROW_UNLESS(o.real_time_factor > 0 && std::isfinite(o.real_time_factor),
                           "the real-time factor must be positive, got " << o.real_time_factor);
    o.Validate();
    steps_per_period = o.control_period / world.options().step;
    AddCars(participant, city.sim, map);
    // The DDS entities in the order they always were: cars, cameras, lamps, traffic, lockstep.
    cameras = std::make_unique<internal::CameraPublisher>(participant, city.sim, map, world,
                                                          o.mode == SimMode::kRealTime);
    lamps = std::make_unique<internal::SignalLamps>(
        [&](const maps::SignalHead& head) -> const dds::Participant& {
          const maps::District* d = districts.Of(head.intersection);
          return d == nullptr ? participant : *district_participants[districts.IndexOf(*d)];
        },
        map);
    std::vector<std::string> names;
    for (const auto& car : cars) names.push_back(car->name());
    traffic = std::make_unique<internal::BackgroundTraffic>(participant, o.traffic,
                                                            std::move(names), !cameras->empty());
    if (o.mode == SimMode::kLockstep) {
      lockstep = std::make_unique<dds::LockstepServer>(participant, o.controllers, o.stages);
    }
    origin = o.mode == SimMode::kRealTime ? WallClock().Now() : Time{};
  }

  // The unmapped obstacles, then the city's cars with their sensors and endpoints.
  void AddCars(const dds::Participant& participant, const SimConfig& sim, const maps::Map& map) {
    const std::vector<RigidTransform2> poses = SpawnPoses(sim, map);
    const std::vector<UnmappedObstacle> obstacles = UnmappedObstacles(sim, map, poses);
    AddObstacles(obstacles, world);
    for (const UnmappedObstacle& ob : obstacles) {
      std::string when;
      if (ob.from_s > Duration{0})
        when += fmt::format(", placed at {:.3f} s", ToSeconds(ob.from_s));
      if (ob.until_s) when += fmt::format(", removed at {:.3f} s", ToSeconds(*ob.until_s));
      spdlog::info(
          "unmapped obstacle {}: {:.2f} x {:.2f} x {:.2f} m at ({:.3f}, {:.3f}), {:.3f} rad{}",
          ob.name.empty() ? "(unnamed)" : ob.name, ob.length_m, ob.width_m, ob.height_m, ob.x_m,
          ob.y_m, ob.yaw_rad, when);
    }
    for (std::size_t i = 0; i < sim.vehicles.size(); ++i) {
      const SimVehicleConfig& c = sim.vehicles[i];
      const int index = world.AddVehicle(c.params, poses[i]);
      suites.emplace_back(EffectiveSensors(sim, i), index, sim.seed);
      cars.push_back(std::make_unique<internal::CarEndpoints>(
          participant, ParseVehicleName(c.name),
          CommandNoise(sim.variability, c.params, sim.seed, index), district_participants));
    }
  }

  Time Stamp(Duration t) const { return origin + t; }

  // Which district's `ips` writer of a car gets its position besides its own: 1 + the district's
  // index (0: none, without districts).
  std::size_t IpsTo(const SensorReadings& r) const {
    if (districts.empty() || !r.ips) return 0;
    return 1 + districts.IndexOf(*districts.At(r.ips->position_m.head<2>()));
  }

  void TakeCommands() {
    const Duration now = world.time();
    for (std::size_t i = 0; i < cars.size(); ++i) {
      world.SetCommand(static_cast<int>(i), cars[i]->TakeCommand(now, options.command_timeout));
    }
  }

  // For each car, the background boxes its LIDAR may reach in this period: a city's objects
  // far from every car then cost the LIDARs nothing during the period's steps.
  void ChooseLidarTraffic() {
    lidar_boxes.resize(cars.size());
    lidar_traffic.resize(cars.size());
    for (std::size_t i = 0; i < cars.size(); ++i) {
      lidar_boxes[i].clear();
      suites[i].Reachable(world, traffic->boxes(), options.control_period, lidar_boxes[i]);
      lidar_traffic[i] = lidar_boxes[i].size();
    }
  }

  // What the LIDARs see after a step: each car's background boxes of the period (kept), then
  // every car's box.
  void UpdateBoxes() {
    VehicleBoxes(world, car_boxes);
    for (std::size_t i = 0; i < cars.size(); ++i) {
      std::vector<DynamicBox>& seen = lidar_boxes[i];
      seen.erase(seen.begin() + static_cast<std::ptrdiff_t>(lidar_traffic[i]), seen.end());
      seen.insert(seen.end(), car_boxes.begin(), car_boxes.end());
    }
  }

  // The frames of the cameras due now: rendered from the world as it is, in this thread (so
  // that lockstep and fast runs are reproducible) or handed to the cameras' workers, and
  // published.
  void PublishCameras() {
    cameras->PublishDue(world, Stamp(world.time()), traffic->looks(),
                        [this](std::vector<CarLights>& lights, std::vector<HeadLamps>& lit) {
                          lights.resize(cars.size());
                          for (std::size_t i = 0; i < cars.size(); ++i) {
                            lights[i] = cars[i]->lights();
                          }
                          lamps->Lit(lit);
                        });
  }

  // One control period: commands, physics steps with their sensors and cameras, /clock,
  // ground truth.
  void Period() {
    TakeCommands();
    lamps->Take();
    traffic->Take(Stamp(world.time()), options.mode == SimMode::kRealTime, world);
    ChooseLidarTraffic();
    for (std::int64_t k = 0; k < steps_per_period; ++k) {
      world.Step();
      traffic->NoteContacts(world);
      UpdateBoxes();
      for (std::size_t i = 0; i < cars.size(); ++i) {
        suites[i].Sample(world, world.Scene(), lidar_boxes[i], readings);
        cars[i]->Publish(readings, suites[i].config().imu, origin, IpsTo(readings));
      }
      PublishCameras();
    }
    PublishState();
  }

  // Every car's ground truth, /clock, and the log's rows, for the world's time.
  void PublishState() {
    for (std::size_t i = 0; i < cars.size(); ++i) {
      cars[i]->PublishGroundTruth(world.State(static_cast<int>(i)), Stamp(world.time()));
    }
    clock.Write(msg::Clock{dds::ToMsg(Stamp(world.time()))});
    if (log != nullptr) {
      for (std::size_t i = 0; i < cars.size(); ++i) {
        *log << cars[i]->name() << ',';
        WriteReplayRow(*log, world.time(), world.State(static_cast<int>(i)));
      }
    }
  }

  // --- Lockstep ---------------------------------------------------------------------------

  // Announces the step at the world's time once every reader acknowledged its messages (the
  // protocol's rule 2); `last`: the simulator stops after it.
  void AnnounceStep(bool last) {
    for (const auto& car : cars) car->WaitForAcks(dds::kLockstepAckTimeout);
    cameras->WaitForAcks(dds::kLockstepAckTimeout);
    if (last) {
      lockstep->End(Stamp(world.time()));
    } else {
      lockstep->Announce(Stamp(world.time()));
    }
  }
};

SimService::SimService(const dds::Participant& participant, const SimCity& city,
                       const maps::Map& map, const ServiceOptions& options,
                       const DistrictParticipants& districts)
    : impl_(std::make_unique<Impl>(participant, city, map, options, districts)) {}

SimService::~SimService() = default;

void SimService::LogTo(std::ostream* out) {
  impl_->log = out;
  if (out != nullptr) *out << "vehicle," << kReplayLogHeader << '\n';
}

void SimService::Run(const std::atomic<bool>& stop) {
  Impl& s = *impl_;
  dds::LockstepServer* const lockstep = s.lockstep.get();
  if (lockstep != nullptr && !lockstep->WaitForControllers(stop)) return;
  const auto wall_start = std::chrono::steady_clock::now();
  const Duration sim_start = s.world.time();
  Duration last_report = sim_start;
  const auto duration_over = [&] {
    return s.options.duration && s.world.time() - sim_start >= *s.options.duration;
  };
  if (lockstep != nullptr) {
    s.PublishState();
    s.AnnounceStep(false);
  }
  while (!stop.load()) {
    if (duration_over()) break;
    if (lockstep != nullptr && !lockstep->WaitForAnswers(stop)) break;
    s.Period();
    if (lockstep != nullptr) s.AnnounceStep(stop.load() || duration_over());
    if (s.options.mode == SimMode::kRealTime) {
      const auto due = wall_start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                        (s.world.time() - sim_start) / s.options.real_time_factor);
      std::this_thread::sleep_until(due);
    }
    if (s.world.time() - last_report >= std::chrono::seconds(60)) {
      last_report = s.world.time();
      const double wall =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
      spdlog::info("simulated {:.0f} s in {:.0f} s of wall time ({:.1f}x)",
                   ToSeconds(s.world.time() - sim_start), wall,
                   ToSeconds(s.world.time() - sim_start) / wall);
    }
  }
  // Stopped while the controllers were deciding: the step announced is the last.
  if (lockstep != nullptr && !lockstep->ended()) lockstep->End(s.Stamp(s.world.time()));
}

std::map<SignalHeadId, LampState> SimService::Lamps() const { return impl_->lamps->Get(); }

Duration SimService::time() const { return impl_->world.time(); }

std::int64_t SimService::traffic_collisions() const { return impl_->traffic->collisions(); }

std::uint64_t SimService::camera_frames() const { return impl_->cameras->frames(); }

std::int64_t SimService::steps() const { return impl_->world.steps(); }

}  // namespace autodrive::vehicle_sim
