#include "vehicle_sim/dataset.h"

#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/error.h"
#include "maps/map.h"
#include "vehicle_sim/cameras.h"
#include "vehicle_sim/sensors.h"
#include "vehicle_sim/variability.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim {

void FixedCycleLamps(const maps::Map& map, Duration t, std::vector<HeadLamps>& out) {
  constexpr double kGreen = 6.0, kYellow = 2.0, kAllRed = 1.0;
  constexpr double kSlot = kGreen + kYellow + kAllRed;
  out.clear();
  for (const maps::Intersection& x : map.intersections) {
    // The approaches that have heads, in the map's order.
    std::vector<ApproachId> served;
    for (const SignalHeadId h : x.signal_heads) {
      const ApproachId a = map.signal_head(h).approach;
      if (std::find(served.begin(), served.end(), a) == served.end()) served.push_back(a);
    }
    if (served.empty()) continue;
    const double in_cycle = std::fmod(ToSeconds(t), kSlot * static_cast<double>(served.size()));
    const auto slot = static_cast<std::size_t>(in_cycle / kSlot);
    const double in_slot = in_cycle - kSlot * static_cast<double>(slot);
    for (const SignalHeadId h : x.signal_heads) {
      const bool mine = map.signal_head(h).approach == served[slot];
      HeadLamps l{h, true, false, false};
      if (mine && in_slot < kGreen) l = {h, false, false, true};
      if (mine && in_slot >= kGreen && in_slot < kGreen + kYellow) l = {h, false, true, false};
      out.push_back(l);
    }
  }
}

namespace {

// The city as the data set renders it: only the named camera, enabled.
SimConfig OnlyCamera(const SimConfig& sim, const std::string& name) {
  SimConfig out = sim;
  std::vector<std::string> names;
  bool found = false;
  for (auto& v : out.vehicles) {
    for (const bool front : {true, false}) {
      OnboardCameraConfig& c = front ? v.sensors.front_camera : v.sensors.rear_camera;
      const std::string n = v.name + (front ? "/front_camera" : "/rear_camera");
      names.push_back(n);
      c.enabled = n == name;
      found = found || c.enabled;
    }
  }
  out.cameras.clear();
  for (const auto& c : sim.cameras) {
    names.push_back(c.name);
    if (c.name == name) {
      out.cameras.push_back(c);
      found = true;
    }
  }
  if (!found) {
    std::string list;
    for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
    throw InputError("no camera \"" + name + "\" in the city (it has " + list + ")");
  }
  return out;
}

void WritePose(const std::filesystem::path& path, const SimConfig& sim, const SimCamera& cam) {
  MountConfig mount;
  std::string parent = "map";
  if (cam.vehicle) {
    const auto& v = sim.vehicles.at(static_cast<std::size_t>(*cam.vehicle));
    mount = (cam.front ? v.sensors.front_camera : v.sensors.rear_camera).mount;
    parent = v.name;
  } else {
    for (const auto& c : sim.cameras) {
      if (c.name == cam.name) mount = c.mount;
    }
  }
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap;
  out << YAML::Key << "camera" << YAML::Value << cam.name;
  out << YAML::Key << "frame_id" << YAML::Value << cam.frame_id;
  out << YAML::Key << "parent_frame" << YAML::Value << parent;
  out << YAML::Key << "mount" << YAML::Value << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "x_m" << YAML::Value << mount.x_m << YAML::Key << "y_m" << YAML::Value
      << mount.y_m << YAML::Key << "z_m" << YAML::Value << mount.z_m << YAML::Key << "roll_rad"
      << YAML::Value << mount.roll_rad << YAML::Key << "pitch_rad" << YAML::Value << mount.pitch_rad
      << YAML::Key << "yaw_rad" << YAML::Value << mount.yaw_rad;
  out << YAML::EndMap;
  out << YAML::Key << "X_parent_optical" << YAML::Value << YAML::BeginSeq;
  for (int r = 0; r < 4; ++r) {
    out << YAML::Flow << YAML::BeginSeq;
    for (int c = 0; c < 4; ++c) out << cam.X_PC.matrix()(r, c);
    out << YAML::EndSeq;
  }
  out << YAML::EndSeq << YAML::EndMap;
  std::ofstream file(path);
  file << out.c_str() << '\n';
  AUTODRIVE_THROW_UNLESS(file.good(), "cannot write " << path.string());
}

std::string Csv(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6f", v);
  if (std::string_view(text) == "-0.000000") return "0.000000";
  return text;
}

}  // namespace

