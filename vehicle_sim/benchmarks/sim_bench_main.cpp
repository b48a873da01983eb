// autodrive-bench-sim: the simulator's speed on one core. Prints dynamics steps per second for
// one car; the real-time factor with 1 and 10 cars on the small town with their sensors (LIDAR at
// 7 Hz, IMU at 100 Hz, encoders, IPS and feedback at their rates); and the LIDAR's rays per
// second in that run. Goals (issue 9): >= 100x real time for one car, >= 10x for ten, >= 2
// million rays/s. Then the cameras (issue 10) on the Driving School with four cars driving: ms
// per 1280x720 on-board frame without and with film effects (light, exposure, Gaussian blur,
// noise; and motion blur, 4 sub-frames, on its own line) and per 1920x1080 overhead frame.
// Goals: <= 5 ms on-board, <= 8 ms with effects, <= 15 ms overhead. Both again with `--traffic`
// background objects (default 2000; 0: not run) over a city of 100 x 100 m around the map, 20
// of them on the map (and the ten cars' run of the dynamics with them as boxes for the
// LIDARs and the physics): objects out of view should cost little. Times are this
// thread's CPU time (one core), with the wall time beside it.
#include <time.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <opencv2/core/utility.hpp>

#include "common/camera/camera_model.h"
#include "common/cpu_time.h"
#include "common/time.h"
#include "maps/map.h"
#include "maps/map_io.h"
#include "vehicle_sim/renderer.h"
#include "vehicle_sim/sensors.h"
#include "vehicle_sim/sim_config.h"
#include "vehicle_sim/traffic.h"
#include "vehicle_sim/world.h"

namespace {

using namespace autodrive;
using namespace autodrive::vehicle_sim;

double WallSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Each car drives a slow weave so that it keeps moving, turning and meeting things.
VehicleCommand Weave(int car, Duration t) {
  const double s = ToSeconds(t);
  return {0.6, 0.7 * std::sin(0.8 * s + car)};
}

// `n` background cars at rest: 20 on the map (or n if fewer), the others in a city of
// 100 x 100 m around it, 10 m or more from the map's centre (out of the overhead camera's
// view); seeded.
std::vector<TrafficObject> Traffic(const maps::Map& map, int n) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::vector<TrafficObject> objects;
  for (int k = 0; k < n; ++k) {
    TrafficObject o;
    o.id = "veh" + std::to_string(k);
    const Eigen::Vector2d centre = map.size_m() / 2;
    Eigen::Vector2d p =
        centre + Eigen::Vector2d(u01(rng) - 0.5, u01(rng) - 0.5)
                     .cwiseProduct(k < 20 ? map.size_m() : Eigen::Vector2d(100, 100));
    while (k >= 20 && (p - centre).norm() < 10) {
      p = centre + 100 * Eigen::Vector2d(u01(rng) - 0.5, u01(rng) - 0.5);
    }
    const double x = p.x(), y = p.y();
    o.X_MO = Eigen::Translation3d(x, y, 0) *
             Eigen::AngleAxisd(2 * kPi * u01(rng), Eigen::Vector3d::UnitZ());
    o.size_m = {0.32, 0.13, k % 10 == 0 ? 0.22 : 0.11};  // every tenth a LIDAR sees
    o.object_class = k % 10 == 0 ? TrafficClass::kBus : TrafficClass::kCar;
    objects.push_back(o);
  }
  return objects;
}

struct Run {
  double sim_s = 0, cpu_s = 0, wall_s = 0, sensor_cpu_s = 0;
  std::int64_t steps = 0, rays = 0, scans = 0;
};

