#include "vehicle_sim/internal/ode_vehicle.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>

#include <Eigen/Geometry>

#include "common/error.h"

namespace autodrive::vehicle_sim::internal {

namespace {

// ODE's hinge-2 rates and motor velocities are of body 1 (the chassis) relative to body 2 (the
// wheel): a wheel spinning forward about its left-pointing axle is a negative rate, and a wheel
// turned left (positive about the chassis' z) a negative angle 1.
constexpr double kSpinMotorSign = -1.0;
constexpr double kSteerJointSign = -1.0;

// Contact softness of the tyres' normal direction (ODE ERP and CFM).
constexpr double kTyreErp = 0.5;
constexpr double kTyreCfm = 1e-6;

Eigen::Vector3d ToEigen(const dReal* v) { return {v[0], v[1], v[2]}; }

Eigen::Matrix3d RotationOf(dBodyID body) {
  const dReal* R = dBodyGetRotation(body);  // 3x4, row-major
  Eigen::Matrix3d m;
  m << R[0], R[1], R[2], R[4], R[5], R[6], R[8], R[9], R[10];
  return m;
}

Eigen::Vector3d AxleOf(dJointID joint) {
  dVector3 a;
  dJointGetHinge2Axis2(joint, a);
  return ToEigen(a);
}

bool Finite(const dReal* v, int n) {
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(v[i])) return false;
  }
  return true;
}

bool IsFront(int wheel) { return wheel < 2; }

bool IsDriven(DriveLayout layout, int wheel) {
  switch (layout) {
    case DriveLayout::kRear:
      return !IsFront(wheel);
    case DriveLayout::kFront:
      return IsFront(wheel);
    case DriveLayout::kAll:
      return true;
  }
  return false;
}

}  // namespace