DatasetSummary RenderDataset(const SimCity& city, const maps::Map& map,
                             const DatasetOptions& options, const DatasetDriver& driver,
                             const std::function<void(int, int)>& progress) {
  const SimConfig sim = OnlyCamera(city.sim, options.camera);
  std::error_code ec;
  std::filesystem::create_directories(options.out_dir, ec);
  AUTODRIVE_THROW_UNLESS(
      !ec && std::filesystem::is_directory(options.out_dir),
      "cannot make the directory " << options.out_dir.string() << ": " << ec.message());
  World world(SimulatedMap(sim, map), sim.world);
  const std::vector<RigidTransform2> poses = SpawnPoses(sim, map);
  AddObstacles(UnmappedObstacles(sim, map, poses), world);
  std::vector<SensorSuite> suites;
  for (std::size_t i = 0; i < sim.vehicles.size(); ++i) {
    const int index = world.AddVehicle(sim.vehicles[i].params, poses[i]);
    SensorConfig sensors = EffectiveSensors(sim, i);
    suites.emplace_back(sensors, index, sim.seed);
  }
  SimCameras cameras(sim, map, world);
  AUTODRIVE_CHECK(cameras.cameras().size() == 1, "one camera expected");
  const SimCamera& cam = cameras.cameras().front();
  camera::SaveOpenCvCalibration(options.out_dir / "camera.yaml", cam.intrinsics);
  WritePose(options.out_dir / "camera_pose.yaml", sim, cam);
  std::ofstream truth(options.out_dir / "ground_truth.csv");
  AUTODRIVE_THROW_UNLESS(truth.good(),
                         "cannot write " << (options.out_dir / "ground_truth.csv").string());
  truth << "frame,stamp_s,vehicle,tag_id,x_m,y_m,yaw_rad\n";
  // An on-board camera's car: its driver's commands are the data set's labels.
  std::ofstream labels;
  if (cam.vehicle) {
    labels.open(options.out_dir / "labels.csv");
    AUTODRIVE_THROW_UNLESS(labels.good(),
                           "cannot write " << (options.out_dir / "labels.csv").string());
    labels << "frame,stamp_s,throttle,steering,speed_mps,yaw_rate_radps,x_m,y_m,yaw_rad\n";
  }
  std::vector<CommandNoise> noise;
  for (std::size_t i = 0; i < sim.vehicles.size(); ++i) {
    noise.emplace_back(sim.variability, sim.vehicles[i].params, sim.seed, static_cast<int>(i));
  }
  std::vector<VehicleCommand> commanded(sim.vehicles.size());
  std::mt19937_64 perturbation_rng(
      StreamSeed(sim.seed, cam.vehicle.value_or(-1), kPerturbationStream));
  double perturbation = 0.0;

  const int total = static_cast<int>(options.duration / cam.period) + 1;
  const std::int64_t steps_per_period =
      std::max<std::int64_t>(1, options.control_period / world.options().step);
  std::vector<std::vector<float>> scans(sim.vehicles.size());
  std::vector<HeadLamps> lamps;
  std::vector<DynamicBox> boxes;
  std::vector<std::size_t> due;
  SensorReadings readings;
  Image image;
  DatasetSummary summary;
  double render_ms = 0;
  const std::vector<CarLights> lights(sim.vehicles.size(), CarLights{1, 0});  // headlights on
  const Duration end = world.time() + options.duration;
  const Duration start = world.time();
  while (world.time() <= end) {
    if (options.done && options.done(world)) break;
    FixedCycleLamps(map, world.time(), lamps);
    if (cam.vehicle && options.steering_perturbation > 0) {
      // Ornstein-Uhlenbeck over one control period.
      const double a = ToSeconds(options.control_period) / ToSeconds(options.perturbation_time);
      perturbation += -a * perturbation +
                      Gaussian(perturbation_rng, options.steering_perturbation * std::sqrt(2 * a));
    }
    for (std::size_t i = 0; i < sim.vehicles.size(); ++i) {
      commanded[i] = driver(i, world, scans[i], lamps, world.time());
      VehicleCommand executed = commanded[i];
      if (cam.vehicle && static_cast<int>(i) == *cam.vehicle) {
        executed.steering = std::clamp(executed.steering + perturbation, -1.0, 1.0);
      }
      world.SetCommand(static_cast<int>(i), noise[i].Apply(executed));
    }
    for (std::int64_t k = 0; k < steps_per_period && world.time() <= end; ++k) {
      world.Step();
      VehicleBoxes(world, boxes);
      for (std::size_t i = 0; i < suites.size(); ++i) {
        suites[i].Sample(world, world.Scene(), boxes, readings);
        if (readings.lidar) scans[i] = readings.lidar->ranges;
      }
      cameras.Due(world.time(), due);
      if (due.empty()) continue;
      cameras.Snapshot(world, lights, lamps);
      const auto t0 = std::chrono::steady_clock::now();
      cameras.Render(
          0, image,
          sim.seed * 0x9e3779b97f4a7c15ULL ^ static_cast<std::uint64_t>(world.time().count()));
      render_ms +=
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      char name[32];
      std::snprintf(name, sizeof name, "frame_%06d.png", summary.frames);
      cv::Mat rgb(image.height_px, image.width_px, CV_8UC3, image.rgb.data());
      cv::Mat bgr;
      cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
      AUTODRIVE_THROW_UNLESS(cv::imwrite((options.out_dir / name).string(), bgr),
                             "cannot write " << (options.out_dir / name).string());
      for (const RenderVehicle& car : cameras.vehicles()) {
        const Eigen::Vector3d p = VehicleTagPose(car).translation();
        const Eigen::Matrix3d& R = car.X_MV.linear();
        truth << summary.frames << ',' << Csv(ToSeconds(world.time())) << ','
              << sim.vehicles[static_cast<std::size_t>(car.index)].name << ','
              << (car.look.tag ? std::to_string(car.look.tag->id) : "") << ',' << Csv(p.x()) << ','
              << Csv(p.y()) << ',' << Csv(std::atan2(R(1, 0), R(0, 0))) << '\n';
        ++summary.rows;
      }
      if (cam.vehicle) {
        const auto car = static_cast<std::size_t>(*cam.vehicle);
        const VehicleState& state = world.State(*cam.vehicle);
        labels << summary.frames << ',' << Csv(ToSeconds(world.time())) << ','
               << Csv(commanded[car].throttle) << ',' << Csv(commanded[car].steering) << ','
               << Csv(state.v_V_mps.x()) << ',' << Csv(state.w_V_radps.z()) << ','
               << Csv(state.X_MV.translation().x()) << ',' << Csv(state.X_MV.translation().y())
               << ',' << Csv(YawFromQuaternion(state.X_MV.rotation())) << '\n';
      }
      ++summary.frames;
      if (progress) progress(summary.frames, total);
    }
  }
  truth.close();
  AUTODRIVE_THROW_UNLESS(!truth.fail(), "writing ground_truth.csv failed");
  if (labels.is_open()) {
    labels.close();
    AUTODRIVE_THROW_UNLESS(!labels.fail(), "writing labels.csv failed");
  }
  summary.duration = world.time() - start;
  summary.render_ms_mean = summary.frames > 0 ? render_ms / summary.frames : 0.0;
  return summary;
}

}  // namespace autodrive::vehicle_sim