Run RunCity(const maps::Map& map, const SimConfig& sim, int cars, double seconds, bool sensors,
            int traffic = 0) {
  World world(map, sim.world);
  SimConfig config = sim;
  config.vehicles.clear();
  for (int i = 0; i < cars; ++i) {
    config.vehicles.push_back({"nigel_" + std::to_string(i + 1), std::nullopt, {}, {}, {}});
  }
  const std::vector<RigidTransform2> poses = SpawnPoses(config, map);
  std::vector<SensorSuite> suites;
  for (int i = 0; i < cars; ++i) {
    world.AddVehicle(VehicleParams{}, poses[static_cast<std::size_t>(i)]);
    suites.emplace_back(SensorConfig{}, i, sim.seed);
  }
  const StaticScene& scene = world.Scene();
  std::vector<DynamicBox> traffic_boxes;
  for (const TrafficObject& o : Traffic(map, traffic)) {
    traffic_boxes.push_back(TrafficBox(
        o, o.X_MO,
        BoxId(static_cast<std::uint32_t>(cars + static_cast<int>(traffic_boxes.size())))));
  }
  std::vector<DynamicBox> boxes;
  std::vector<std::vector<DynamicBox>> reachable(static_cast<std::size_t>(cars));
  std::vector<std::size_t> reachable_traffic(static_cast<std::size_t>(cars), 0);
  SensorReadings readings;
  Run run;
  const double cpu0 = ThreadCpuSeconds();
  const double wall0 = WallSeconds();
  const Duration end = FromSeconds(seconds);
  while (world.time() < end) {
    // As the service does: the traffic placed anew every control period (10 ms).
    if (traffic > 0 && world.steps() % 5 == 0) world.SetTraffic(traffic_boxes);
    for (int i = 0; i < cars; ++i) world.SetCommand(i, Weave(i, world.time()));
    world.Step();
    if (sensors) {
      const double s0 = ThreadCpuSeconds();
      if (traffic > 0) {
        // As the service does: each car's LIDAR gets the traffic it may reach in the control
        // period, then the cars' boxes.
        VehicleBoxes(world, boxes);
        for (std::size_t i = 0; i < suites.size(); ++i) {
          if (world.steps() % 5 == 1) {
            reachable[i].clear();
            suites[i].Reachable(world, traffic_boxes, std::chrono::milliseconds(10), reachable[i]);
            reachable_traffic[i] = reachable[i].size();
          }
          reachable[i].erase(
              reachable[i].begin() + static_cast<std::ptrdiff_t>(reachable_traffic[i]),
              reachable[i].end());
          reachable[i].insert(reachable[i].end(), boxes.begin(), boxes.end());
          suites[i].Sample(world, scene, reachable[i], readings);
          run.scans += readings.lidar.has_value();
        }
        run.sensor_cpu_s += ThreadCpuSeconds() - s0;
        continue;
      }
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

struct CameraRun {
  int frames = 0;
  double cpu_ms_mean = 0, cpu_ms_max = 0, wall_ms_mean = 0;
  RenderStats stats;  ///< summed over the frames
};

// Renders `frames` frames of one camera while four cars drive; a frame every 1/15 s.
CameraRun RunCamera(const maps::Map& map, const camera::Intrinsics& intrinsics,
                    const FilmOptions& film, bool onboard, int frames, double texel_m,
                    int traffic = 0) {
  World world(map, {});
  SimConfig config;
  config.vehicles.clear();
  for (int i = 0; i < 4; ++i) {
    config.vehicles.push_back({"nigel_" + std::to_string(i + 1), std::nullopt, {}, {}, {}});
  }
  const std::vector<RigidTransform2> poses = SpawnPoses(config, map);
  for (int i = 0; i < 4; ++i) world.AddVehicle(VehicleParams{}, poses[static_cast<std::size_t>(i)]);
  RenderWorldOptions options;
  options.ground_texel_m = texel_m;
  const auto render_world =
      std::make_shared<const RenderWorld>(map, world.Scene().geometry(), options);
  CameraRenderer renderer(render_world, intrinsics, film);
  std::vector<RenderVehicle> cars(4);
  std::vector<HeadLamps> lamps;
  for (const auto& head : map.signal_heads) lamps.push_back({head.id, true, false, false});
  std::vector<RenderTraffic> looks;
  for (const TrafficObject& o : Traffic(map, traffic)) looks.push_back(TrafficLook(o, o.X_MO));
  const Eigen::Isometry3d overhead = camera::CameraPoseFromMount(
      {map.size_m().x() / 2, map.size_m().y() / 2, 4.8}, {0.0, kPi / 2, kPi / 2});
  Image image;
  CameraRun run;
  for (int f = 0; f < frames; ++f) {
    // The car carrying the on-board camera creeps along its lane (towards the poles, heads and
    // cars ahead); the others weave.
    for (int i = 0; i < 4; ++i) {
      world.SetCommand(i, onboard && i == 0 ? VehicleCommand{0.3, 0.0} : Weave(i, world.time()));
    }
    world.StepUntil(world.time() + std::chrono::milliseconds(67));
    for (int i = 0; i < 4; ++i) {
      const VehicleState& state = world.State(i);
      RenderVehicle& car = cars[static_cast<std::size_t>(i)];
      car.index = i;
      car.params = &world.Params(i);
      car.X_MV = Eigen::Translation3d(state.X_MV.translation()) * state.X_MV.rotation();
      car.v_M_mps = state.X_MV.rotation() * state.v_V_mps;
      car.w_M_radps = state.X_MV.rotation() * state.w_V_radps;
      car.look.tag = TagSpec{"tag36h11", i + 1, 0.0762};
    }
    FrameState frame;
    frame.time_s = ToSeconds(world.time());
    frame.vehicles = cars;
    frame.lamps = lamps;
    frame.traffic = looks;
    const double cpu0 = ThreadCpuSeconds();
    const double wall0 = WallSeconds();
    if (onboard) {
      const Eigen::Isometry3d X_MC =
          cars[0].X_MV * camera::CameraPoseFromMount({0.195, 0, 0.110}, {0, 7.3 * kPi / 180, 0});
      renderer.Render(X_MC, frame, image, 0, cars[0].v_M_mps, cars[0].w_M_radps,
                      static_cast<std::uint64_t>(f));
    } else {
      renderer.Render(overhead, frame, image, std::nullopt, Eigen::Vector3d::Zero(),
                      Eigen::Vector3d::Zero(), static_cast<std::uint64_t>(f));
    }
    const double cpu_ms = 1e3 * (ThreadCpuSeconds() - cpu0);
    if (f == 0) continue;  // the first frame of a fixed camera draws its ground once
    run.cpu_ms_mean += cpu_ms;
    run.cpu_ms_max = std::max(run.cpu_ms_max, cpu_ms);
    run.wall_ms_mean += 1e3 * (WallSeconds() - wall0);
    ++run.frames;
    run.stats.ground_ms += renderer.stats().ground_ms;
    run.stats.objects_ms += renderer.stats().objects_ms;
    run.stats.film_ms += renderer.stats().film_ms;
    run.stats.parts_drawn += renderer.stats().parts_drawn;
    run.stats.traffic_in_view += renderer.stats().traffic_in_view;
    run.stats.pixels_tested += renderer.stats().pixels_tested;
  }
  run.cpu_ms_mean /= run.frames;
  run.wall_ms_mean /= run.frames;
  return run;
}

void Cameras(const maps::Map& map, int frames, double texel_m, int traffic) {
  std::printf("cameras on %s, 4 cars driving, %d frames each, ground texel %.4g m, one thread\n",
              map.name.c_str(), frames, texel_m);
  FilmOptions effects;
  effects.exposure = 1.1;
  effects.blur_sigma_px = 0.5;
  effects.noise_sigma = 3.0;
  FilmOptions motion = effects;
  motion.exposure_time_s = 0.01;
  // fx = fy = 1000 px, principal point in the middle: the renderer test's overhead camera.
  const camera::Intrinsics overhead = camera::IntrinsicsFromSensor(1000.0, 1920.0, 1920, 1080);
  const auto line = [](const char* what, const CameraRun& r) {
    const double n = r.frames;
    std::printf(
        "%-44s %6.2f ms/frame (max %6.2f; wall %6.2f: ground %.2f, objects %.2f, film %.2f; "
        "%.0f parts, %.2f Mpx tested)\n",
        what, r.cpu_ms_mean, r.cpu_ms_max, r.wall_ms_mean, r.stats.ground_ms / n,
        r.stats.objects_ms / n, r.stats.film_ms / n, r.stats.parts_drawn / n,
        static_cast<double>(r.stats.pixels_tested) / n / 1e6);
  };
  line("on-board 1280x720:",
       RunCamera(map, camera::PiCameraV21Intrinsics(), {}, true, frames, texel_m));
  line("on-board 1280x720, film effects:",
       RunCamera(map, camera::PiCameraV21Intrinsics(), effects, true, frames, texel_m));
  line("on-board 1280x720, effects + motion blur (4):",
       RunCamera(map, camera::PiCameraV21Intrinsics(), motion, true, frames, texel_m));
  line("overhead 1920x1080:", RunCamera(map, overhead, {}, false, frames, texel_m));
  line("overhead 1920x1080, film effects:",
       RunCamera(map, overhead, effects, false, frames, texel_m));
  if (traffic > 0) {
    const auto with = [&](const char* what, const CameraRun& r) {
      line(what, r);
      std::printf("%-44s %.1f of %d background objects in view\n", "",
                  r.stats.traffic_in_view / static_cast<double>(r.frames), traffic);
    };
    with("on-board 1280x720, background traffic:",
         RunCamera(map, camera::PiCameraV21Intrinsics(), {}, true, frames, texel_m, traffic));
    with("overhead 1920x1080, background traffic:",
         RunCamera(map, overhead, {}, false, frames, texel_m, traffic));
  }
  std::printf("goals: <= 5 ms on-board, <= 8 ms with effects, <= 15 ms overhead\n");
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
  std::string camera_map_path = "config/maps/driving_school.yaml";
  int camera_frames = 100;
  bool only_cameras = false;
  int traffic = 2000;
  app.add_option("--traffic", traffic,
                 "background objects for the runs with traffic (0: none of those runs)")
      ->check(CLI::Range(0, 100000))
      ->capture_default_str();
  double texel_m = RenderConfig{}.ground_texel_m;
  app.add_option("--ground-texel", texel_m, "the ground picture's metres per texel (sim.render)")
      ->check(CLI::Range(0.0005, 0.1))
      ->capture_default_str();
  app.add_option("--camera-map", camera_map_path, "map the cameras' benchmark runs on")
      ->capture_default_str();
  app.add_option("--camera-frames", camera_frames, "frames per camera run")
      ->check(CLI::Range(2, 100000))
      ->capture_default_str();
  app.add_flag("--only-cameras", only_cameras, "run the cameras' benchmark only");
  CLI11_PARSE(app, argc, argv);
  cv::setNumThreads(1);  // OpenCV's own threads would hide work from this thread's CPU time
  if (only_cameras) map_path = camera_map_path;
  if (!std::filesystem::exists(map_path) || !std::filesystem::exists(camera_map_path)) {
    std::fprintf(stderr,
                 "autodrive-bench-sim: no map at %s (run from the repository root or "
                 "give --map)\n",
                 (std::filesystem::exists(map_path) ? camera_map_path : map_path).c_str());
    return 1;
  }
  if (only_cameras) {
    Cameras(maps::LoadMapOrLayout(camera_map_path), camera_frames, texel_m, traffic);
    return 0;
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
  if (traffic > 0) {
    const Run r = RunCity(map, sim, 10, seconds, true, traffic);
    std::printf(
        "10 cars, %d background:  %9.0f steps/s   %7.1fx real time   (cpu %.2f s, wall %.2f s; "
        "sensors %.0f%% of it)\n",
        traffic, static_cast<double>(r.steps) / r.cpu_s, r.sim_s / r.cpu_s, r.cpu_s, r.wall_s,
        100 * r.sensor_cpu_s / r.cpu_s);
  }
  std::printf("goals: >= 100x real time for 1 car, >= 10x for 10, >= 2 million rays/s\n");
  Cameras(maps::LoadMapOrLayout(camera_map_path), camera_frames, texel_m, traffic);
  return 0;
}