OdeVehicle::OdeVehicle(const VehicleParams& params, int index, dWorldID world, dSpaceID space,
                       double gravity_mps2, double step_s, double x_m, double y_m, double yaw_rad,
                       double ground_z_m)
    : params_(params),
      tyres_(params.ResolvedTyres(gravity_mps2)),
      index_(index),
      gravity_(gravity_mps2),
      step_s_(step_s) {
  params_.Validate();
  const VehicleParams& p = params_;
  const double L = p.wheelbase_m;
  const double r = p.wheel_radius_m;
  const double mw = p.wheel_mass_kg;
  const double chassis_mass = p.mass_kg - 4 * mw;

  // Wheel centres in V: front left, front right, rear left, rear right.
  const std::array<Eigen::Vector3d, kWheels> p_VW = {
      Eigen::Vector3d(L, p.track_width_m / 2, r), Eigen::Vector3d(L, -p.track_width_m / 2, r),
      Eigen::Vector3d(0, p.track_width_m / 2, r), Eigen::Vector3d(0, -p.track_width_m / 2, r)};
  // The whole car's centre of mass is given; the chassis' is what remains without the wheels.
  const Eigen::Vector3d p_VCom(p.com_ahead_of_rear_axle_m, 0, p.com_height_m);
  Eigen::Vector3d wheels_moment = Eigen::Vector3d::Zero();
  for (const auto& w : p_VW) wheels_moment += mw * w;
  p_VC_ = (p.mass_kg * p_VCom - wheels_moment) / chassis_mass;

  // Yaw inertia: the whole car's figure, less the wheels' (own and parallel-axis) and the
  // chassis' offset from the whole centre of mass.
  const double wheel_radial = mw * (3 * r * r + p.wheel_width_m * p.wheel_width_m) / 12;
  double izz = p.yaw_inertia_kgm2 - chassis_mass * (p_VC_ - p_VCom).head<2>().squaredNorm();
  for (const auto& w : p_VW) izz -= wheel_radial + mw * (w - p_VCom).head<2>().squaredNorm();
  AUTODRIVE_THROW_UNLESS(
      izz > 0, "yaw_inertia_kgm2 " << p.yaw_inertia_kgm2 << " is less than the wheels alone give");
  // Roll and pitch: a uniform box of the body's size, scaled by the same factor as yaw.
  const double bl = p.body_length_m;
  const double bw = p.body_width_m;
  const double bh = p.body_height_m - p.body_clearance_m;
  const double box_scale = izz / (chassis_mass * (bl * bl + bw * bw) / 12);
  const double ixx = box_scale * chassis_mass * (bw * bw + bh * bh) / 12;
  const double iyy = box_scale * chassis_mass * (bl * bl + bh * bh) / 12;

  // Suspension: each corner carries its share of the chassis (the sprung masses, whose centre
  // of mass is the chassis'); stiffness and damping from the natural frequency.
  const double omega_n = 2 * std::numbers::pi * p.suspension_frequency_hz;
  const double sag = gravity_mps2 / (omega_n * omega_n);  // same static deflection everywhere
  const double front_share = p_VC_.x() / L;

  const Eigen::Matrix3d R_MV = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).matrix();
  // The wheels stand on the ground; the joints are made with the chassis `sag` above its place
  // (so the springs' rest length is that), then the chassis is lowered onto its place.
  const Eigen::Vector3d p_MV(x_m, y_m, ground_z_m);
  dMatrix3 R;
  dRFromAxisAndAngle(R, 0, 0, 1, yaw_rad);

  chassis_ = dBodyCreate(world);
  const Eigen::Vector3d p_MC = p_MV + R_MV * p_VC_ + Eigen::Vector3d(0, 0, sag);
  dBodySetPosition(chassis_, p_MC.x(), p_MC.y(), p_MC.z());
  dBodySetRotation(chassis_, R);
  dMass m;
  dMassSetParameters(&m, chassis_mass, 0, 0, 0, ixx, iyy, izz, 0, 0, 0);
  dBodySetMass(chassis_, &m);

  // The body's collision box spans the wheels too: the wheels only touch the ground.
  const double box_width = std::max(p.body_width_m, p.track_width_m + p.wheel_width_m);
  chassis_geom_ = dCreateBox(space, bl, box_width, bh);
  dGeomSetBody(chassis_geom_, chassis_);
  const Eigen::Vector3d box_offset =
      Eigen::Vector3d(p.body_centre_ahead_of_rear_axle_m, 0, p.body_clearance_m + bh / 2) - p_VC_;
  dGeomSetOffsetPosition(chassis_geom_, box_offset.x(), box_offset.y(), box_offset.z());
  chassis_tag_ = {GeomTag::Kind::kChassis, index, -1, -1};
  dGeomSetData(chassis_geom_, &chassis_tag_);
  dGeomSetCategoryBits(chassis_geom_, kChassisBit);
  dGeomSetCollideBits(chassis_geom_, kTerrainBit | kObstacleBit | kChassisBit | kTrafficBit);

  const double inner_limit = AckermannAngles(p.steering_limit_rad, L, p.track_width_m)[0] + 0.05;
  for (int i = 0; i < kWheels; ++i) {
    const Eigen::Vector3d p_MW = p_MV + R_MV * p_VW[static_cast<std::size_t>(i)];
    const auto ui = static_cast<std::size_t>(i);
    wheels_[ui] = dBodyCreate(world);
    dBodySetPosition(wheels_[ui], p_MW.x(), p_MW.y(), p_MW.z());
    dBodySetRotation(wheels_[ui], R);
    dMassSetCylinderTotal(&m, mw, 2, r, p.wheel_width_m);  // axis along the body's y
    dBodySetMass(wheels_[ui], &m);
    // A sphere touches the ground at one point below the axle whatever the wheel's spin.
    wheel_geoms_[ui] = dCreateSphere(space, r);
    dGeomSetBody(wheel_geoms_[ui], wheels_[ui]);
    wheel_tags_[ui] = {GeomTag::Kind::kWheel, index, i, -1};
    dGeomSetData(wheel_geoms_[ui], &wheel_tags_[ui]);
    dGeomSetCategoryBits(wheel_geoms_[ui], kWheelBit);
    dGeomSetCollideBits(wheel_geoms_[ui], kTerrainBit);

    dJointID j = dJointCreateHinge2(world, nullptr);
    joints_[ui] = j;
    dJointAttach(j, chassis_, wheels_[ui]);
    dJointSetHinge2Anchor(j, p_MW.x(), p_MW.y(), p_MW.z());
    const Eigen::Vector3d axis1 = R_MV.col(2);
    const Eigen::Vector3d axis2 = R_MV.col(1);
    const dReal a1[3] = {axis1.x(), axis1.y(), axis1.z()};
    const dReal a2[3] = {axis2.x(), axis2.y(), axis2.z()};
    dJointSetHinge2Axes(j, a1, a2);
    const double sprung = chassis_mass * (IsFront(i) ? front_share : 1 - front_share) / 2;
    const double k = sprung * omega_n * omega_n;
    const double b = 2 * p.suspension_damping_ratio * std::sqrt(k * sprung);
    dJointSetHinge2Param(j, dParamSuspensionERP, step_s * k / (step_s * k + b));
    dJointSetHinge2Param(j, dParamSuspensionCFM, 1 / (step_s * k + b));
    const double limit = IsFront(i) ? inner_limit : 0.0;
    dJointSetHinge2Param(j, dParamLoStop, -limit);
    dJointSetHinge2Param(j, dParamHiStop, limit);
    static_load_n_[ui] =
        IsFront(i) ? p.FrontWheelLoadN(gravity_mps2) : p.RearWheelLoadN(gravity_mps2);
  }
  // Lower the chassis onto its place: the springs, at rest length where the joints were made,
  // are now compressed by the sag and carry the chassis' weight from the first step on.
  const Eigen::Vector3d p_MC_rest = p_MV + R_MV * p_VC_;
  dBodySetPosition(chassis_, p_MC_rest.x(), p_MC_rest.y(), p_MC_rest.z());
  UpdateState(true);
}

