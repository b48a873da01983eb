#include "vehicle_sim/cameras.h"

#include <cmath>

#include "common/error.h"
#include "maps/map.h"
#include "vehicle_sim/variability.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim {

namespace {

Duration Period(double rate_hz) { return FromSeconds(1.0 / rate_hz); }

// Rethrows a lens's error with the camera's name in front.
template <typename F>
auto Named(const std::string& name, F&& f) {
  try {
    return f();
  } catch (const ConfigError& e) {
    throw ConfigError("camera " + name + ": " + e.what());
  } catch (const InputError& e) {
    throw InputError("camera " + name + ": " + e.what());
  }
}

}  // namespace

SimCameras::SimCameras(const SimConfig& sim, const maps::Map& map, const World& world) {
  for (std::size_t i = 0; i < sim.vehicles.size(); ++i) {
    const SimVehicleConfig& v = sim.vehicles[i];
    for (const bool front : {true, false}) {
      const OnboardCameraConfig& c = front ? v.sensors.front_camera : v.sensors.rear_camera;
      if (!c.enabled) continue;
      SimCamera cam;
      cam.frame_id = front ? "front_camera" : "rear_camera";
      cam.name = v.name + "/" + cam.frame_id;
      cam.vehicle = static_cast<int>(i);
      cam.vehicle_id = ParseVehicleName(v.name);
      cam.front = front;
      cam.X_PC = c.mount.OpticalPose();
      cam.intrinsics = Named(cam.name, [&] { return c.lens.Intrinsics(); });
      cam.film = LitFilm(c.film, sim);
      cam.period = Period(c.rate_hz);
      cameras_.push_back(cam);
    }
  }
  for (const OverheadCameraConfig& c : sim.cameras) {
    SimCamera cam;
    cam.name = c.name;
    cam.frame_id = c.name;
    cam.X_PC = c.mount.OpticalPose();
    cam.intrinsics = Named(cam.name, [&] { return c.Intrinsics(); });
    cam.film = LitFilm(c.film, sim);
    cam.period = Period(c.rate_hz);
    cam.lost_from = c.lost_from_s;
    cam.lost_until = c.lost_until_s;
    cameras_.push_back(cam);
  }
  if (cameras_.empty()) return;
  RenderWorldOptions options;
  options.ground_texel_m = sim.render.ground_texel_m;
  options.scene = sim.world.scene;
  options.ground_tags = sim.ground_tags;
  world_ = std::make_shared<const RenderWorld>(map, world.PermanentGeometry(), options);
  for (std::size_t i = 0; i < sim.vehicles.size(); ++i) {
    looks_.push_back(EffectiveLook(sim, i));
    if (looks_.back().tag) (void)world_->Tag(*looks_.back().tag);  // an unknown family fails here
  }
  for (const SimCamera& cam : cameras_) {
    renderers_.push_back(std::make_unique<CameraRenderer>(world_, cam.intrinsics, cam.film));
  }
}

SimCameras::~SimCameras() = default;

std::optional<std::size_t> SimCameras::Find(const std::string& name) const {
  for (std::size_t k = 0; k < cameras_.size(); ++k) {
    if (cameras_[k].name == name) return k;
  }
  return std::nullopt;
}

void SimCameras::Due(Duration now, std::vector<std::size_t>& due) {
  due.clear();
  for (std::size_t k = 0; k < cameras_.size(); ++k) {
    SimCamera& cam = cameras_[k];
    if (cam.next_due > now) continue;
    if (!cam.LostAt(now)) due.push_back(k);
    // The next multiple of the period after now (a frame is never owed twice).
    while (cam.next_due <= now) cam.next_due += cam.period;
  }
}

void SimCameras::Snapshot(const World& world, std::span<const CarLights> lights,
                          std::span<const HeadLamps> lamps,
                          std::span<const RenderTraffic> traffic) {
  if (cameras_.empty()) return;
  time_s_ = ToSeconds(world.time());
  vehicles_.resize(looks_.size());
  for (std::size_t i = 0; i < looks_.size(); ++i) {
    const VehicleState& s = world.State(static_cast<int>(i));
    RenderVehicle& car = vehicles_[i];
    car.index = static_cast<int>(i);
    car.X_MV = Eigen::Translation3d(s.X_MV.translation()) * s.X_MV.rotation();
    car.v_M_mps = s.X_MV.rotation() * s.v_V_mps;
    car.w_M_radps = s.X_MV.rotation() * s.w_V_radps;
    car.params = &world.Params(static_cast<int>(i));
    car.look = looks_[i];
    const CarLights l = i < lights.size() ? lights[i] : CarLights{};
    car.headlights = l.headlights != 0;
    car.left_indicator = l.left_indicator();
    car.right_indicator = l.right_indicator();
  }
  lamps_.assign(lamps.begin(), lamps.end());
  traffic_.assign(traffic.begin(), traffic.end());
  // The unmapped obstacles standing for a while, as blocks among the traffic.
  for (const TimedBox& t : world.TimedBoxes()) {
    if (!t.StandsAt(world.time())) continue;
    RenderTraffic box;
    const Eigen::Vector2d c = t.box.X_MB.translation();
    box.X_MO = Eigen::Translation3d(c.x(), c.y(), world.GroundHeight(c.x(), c.y())) *
               Eigen::AngleAxisd(t.box.X_MB.yaw(), Eigen::Vector3d::UnitZ());
    box.size_m = t.box.size_m;
    box.shape = TrafficShape::kBlock;
    box.body = box.roof = kUnmappedObstacleColour;
    traffic_.push_back(box);
  }
}

Eigen::Isometry3d SimCameras::CameraPose(std::size_t k) const {
  const SimCamera& cam = cameras_.at(k);
  if (!cam.vehicle) return cam.X_PC;
  return vehicles_.at(static_cast<std::size_t>(*cam.vehicle)).X_MV * cam.X_PC;
}

void SimCameras::MakeJob(std::size_t k, std::uint64_t noise_seed, Job& job) const {
  const SimCamera& cam = cameras_.at(k);
  job.vehicles.assign(vehicles_.begin(), vehicles_.end());
  job.lamps.assign(lamps_.begin(), lamps_.end());
  job.traffic.assign(traffic_.begin(), traffic_.end());
  job.time_s = time_s_;
  job.X_MC = CameraPose(k);
  job.v_M.setZero();
  job.w_M.setZero();
  if (cam.vehicle) {
    const RenderVehicle& car = vehicles_.at(static_cast<std::size_t>(*cam.vehicle));
    const Eigen::Vector3d p_VC_M = car.X_MV.linear() * cam.X_PC.translation();
    job.w_M = car.w_M_radps;
    job.v_M = car.v_M_mps + job.w_M.cross(p_VC_M);
  }
  job.noise_seed = noise_seed;
}

void SimCameras::Render(std::size_t k, const Job& job, Image& out) {
  FrameState frame;
  frame.time_s = job.time_s;
  frame.vehicles = job.vehicles;
  frame.lamps = job.lamps;
  frame.traffic = job.traffic;
  renderers_.at(k)->Render(job.X_MC, frame, out, cameras_.at(k).vehicle, job.v_M, job.w_M,
                           job.noise_seed);
}

void SimCameras::Render(std::size_t k, Image& out, std::uint64_t noise_seed) {
  Job& job = scratch_;
  MakeJob(k, noise_seed, job);
  Render(k, job, out);
}

}  // namespace autodrive::vehicle_sim
