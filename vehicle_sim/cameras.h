#pragma once
/// @file
/// The simulator's cameras: every enabled on-board camera (`front_camera`, `rear_camera` per
/// car) and every overhead camera of a city's `sim` section, rendered from one world state by
/// one shared `RenderWorld`, each at its own rate. Used by the DDS service (which publishes the
/// frames) and by `autodrive-sim render` (which writes them to files).
///
/// Timing: camera k's frames fall due at t = j / rate_k of simulated time (j = 0, 1, ...), like
/// the other sensors'; `Due` lists the cameras whose time has come, and a frame rendered at the
/// world's time `t` is stamped `t` (the middle of its exposure).

#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "common/camera/camera_model.h"
#include "common/ids.h"
#include "common/time.h"
#include "vehicle_sim/renderer.h"
#include "vehicle_sim/sim_config.h"

namespace autodrive::maps {
struct Map;
}

namespace autodrive::vehicle_sim {

class World;

/// The devkit's values of `indicators_command` (std_msgs/Int32).
enum class Indicators : std::int32_t { kOff = 0, kLeft = 1, kRight = 2, kBoth = 3 };

/// What a car's lights do, as its `headlights_command` and `indicators_command` last said
/// (the devkit's wire values: headlights 0 off, else on; indicators as `Indicators`).
struct CarLights {
  std::int32_t headlights = 0;
  std::int32_t indicators = 0;

  [[nodiscard]] bool left_indicator() const {
    return indicators == static_cast<std::int32_t>(Indicators::kLeft) ||
           indicators == static_cast<std::int32_t>(Indicators::kBoth);
  }
  [[nodiscard]] bool right_indicator() const {
    return indicators == static_cast<std::int32_t>(Indicators::kRight) ||
           indicators == static_cast<std::int32_t>(Indicators::kBoth);
  }
};

/// One camera of the simulation.
struct SimCamera {
  std::string name;            ///< "nigel_1/front_camera", or an overhead camera's name
  std::string frame_id;        ///< the images' frame id: "front_camera", "rear_camera", or the name
  std::optional<int> vehicle;  ///< the car carrying it (its world index), or none (overhead)
  std::optional<VehicleId> vehicle_id;
  bool front = true;  ///< on-board: front or rear
  /// The optical frame's pose in the car's frame V (on-board) or in the map frame (overhead).
  Eigen::Isometry3d X_PC = Eigen::Isometry3d::Identity();
  camera::Intrinsics intrinsics;
  FilmOptions film;
  Duration period{};
  Duration next_due{0};
  /// Lost (no frame) from..until (overhead cameras' `lost_from_s`, `lost_until_s`).
  std::optional<Duration> lost_from;
  std::optional<Duration> lost_until;
  [[nodiscard]] bool LostAt(Duration t) const {
    return lost_from && *lost_from <= t && (!lost_until || t < *lost_until);
  }
};

class SimCameras {
 public:
  /// The cameras of `sim` for the cars already in `world` (car i of `sim.vehicles` is the
  /// world's vehicle i), drawing `world`'s static geometry on `map`. Builds the ground's
  /// picture once (about a second for a 5 m map). With no camera enabled it holds nothing and
  /// costs nothing. @throws InputError or ConfigError (naming the camera) for a bad lens or tag.
  SimCameras(const SimConfig& sim, const maps::Map& map, const World& world);
  ~SimCameras();
  SimCameras(const SimCameras&) = delete;
  SimCameras& operator=(const SimCameras&) = delete;

  [[nodiscard]] bool empty() const { return cameras_.empty(); }
  [[nodiscard]] const std::vector<SimCamera>& cameras() const { return cameras_; }
  /// The index of the camera named `name` ("nigel_1/front_camera" or an overhead camera's name),
  /// or none.
  [[nodiscard]] std::optional<std::size_t> Find(const std::string& name) const;

  /// The cameras whose frame is due at `now` (their due time passed), each moved to its next
  /// due time; `due` is cleared first. A camera lost at `now` moves on with none due.
  void Due(Duration now, std::vector<std::size_t>& due);

  /// The world's moving parts now, for `Render`: every car with its look, velocity and lights
  /// (`lights[i]` for car i; missing ones are off), the lamps (`lamps(head)`: 0 off,
  /// 1 red, 2 yellow, 3 green; heads not in the map are ignored), and the background traffic.
  void Snapshot(const World& world, std::span<const CarLights> lights,
                std::span<const HeadLamps> lamps, std::span<const RenderTraffic> traffic = {});

  /// Renders camera `k` from the last `Snapshot` into `out`. `noise_seed`: this frame's noise.
  void Render(std::size_t k, Image& out, std::uint64_t noise_seed);

  /// A frame of camera `k` to render later, maybe on another thread: a copy of the last
  /// `Snapshot` and the camera's pose and motion in it.
  struct Job {
    std::vector<RenderVehicle> vehicles;
    std::vector<HeadLamps> lamps;
    std::vector<RenderTraffic> traffic;
    double time_s = 0.0;
    Eigen::Isometry3d X_MC = Eigen::Isometry3d::Identity();
    Eigen::Vector3d v_M = Eigen::Vector3d::Zero(), w_M = Eigen::Vector3d::Zero();
    std::uint64_t noise_seed = 0;
  };
  /// Fills `job` (reusing its storage) for camera `k` from the last `Snapshot`.
  void MakeJob(std::size_t k, std::uint64_t noise_seed, Job& job) const;
  /// Renders `job` with camera `k`'s renderer. Different cameras may render at once on
  /// different threads; one camera on one thread at a time.
  void Render(std::size_t k, const Job& job, Image& out);
  /// The optical frame's pose in the map frame at the last `Snapshot`.
  [[nodiscard]] Eigen::Isometry3d CameraPose(std::size_t k) const;
  /// The last `Snapshot`'s cars (for ground truth).
  [[nodiscard]] std::span<const RenderVehicle> vehicles() const { return vehicles_; }
  /// The renderer of camera k (its statistics).
  [[nodiscard]] const CameraRenderer& renderer(std::size_t k) const { return *renderers_[k]; }

 private:
  std::shared_ptr<const RenderWorld> world_;
  std::vector<SimCamera> cameras_;
  std::vector<std::unique_ptr<CameraRenderer>> renderers_;
  std::vector<VehicleLook> looks_;
  std::vector<RenderVehicle> vehicles_;
  std::vector<HeadLamps> lamps_;
  std::vector<RenderTraffic> traffic_;
  double time_s_ = 0.0;
  Job scratch_;
};

}  // namespace autodrive::vehicle_sim