OdeVehicle::~OdeVehicle() {
  for (dJointID j : joints_) dJointDestroy(j);
  for (dGeomID g : wheel_geoms_) dGeomDestroy(g);
  dGeomDestroy(chassis_geom_);
  for (dBodyID b : wheels_) dBodyDestroy(b);
  dBodyDestroy(chassis_);
}

void OdeVehicle::PrepareStep() {
  const VehicleParams& p = params_;
  const double h = step_s_;
  const double throttle = std::clamp(command_.throttle, -1.0, 1.0);
  const double steering = std::clamp(command_.steering, -1.0, 1.0);

  // Steering actuator: slews to the command at its rate; each front wheel follows its
  // Ackermann angle through the joint's motor, limited by the servo's torque.
  const double max_move = p.steering_rate_radps * h;
  steering_rad_ += std::clamp(steering * p.steering_limit_rad - steering_rad_, -max_move, max_move);
  const std::array<double, 2> angles =
      AckermannAngles(steering_rad_, p.wheelbase_m, p.track_width_m);
  for (int i = 0; i < 2; ++i) {
    const dJointID j = joints_[static_cast<std::size_t>(i)];
    const double error =
        kSteerJointSign * angles[static_cast<std::size_t>(i)] - dJointGetHinge2Angle1(j);
    dJointSetHinge2Param(j, dParamVel, error / h);
    dJointSetHinge2Param(j, dParamFMax, p.steering_torque_nm);
  }

  const Eigen::Vector3d w_chassis = ToEigen(dBodyGetAngularVel(chassis_));
  const Eigen::Matrix3d R_MC = RotationOf(chassis_);
  std::array<double, kWheels> ground_speed{};  // of each wheel's centre along its heading
  for (int i = 0; i < kWheels; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const Eigen::Vector3d axle = AxleOf(joints_[ui]);
    const Eigen::Vector3d w_wheel = ToEigen(dBodyGetAngularVel(wheels_[ui]));
    // Rolling resistance: rotational damping of the wheel against the chassis.
    const Eigen::Vector3d damping =
        -p.rolling_resistance_nms * (w_wheel - w_chassis).dot(axle) * axle;
    dBodyAddTorque(wheels_[ui], damping.x(), damping.y(), damping.z());
    dBodyAddTorque(chassis_, -damping.x(), -damping.y(), -damping.z());

    // The tyre for this step, from the slip at the last one.
    const Eigen::Vector3d up = in_contact_[ui] ? last_normal_[ui] : Eigen::Vector3d(R_MC.col(2));
    Eigen::Vector3d forward = axle.cross(up);
    if (forward.norm() < 1e-9) forward = R_MC.col(0);
    forward.normalize();
    const Eigen::Vector3d left = up.cross(forward);
    const Eigen::Vector3d v = ToEigen(dBodyGetLinearVel(wheels_[ui]));
    const double vx = v.dot(forward);
    const double vy = v.dot(left);
    ground_speed[ui] = vx;
    const double v_ref = std::hypot(vx, p.slip_speed_guard_mps);
    const double spin = w_wheel.dot(axle);
    WheelState& ws = state_.wheels[ui];
    ws.slip_longitudinal = (p.wheel_radius_m * spin - vx) / v_ref;
    ws.slip_lateral = vy / v_ref;
    const double load = in_contact_[ui] ? std::max(ws.normal_force_n, 0.05 * static_load_n_[ui])
                                        : static_load_n_[ui];
    const TyreCurve& lon = tyres_[IsFront(i) ? 0 : 2];
    const TyreCurve& lat = tyres_[IsFront(i) ? 1 : 3];
    const double mu = p.friction_coefficient;
    TyreContact& t = tyre_[ui];
    t.slip_longitudinal = v_ref / (load * mu * lon.Secant(ws.slip_longitudinal));
    t.slip_lateral = v_ref / (load * mu * lat.Secant(ws.slip_lateral));
    t.mu_longitudinal = mu * lon.extremum_value;
    t.mu_lateral = mu * lat.extremum_value;
    t.axle_M[0] = axle.x();
    t.axle_M[1] = axle.y();
    t.axle_M[2] = axle.z();
    in_contact_[ui] = false;
  }

  // Drive: speed-controlled motors (target: throttle x top speed over the wheel radius),
  // torque saturated at the drive torque, as ODE joint motors (implicit: they hold their speed
  // downhill and never go unstable, whatever the wheel's inertia). The two wheels of an axle
  // share the target as an open differential would: their mean is the target, and each wheel
  // runs faster or slower by its own ground speed's difference from the axle's mean (last
  // step), so that in a curve neither wheel scrubs. At zero throttle the motors hold each
  // driven wheel at zero speed with the brake torque; wheels that are not driven roll freely.
  const double wheel_speed =
      (throttle >= 0 ? throttle * p.top_speed_mps : throttle * p.reverse_top_speed_mps) /
      p.wheel_radius_m;
  for (int i = 0; i < kWheels; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const dJointID j = joints_[ui];
    if (!IsDriven(p.drive, i)) {
      dJointSetHinge2Param(j, dParamFMax2, 0.0);
      continue;
    }
    double target = 0.0;
    if (throttle != 0.0) {
      const std::size_t other = ui ^ 1U;  // the other wheel of the axle
      target = wheel_speed + 0.5 * (ground_speed[ui] - ground_speed[other]) / p.wheel_radius_m;
    }
    dJointSetHinge2Param(j, dParamVel2, kSpinMotorSign * target);
    dJointSetHinge2Param(j, dParamFMax2, throttle != 0.0 ? p.drive_torque_nm : p.brake_torque_nm);
  }
}

