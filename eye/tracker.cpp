#include "eye/tracker.h"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "common/geometry.h"

namespace autodrive::eye {

namespace {

constexpr double kMaxBackwards_s = 0.2;

}  // namespace

VehicleTrack::VehicleTrack(const VehicleTagConfig& vehicle, const TrackingConfig& config)
    : vehicle_(vehicle),
      config_(config),
      p_VT_(vehicle.mount.p_VT()),
      yaw_VT_rad_(vehicle.mount.yaw_VT_rad()) {}

double VehicleTrack::VehicleYawOfTag(double tag_yaw_rad) const {
  return std::remainder(tag_yaw_rad - yaw_VT_rad_, 2 * kPi);
}

void VehicleTrack::PredictInPlace(double dt, State& x, Cov& P) const {
  const double th = x(2), v = x(3), w = x(4);
  State next = x;
  Eigen::Matrix<double, 5, 5> F = Eigen::Matrix<double, 5, 5>::Identity();
  if (std::abs(w) > 1e-6) {
    const double th1 = th + w * dt;
    next(0) += v / w * (std::sin(th1) - std::sin(th));
    next(1) += v / w * (std::cos(th) - std::cos(th1));
    F(0, 2) = v / w * (std::cos(th1) - std::cos(th));
    F(1, 2) = v / w * (std::sin(th1) - std::sin(th));
    F(0, 3) = (std::sin(th1) - std::sin(th)) / w;
    F(1, 3) = (std::cos(th) - std::cos(th1)) / w;
    F(0, 4) = v * dt * std::cos(th1) / w - v / (w * w) * (std::sin(th1) - std::sin(th));
    F(1, 4) = v * dt * std::sin(th1) / w - v / (w * w) * (std::cos(th) - std::cos(th1));
  } else {
    next(0) += v * dt * std::cos(th);
    next(1) += v * dt * std::sin(th);
    F(0, 2) = -v * dt * std::sin(th);
    F(1, 2) = v * dt * std::cos(th);
    F(0, 3) = dt * std::cos(th);
    F(1, 3) = dt * std::sin(th);
    F(0, 4) = -0.5 * v * dt * dt * std::sin(th);
    F(1, 4) = 0.5 * v * dt * dt * std::cos(th);
  }
  next(2) = std::remainder(th + w * dt, 2 * kPi);
  F(2, 4) = dt;
  // White acceleration and angular acceleration over the interval.
  const double adt = std::abs(dt);
  Eigen::Matrix<double, 5, 2> G = Eigen::Matrix<double, 5, 2>::Zero();
  G(0, 0) = 0.5 * adt * adt * std::cos(th);
  G(1, 0) = 0.5 * adt * adt * std::sin(th);
  G(3, 0) = adt;
  G(2, 1) = 0.5 * adt * adt;
  G(4, 1) = adt;
  const Eigen::Vector2d q(config_.accel_sigma * config_.accel_sigma,
                          config_.yaw_accel_sigma * config_.yaw_accel_sigma);
  x = next;
  P = F * P * F.transpose() + G * q.asDiagonal() * G.transpose();
}

void VehicleTrack::Start(Time stamp, const PlanarTagPose& tag) {
  const double yaw = VehicleYawOfTag(tag.yaw_rad);
  const double c = std::cos(yaw), s = std::sin(yaw);
  const double a = p_VT_.x(), l = p_VT_.y();
  x_ << tag.p_M.x() - (c * a - s * l), tag.p_M.y() - (s * a + c * l), yaw, 0.0, 0.0;
  P_.setZero();
  P_.topLeftCorner<3, 3>() = tag.covariance;
  P_(3, 3) = 0.3 * 0.3;  // a Nigel drives at up to 0.26 m/s
  P_(4, 4) = 2.0 * 2.0;
  stamp_ = stamp;
  started_ = true;
  outliers_in_a_row_ = 0;
}

void VehicleTrack::Remember() {
  before_.started = started_;
  before_.stamp = stamp_;
  before_.x = x_;
  before_.P = P_;
  before_.outliers_in_a_row = outliers_in_a_row_;
  before_.outliers_total = outliers_total_;
  can_undo_ = true;
}

void VehicleTrack::UndoLastUpdate() {
  if (!can_undo_) return;
  started_ = before_.started;
  stamp_ = before_.stamp;
  x_ = before_.x;
  P_ = before_.P;
  outliers_in_a_row_ = before_.outliers_in_a_row;
  outliers_total_ = before_.outliers_total;
  can_undo_ = false;
}

TrackUpdate VehicleTrack::Update(Time stamp, const PlanarTagPose& tag, bool may_restart) {
  if (remember_) Remember();
  if (!started_) {
    if (!may_restart) return TrackUpdate::kHeld;
    Start(stamp, tag);
    return TrackUpdate::kStarted;
  }
  const double dt = ToSeconds(stamp - stamp_);
  if (dt < -kMaxBackwards_s) return TrackUpdate::kTooOld;
  State x = x_;
  Cov P = P_;
  PredictInPlace(dt, x, P);
  // Measurement: the tag's centre and the car's yaw.
  const double a = p_VT_.x(), l = p_VT_.y();
  const double c = std::cos(x(2)), s = std::sin(x(2));
  const Eigen::Vector3d h(x(0) + c * a - s * l, x(1) + s * a + c * l, x(2));
  Eigen::Matrix<double, 3, 5> H = Eigen::Matrix<double, 3, 5>::Zero();
  H(0, 0) = 1;
  H(0, 2) = -s * a - c * l;
  H(1, 1) = 1;
  H(1, 2) = c * a - s * l;
  H(2, 2) = 1;
  Eigen::Vector3d innovation(tag.p_M.x() - h(0), tag.p_M.y() - h(1),
                             std::remainder(VehicleYawOfTag(tag.yaw_rad) - h(2), 2 * kPi));
  const Eigen::Matrix3d S = H * P * H.transpose() + tag.covariance;
  const Eigen::LDLT<Eigen::Matrix3d> S_ldlt(S);
  const double d2 = innovation.dot(S_ldlt.solve(innovation));
  if (!(d2 <= config_.gate_chi2)) {
    ++outliers_total_;
    if (++outliers_in_a_row_ >= config_.restart_after_outliers && may_restart) {
      Start(stamp, tag);
      return TrackUpdate::kRestarted;
    }
    return TrackUpdate::kOutlier;
  }
  outliers_in_a_row_ = 0;
  const Eigen::Matrix<double, 5, 3> K = P * H.transpose() * S.inverse();
  x += K * innovation;
  x(2) = std::remainder(x(2), 2 * kPi);
  const Cov I_KH = Cov::Identity() - K * H;
  // Joseph form: stays symmetric and positive.
  P = I_KH * P * I_KH.transpose() + K * tag.covariance * K.transpose();
  if (dt >= 0) {
    x_ = x;
    P_ = P;
    stamp_ = stamp;
  } else {
    // A late frame: fused at its own time, then carried forward to the newest time again.
    PredictInPlace(-dt, x, P);
    x_ = x;
    P_ = P;
  }
  return TrackUpdate::kUpdated;
}

bool VehicleTrack::active(Time now) const {
  return started_ && ToSeconds(now - stamp_) <= config_.lost_after_s;
}

VehicleEstimate VehicleTrack::Predict(Time stamp) const {
  State x = x_;
  Cov P = P_;
  const double dt = ToSeconds(stamp - stamp_);
  if (dt != 0) PredictInPlace(dt, x, P);
  VehicleEstimate e;
  e.stamp = stamp;
  e.pose = x.head<3>();
  e.speed_mps = x(3);
  e.yaw_rate_radps = x(4);
  e.covariance = P;
  e.tag_centre_M = x.head<2>() + Eigen::Rotation2Dd(x(2)) * p_VT_;
  return e;
}

}  // namespace autodrive::eye
