#pragma once
/// @file
/// One car as ODE bodies and joints: a chassis, four wheels on hinge-2 joints (steering axis
/// with suspension, spin axis with the drive motor), tyres as force-dependent-slip contacts.
/// Used by World only.

#include <ode/ode.h>

#include <array>
#include <cstdint>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "vehicle_sim/vehicle.h"
#include "vehicle_sim/vehicle_params.h"

namespace autodrive::vehicle_sim::internal {

/// Collision categories (ODE category and collide bits).
enum GeomCategory : unsigned long {
  kTerrainBit = 1UL << 0,
  kObstacleBit = 1UL << 1,
  kChassisBit = 1UL << 2,
  kWheelBit = 1UL << 3,
  kTrafficBit = 1UL << 4,  ///< background traffic (fixed boxes moved each control period)
};

/// What a geom is, kept as its ODE user data.
struct GeomTag {
  enum class Kind { kTerrain, kObstacle, kChassis, kWheel, kTraffic } kind = Kind::kObstacle;
  int vehicle = -1;  ///< for chassis and wheels
  int wheel = -1;    ///< for wheels: index of `Wheel`
  int traffic = -1;  ///< for background traffic: its index in `World::SetTraffic`'s boxes
};

/// The tyre of one wheel for the coming step: the force-dependent-slip coefficients and
/// friction limits of its contact, from the tyre curves at the last step's slip.
struct TyreContact {
  double slip_longitudinal = 0.0;  ///< FDS coefficient along the rolling direction (m/s/N)
  double slip_lateral = 0.0;       ///< along the axle
  double mu_longitudinal = 0.0;    ///< friction limit over the normal force
  double mu_lateral = 0.0;
  dVector3 axle_M{0, 0, 0, 0};  ///< the wheel's spin axis, map frame
};

class OdeVehicle {
 public:
  /// Builds the car at rest at (x, y, yaw) on ground of height `ground_z_m` (slope ignored:
  /// the car settles onto it), in `world` and `space`.
  OdeVehicle(const VehicleParams& params, int index, dWorldID world, dSpaceID space,
             double gravity_mps2, double step_s, double x_m, double y_m, double yaw_rad,
             double ground_z_m);
  ~OdeVehicle();
  OdeVehicle(const OdeVehicle&) = delete;
  OdeVehicle& operator=(const OdeVehicle&) = delete;

  void SetCommand(const VehicleCommand& command) { command_ = command; }
  /// Sets every body of the car moving rigidly with the chassis: `v_M` at the chassis' centre
  /// of mass and `w_M` (map frame).
  void SetVelocity(const Eigen::Vector3d& v_M, const Eigen::Vector3d& w_M);
  /// Before collision: actuators (steering slew, Ackermann, drive/brake motors), rolling
  /// resistance, and the tyre contacts for this step.
  void PrepareStep();
  /// A contact of wheel `wheel` with the ground, from the collision callback: fills the
  /// contact's surface (tyre) and attaches the wheel's feedback slot to `joint` afterwards.
  void FillTyreContact(int wheel, dContact& contact) const;
  /// After `joint` (the contact of wheel `wheel`, wheel as body 1) was made: its force is read
  /// back after the step; `normal` is the contact's normal.
  void AttachFeedback(int wheel, dJointID joint, const dReal* normal);
  /// Before the ODE step: the name and value of the first body quantity beyond anything a lab
  /// car can reach (position beyond 1e6 m, speed beyond 1e4 m/s, spin beyond 1e5 rad/s, or not
  /// finite), or empty. ODE aborts the process on a state that overflows inside its step (a
  /// quaternion it cannot normalise), so a diverging state is stopped here first.
  std::string CheckBeforeStep() const;
  /// After the ODE step: normal forces, spin integrals, encoder ticks, the state snapshot.
  /// Returns the name of the first non-finite quantity, or empty.
  std::string FinishStep();

  [[nodiscard]] const VehicleState& state() const { return state_; }
  /// The body's collision box now: pose and half extents.
  void Box(Eigen::Isometry3d& X_MB, Eigen::Vector3d& half_extents_m) const;
  [[nodiscard]] const VehicleParams& params() const { return params_; }

 private:
  void UpdateState(bool first);

  VehicleParams params_;
  std::array<TyreCurve, 4> tyres_;  // resolved: front long/lat, rear long/lat
  int index_;
  double gravity_;
  double step_s_;
  dBodyID chassis_ = nullptr;
  dGeomID chassis_geom_ = nullptr;
  std::array<dBodyID, kWheels> wheels_{};
  std::array<dGeomID, kWheels> wheel_geoms_{};
  std::array<dJointID, kWheels> joints_{};
  GeomTag chassis_tag_;
  std::array<GeomTag, kWheels> wheel_tags_{};
  std::array<TyreContact, kWheels> tyre_{};
  std::array<dJointFeedback, kWheels> feedback_{};
  std::array<bool, kWheels> in_contact_{};              // this step's contact (the last, before it)
  std::array<Eigen::Vector3d, kWheels> last_normal_{};  // the ground's, up, at the last contact
  std::array<double, kWheels> static_load_n_{};
  Eigen::Vector3d p_VC_;  // the chassis' centre of mass in V
  VehicleCommand command_;
  double steering_rad_ = 0.0;  // actuator state
  Eigen::Vector3d last_com_velocity_M_ = Eigen::Vector3d::Zero();
  VehicleState state_;
};

}  // namespace autodrive::vehicle_sim::internal