void OdeVehicle::FillTyreContact(int wheel, dContact& contact) const {
  const TyreContact& t = tyre_[static_cast<std::size_t>(wheel)];
  contact.surface.mode = dContactMu2 | dContactFDir1 | dContactSlip1 | dContactSlip2 |
                         dContactSoftERP | dContactSoftCFM | dContactApprox1;
  contact.surface.mu = t.mu_longitudinal;
  contact.surface.mu2 = t.mu_lateral;
  contact.surface.slip1 = t.slip_longitudinal;
  contact.surface.slip2 = t.slip_lateral;
  contact.surface.soft_erp = kTyreErp;
  contact.surface.soft_cfm = kTyreCfm;
  // Friction direction 1 rolls with the wheel: perpendicular to the axle and the normal.
  const Eigen::Vector3d axle = ToEigen(t.axle_M);
  Eigen::Vector3d dir = axle.cross(ToEigen(contact.geom.normal));
  if (dir.norm() < 1e-9) dir = Eigen::Vector3d::UnitX();
  dir.normalize();
  contact.fdir1[0] = dir.x();
  contact.fdir1[1] = dir.y();
  contact.fdir1[2] = dir.z();
}

void OdeVehicle::AttachFeedback(int wheel, dJointID joint, const dReal* normal) {
  const auto ui = static_cast<std::size_t>(wheel);
  dJointSetFeedback(joint, &feedback_[ui]);
  in_contact_[ui] = true;
  Eigen::Vector3d n = ToEigen(normal);
  if (n.z() < 0) n = -n;  // the ground's normal, pointing up out of it
  last_normal_[ui] = n;
}

