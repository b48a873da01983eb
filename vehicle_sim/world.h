#pragma once
/// @file
/// The simulated world on ODE: the ground (and the terrain of a map, with its ramps), the map's
/// walls, boxes, light poles and signs as static obstacles, the background traffic as fixed
/// boxes that the caller moves (`SetTraffic`), and the vehicles, stepped together at a fixed
/// physics step. See docs/vehicle_sim.md for the model and how the tyre curve meets
/// ODE's contacts.
///
/// Copy: no (it owns an ODE world). Move: no. One thread steps a World at a time; several
/// Worlds may live in one process (each is deterministic on its own: `dWorldStep`, whose
/// solver has no random reordering, and collision spaces whose order depends on insertion
/// only).

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "common/geometry.h"
#include "common/time.h"
#include "vehicle_sim/raycast.h"
#include "vehicle_sim/vehicle.h"
#include "vehicle_sim/vehicle_params.h"

namespace autodrive::maps {
struct Map;
}

namespace autodrive::vehicle_sim {

/// How the world is stepped, and its contacts other than the tyres'.
struct WorldOptions {
  /// Physics step. 2 ms: ODE's implicit joints, motors and force-dependent-slip tyres are
  /// stable far beyond it; the explicit parts (rolling resistance) have time constants above
  /// a second; a car at top speed moves 0.5 mm per step, so nothing tunnels.
  Duration step = std::chrono::milliseconds(2);
  double gravity_mps2 = 9.81;
  /// Coulomb friction between bodies (car against wall, box or car), not the tyres.
  double body_friction = 0.5;
  double body_bounce = 0.1;  ///< restitution of body contacts
  /// The static world's poles (at signal heads and signs) and the sensors' ray-casting grid.
  StaticSceneOptions scene;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional(
        "step_s", step,
        config::Range<Duration>{std::chrono::microseconds(100), std::chrono::milliseconds(20)});
    a.Optional("gravity_mps2", gravity_mps2, config::Range{0.0, 100.0});
    a.Optional("body_friction", body_friction, config::Range{0.0, 10.0});
    a.Optional("body_bounce", body_bounce, config::Range{0.0, 1.0});
    a.Optional("scene", scene);
  }
  bool operator==(const WorldOptions&) const = default;
};

/// A step produced a non-finite number, or a car's state diverged beyond anything a lab car
/// reaches (checked before each step, since ODE aborts on a state that overflows inside its
/// step). The message names the vehicle, the step and the quantity; the world is not stepped
/// further (`Step` throws again).
class NumericalError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// An extra static box in the world (an unmapped obstacle): footprint centre, yaw, size.
struct StaticBox {
  RigidTransform2 X_MB;                   ///< centre of the footprint and its heading
  Eigen::Vector3d size_m{0.1, 0.1, 0.1};  ///< length (along B's x), width, height
};

/// An unmapped obstacle that stands only for a while: placed at `from`, removed at `until`.
struct TimedBox {
  StaticBox box;
  Duration from{0};
  std::optional<Duration> until{};  ///< none: it stays
  /// Whether it stands at `t`: from <= t < until.
  [[nodiscard]] bool StandsAt(Duration t) const { return from <= t && (!until || t < *until); }
};

/// A car's body touching a background object in a step.
struct TrafficContact {
  int vehicle = 0;  ///< the car's index
  int traffic = 0;  ///< the object's index in the boxes of the last `World::SetTraffic`
  bool operator==(const TrafficContact&) const = default;
};

class World {
 public:
  /// A world on flat ground (z = 0 everywhere), with nothing on it.
  explicit World(const WorldOptions& options = {});
  /// The world of a built map: its terrain (flat ground when it has no ramps or raised tiles,
  /// else a triangle mesh over the map's extent, two triangles per tile, as maps/ writes
  /// mesh.obj, with the lab's floor at z = 0 around it) and its static geometry as the sensors
  /// see it (`GeometryFromMap`: every obstacle standing on the terrain, a pole at every signal
  /// head and sign). @throws InputError for an obstacle that is not a rectangle.
  World(const maps::Map& map, const WorldOptions& options = {});
  ~World();
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  /// Adds an unmapped obstacle (standing at z = 0 on flat ground, or on the terrain).
  void AddStaticBox(const StaticBox& box);
  /// Adds an unmapped obstacle that stands only while `TimedBox::StandsAt(time())`: from the
  /// step that reaches `from` to the step that reaches `until`, it is in the physics (a static
  /// box, as `AddStaticBox`) and in `Scene()`; otherwise neither. A box due where a car's
  /// body is cannot be put there: the step that would place it throws InputError (naming the
  /// car and the time). @throws InputError for a size that is not positive, or `until` not
  /// after `from`.
  void AddTimedBox(const TimedBox& box);
  /// The timed boxes in the order added.
  [[nodiscard]] std::span<const TimedBox> TimedBoxes() const;

