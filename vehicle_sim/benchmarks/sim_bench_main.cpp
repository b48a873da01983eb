// autodrive-bench-sim: the simulator's speed on one core. Prints dynamics steps per second for
// one car; the real-time factor with 1 and 10 cars on the small town with their sensors (LIDAR at
// 7 Hz, IMU at 100 Hz, encoders, IPS and feedback at their rates); and the LIDAR's rays per
// second in that run. Goals (issue 9): >= 100x real time for one car, >= 10x for ten, >= 2
// million rays/s. Times are this thread's CPU time (one core), with the wall time beside it.
#include <time.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/time.h"
#include "maps/map.h"
#include "maps/map_io.h"
#include "vehicle_sim/sensors.h"
#include "vehicle_sim/sim_config.h"
#include "vehicle_sim/world.h"

namespace {

using namespace autodrive;
using namespace autodrive::vehicle_sim;

double ThreadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double WallSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Each car drives a slow weave so that it keeps moving, turning and meeting things.
VehicleCommand Weave(int car, Duration t) {
  const double s = ToSeconds(t);
  return {0.6, 0.7 * std::sin(0.8 * s + car)};
}

struct Run {
  double sim_s = 0, cpu_s = 0, wall_s = 0, sensor_cpu_s = 0;
  std::int64_t steps = 0, rays = 0, scans = 0;
};

Run RunCity(const maps::Map& map, const SimConfig& sim, int cars, double seconds, bool sensors) {
  World world(map, sim.world);
  SimConfig config = sim;
  config.vehicles.clear();
  for (int i = 0; i < cars; ++i) {
    config.vehicles.push_back({"nigel_" + std::to_string(i + 1), std::nullopt, {}, {}});
  }
  const std::vector<RigidTransform2> poses = SpawnPoses(config, map);
  std::vector<SensorSuite> suites;
  for (int i = 0; i < cars; ++i) {
    world.AddVehicle(VehicleParams{}, poses[static_cast<std::size_t>(i)]);
    suites.emplace_back(SensorConfig{}, i, sim.seed);
  }
  const StaticScene& scene = world.Scene();
  std::vector<DynamicBox> boxes;
  SensorReadings readings;
  Run run;
  const double cpu0 = ThreadCpuSeconds();
  const double wall0 = WallSeconds();
  const Duration end = FromSeconds(seconds);
  while (world.time() < end) {
    for (int i = 0; i < cars; ++i) world.SetCommand(i, Weave(i, world.time()));
    world.Step();
    if (sensors) {
      const double s0 = ThreadCpuSeconds();
      VehicleBoxes(world, boxes);
      for (auto& suite : suites) {
        suite.Sample(world, scene, boxes, readings);
        run.scans += readings.lidar.has_value();
      }
      run.sensor_cpu_s += ThreadCpuSeconds() - s0;
    }
  }
  run.cpu_s = ThreadCpuSeconds() - cpu0;
  run.wall_s = WallSeconds() - wall0;
  run.sim_s = ToSeconds(world.time());
  run.steps = world.steps();
  for (const auto& suite : suites) run.rays += suite.rays_cast();
  return run;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"autodrive-bench-sim: the simulator's speed on one core (docs/vehicle_sim.md)"};
  std::string map_path = "config/maps/small_town.yaml";
  double seconds = 60.0;
  app.add_option("--map", map_path, "map or layout the cars drive on")->capture_default_str();
  app.add_option("--seconds", seconds, "simulated seconds per run")
      ->check(CLI::Range(1.0, 3600.0))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (!std::filesystem::exists(map_path)) {
    std::fprintf(stderr,
                 "autodrive-bench-sim: no map at %s (run from the repository root or "
                 "give --map)\n",
                 map_path.c_str());
    return 1;
  }
  const maps::Map map = maps::LoadMapOrLayout(map_path);
  const SimConfig sim;
  std::printf("map %s, physics step %.4g s, %.0f simulated s per run, one thread\n",
              map.name.c_str(), ToSeconds(sim.world.step), seconds);

  const Run one = RunCity(map, sim, 1, seconds, false);
  std::printf(
      "dynamics, 1 car:          %9.0f steps/s   %7.1fx real time   (cpu %.2f s, wall "
      "%.2f s)\n",
      static_cast<double>(one.steps) / one.cpu_s, one.sim_s / one.cpu_s, one.cpu_s, one.wall_s);
  for (int cars : {1, 10}) {
    const Run r = RunCity(map, sim, cars, seconds, true);
    std::printf(
        "%2d car%s with sensors:   %9.0f steps/s   %7.1fx real time   (cpu %.2f s, "
        "wall %.2f s; sensors %.0f%% of it)\n",
        cars, cars == 1 ? " " : "s", static_cast<double>(r.steps) / r.cpu_s, r.sim_s / r.cpu_s,
        r.cpu_s, r.wall_s, 100 * r.sensor_cpu_s / r.cpu_s);
    if (cars == 10) {
      std::printf(
          "LIDAR, 10 cars:           %9.2f million rays/s (%lld rays in %lld scans, "
          "sensor time %.2f s)\n",
          static_cast<double>(r.rays) / r.sensor_cpu_s / 1e6, static_cast<long long>(r.rays),
          static_cast<long long>(r.scans), r.sensor_cpu_s);
    }
  }
  std::printf("goals: >= 100x real time for 1 car, >= 10x for 10, >= 2 million rays/s\n");
  return 0;
}