std::string OdeVehicle::CheckBeforeStep() const {
  constexpr double kMaxPosition = 1e6, kMaxSpeed = 1e4, kMaxSpin = 1e5;
  const auto check = [](const std::string& what, const dReal* v, double limit,
                        const char* unit) -> std::string {
    const double norm = ToEigen(v).stableNorm();  // no overflow of the squares
    if (std::isfinite(norm) && norm <= limit) return {};
    std::ostringstream out;
    out << what << " (" << norm << ' ' << unit << ')';
    return out.str();
  };
  std::string bad = check("chassis position", dBodyGetPosition(chassis_), kMaxPosition, "m");
  if (bad.empty()) bad = check("chassis velocity", dBodyGetLinearVel(chassis_), kMaxSpeed, "m/s");
  if (bad.empty()) {
    bad = check("chassis angular velocity", dBodyGetAngularVel(chassis_), kMaxSpin, "rad/s");
  }
  for (int i = 0; i < kWheels && bad.empty(); ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const std::string name(ToString(static_cast<Wheel>(i)));
    bad = check(name + " wheel velocity", dBodyGetLinearVel(wheels_[ui]), kMaxSpeed, "m/s");
    if (bad.empty()) {
      bad = check(name + " wheel spin", dBodyGetAngularVel(wheels_[ui]), kMaxSpin, "rad/s");
    }
  }
  return bad;
}

void OdeVehicle::SetVelocity(const Eigen::Vector3d& v_M, const Eigen::Vector3d& w_M) {
  const Eigen::Vector3d c = ToEigen(dBodyGetPosition(chassis_));
  dBodySetLinearVel(chassis_, v_M.x(), v_M.y(), v_M.z());
  dBodySetAngularVel(chassis_, w_M.x(), w_M.y(), w_M.z());
  for (dBodyID wheel : wheels_) {
    const Eigen::Vector3d v = v_M + w_M.cross(ToEigen(dBodyGetPosition(wheel)) - c);
    dBodySetLinearVel(wheel, v.x(), v.y(), v.z());
    dBodySetAngularVel(wheel, w_M.x(), w_M.y(), w_M.z());
  }
}