  /// The background traffic from the next step on, replacing the last call's: each box (map
  /// frame: centre, axes, half extents, as the LIDAR takes it) a fixed obstacle for the cars'
  /// bodies, of infinite mass (a car that drives into one stops against it and does not push
  /// it). Boxes do not touch the static world or each other. Only the boxes within reach of a
  /// car are given to ODE, chosen again when the boxes change or a car has moved 0.25 m, so
  /// that thousands of them cost little. @throws InputError for a non-finite pose or a
  /// half extent that is not positive and finite.
  void SetTraffic(std::span<const DynamicBox> boxes);
  /// The cars and background objects whose bodies touched in the last step, each pair once,
  /// in a deterministic order.
  [[nodiscard]] std::span<const TrafficContact> TrafficContacts() const;

  /// Adds a vehicle at rest at `X_MV` (its rear axle's middle; z from the terrain), wheels on
  /// the ground, springs at their static deflection. Returns its index (0, 1, ...).
  /// @throws InputError (or ConfigError) when `params` fail their validation.
  int AddVehicle(const VehicleParams& params, const RigidTransform2& X_MV);

  /// The command that holds from the next step on. @throws InputError for a non-finite value.
  void SetCommand(int vehicle, const VehicleCommand& command);
  /// Sets the car moving rigidly: every body (chassis and wheels) takes the velocity of the
  /// chassis point it is at, for `v_M` at the chassis' centre of mass and angular velocity
  /// `w_M` (map frame). The wheels do not spin about their axles, so they skid until the tyres
  /// take them up: a scenario that starts at speed, a knock. Its state shows it after the next
  /// step. @throws InputError for a non-finite value.
  void SetVelocity(int vehicle, const Eigen::Vector3d& v_M, const Eigen::Vector3d& w_M);
  /// One physics step of `options().step`. @throws NumericalError (see the class), InputError
  /// when a timed box falls due where a car is (`AddTimedBox`).
  void Step();
  /// Steps until `time()` reaches `until` (whole steps; none when it already has).
  void StepUntil(Duration until);

  [[nodiscard]] const VehicleState& State(int vehicle) const;
  /// The pose of the car's collision box (its body, spanning the wheels) and its half
  /// extents (m): what other cars' LIDARs and cameras see of it.
  void VehicleBox(int vehicle, Eigen::Isometry3d& X_MB, Eigen::Vector3d& half_extents_m) const;
  [[nodiscard]] const VehicleParams& Params(int vehicle) const;
  [[nodiscard]] int vehicles() const;
  /// Simulated time since the start: steps() * step.
  [[nodiscard]] Duration time() const;
  [[nodiscard]] std::int64_t steps() const;
  [[nodiscard]] const WorldOptions& options() const;
  /// Height of the ground at (x, y) as the world has it (0 off the map).
  [[nodiscard]] double GroundHeight(double x_m, double y_m) const;
  /// The static world (terrain, obstacles, poles, unmapped boxes, the timed boxes standing now)
  /// indexed for ray casting: what the LIDAR sees. Built on first use and again after
  /// `AddStaticBox` and whenever a timed box is placed or removed (about a millisecond).
  [[nodiscard]] const StaticScene& Scene() const;
  /// What stands for the whole run: `Scene()`'s geometry without the timed boxes (the cameras'
  /// ground and solid objects are built from it once; they draw the timed boxes as they stand).
  [[nodiscard]] const StaticGeometry& PermanentGeometry() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace autodrive::vehicle_sim