std::string OdeVehicle::FinishStep() {
  for (int i = 0; i < kWheels; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    state_.wheels[ui].normal_force_n =
        in_contact_[ui] ? std::abs(ToEigen(feedback_[ui].f1).dot(last_normal_[ui])) : 0.0;
  }
  UpdateState(false);
  if (!Finite(dBodyGetPosition(chassis_), 3)) return "chassis position";
  if (!Finite(dBodyGetQuaternion(chassis_), 4)) return "chassis orientation";
  if (!Finite(dBodyGetLinearVel(chassis_), 3)) return "chassis velocity";
  if (!Finite(dBodyGetAngularVel(chassis_), 3)) return "chassis angular velocity";
  for (int i = 0; i < kWheels; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const std::string name(ToString(static_cast<Wheel>(i)));
    if (!Finite(dBodyGetPosition(wheels_[ui]), 3)) return name + " wheel position";
    if (!Finite(dBodyGetLinearVel(wheels_[ui]), 3)) return name + " wheel velocity";
    if (!Finite(dBodyGetAngularVel(wheels_[ui]), 3)) return name + " wheel spin";
    if (!std::isfinite(state_.wheels[ui].normal_force_n)) return name + " wheel normal force";
  }
  return {};
}

void OdeVehicle::Box(Eigen::Isometry3d& X_MB, Eigen::Vector3d& half_extents_m) const {
  const dReal* p = dGeomGetPosition(chassis_geom_);
  const dReal* R = dGeomGetRotation(chassis_geom_);
  Eigen::Matrix3d rotation;
  rotation << R[0], R[1], R[2], R[4], R[5], R[6], R[8], R[9], R[10];
  X_MB.setIdentity();
  X_MB.linear() = rotation;
  X_MB.translation() = ToEigen(p);
  dVector3 lengths;
  dGeomBoxGetLengths(chassis_geom_, lengths);
  half_extents_m = 0.5 * ToEigen(lengths);
}

void OdeVehicle::UpdateState(bool first) {
  const Eigen::Matrix3d R_MC = RotationOf(chassis_);
  const Eigen::Vector3d p_MC = ToEigen(dBodyGetPosition(chassis_));
  const Eigen::Vector3d p_MV = p_MC - R_MC * p_VC_;
  const Eigen::Vector3d v_com = ToEigen(dBodyGetLinearVel(chassis_));
  const Eigen::Vector3d w = ToEigen(dBodyGetAngularVel(chassis_));
  const dReal* q = dBodyGetQuaternion(chassis_);  // w, x, y, z
  state_.X_MV = RigidTransform3(p_MV, Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized());
  const Eigen::Vector3d v_V_M = v_com + w.cross(p_MV - p_MC);
  state_.v_V_mps = R_MC.transpose() * v_V_M;
  state_.w_V_radps = R_MC.transpose() * w;
  state_.a_V_mps2 =
      first ? Eigen::Vector3d::Zero()
            : Eigen::Vector3d(R_MC.transpose() * (v_com - last_com_velocity_M_) / step_s_);
  last_com_velocity_M_ = v_com;
  for (int i = 0; i < kWheels; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    WheelState& ws = state_.wheels[ui];
    const Eigen::Vector3d axle = AxleOf(joints_[ui]);
    ws.spin_radps = (ToEigen(dBodyGetAngularVel(wheels_[ui])) - w).dot(axle);
    if (!first) ws.spin_angle_rad += ws.spin_radps * step_s_;
    const Eigen::Vector3d axle_C = R_MC.transpose() * axle;
    ws.steer_rad = IsFront(i) ? std::atan2(-axle_C.x(), axle_C.y()) : 0.0;
  }
  state_.steering_rad = steering_rad_;
  state_.throttle = std::clamp(command_.throttle, -1.0, 1.0);
  const double cpr = params_.encoder_counts_per_rev;
  for (int k = 0; k < 2; ++k) {
    const double turns =
        state_.wheels[static_cast<std::size_t>(2 + k)].spin_angle_rad / (2 * std::numbers::pi);
    state_.encoder_ticks[static_cast<std::size_t>(k)] =
        static_cast<std::int64_t>(std::floor(turns * cpr));
  }
}

}  // namespace autodrive::vehicle_sim::internal
