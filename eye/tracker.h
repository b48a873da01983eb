#pragma once
/// @file
/// A filter per car: an extended Kalman filter on the constant-turn-rate-and-velocity model of
/// the car's origin (the middle of its rear axle, where a car's velocity lies along its
/// heading), updated with its roof tag's planar pose, with outlier gating and prediction
/// through missed frames.

#include <optional>

#include <Eigen/Core>

#include "common/time.h"
#include "eye/eye_config.h"
#include "eye/tag_pose.h"

namespace autodrive::eye {

/// A car's estimated state at a time.
struct VehicleEstimate {
  Time stamp{};
  /// The car's origin and heading in M: x, y (m) and yaw (rad, from M's x to V's x).
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();
  double speed_mps = 0.0;       ///< along V's x
  double yaw_rate_radps = 0.0;  ///< about z
  /// Covariance of (x, y, yaw, speed, yaw rate).
  Eigen::Matrix<double, 5, 5> covariance = Eigen::Matrix<double, 5, 5>::Zero();
  /// The roof tag's centre in M (m), from the pose.
  Eigen::Vector2d tag_centre_M = Eigen::Vector2d::Zero();
};

/// What an update did.
enum class TrackUpdate {
  kStarted,    ///< the first measurement (or the first after the track was lost) started it
  kUpdated,    ///< the measurement was fused
  kOutlier,    ///< gated out (too far from the prediction)
  kRestarted,  ///< too many outliers in a row: restarted from this measurement
  kTooOld,     ///< older than the track's last update by more than a frame or two: ignored
};

/// The filter of one car. Plain value: copyable and movable; not thread-safe.
class VehicleTrack {
 public:
  VehicleTrack(const VehicleTagConfig& vehicle, const TrackingConfig& config);

  /// Fuses the roof tag's pose measured at `stamp` (predicting the state to it first). A
  /// measurement up to 0.2 s older than the last is fused against the state predicted back to
  /// its time (cameras' frames can arrive out of order); older ones are ignored.
  TrackUpdate Update(Time stamp, const PlanarTagPose& tag);

  /// Whether the track has a state and was updated within `lost_after_s` of `now`.
  [[nodiscard]] bool active(Time now) const;
  /// Whether it has a state at all.
  [[nodiscard]] bool started() const { return started_; }
  /// The state predicted to `stamp` (the last state when `stamp` is its time).
  /// Precondition: `started()`.
  [[nodiscard]] VehicleEstimate Predict(Time stamp) const;
  /// The state at the last update. Precondition: `started()`.
  [[nodiscard]] VehicleEstimate Last() const { return Predict(stamp_); }
  [[nodiscard]] Time last_update() const { return stamp_; }
  /// Ends the track (lost): the next measurement starts it again.
  void Stop() { started_ = false; }
  [[nodiscard]] const VehicleTagConfig& vehicle() const { return vehicle_; }
  [[nodiscard]] long long outliers() const { return outliers_total_; }

 private:
  using State = Eigen::Matrix<double, 5, 1>;
  using Cov = Eigen::Matrix<double, 5, 5>;
  void PredictInPlace(double dt_s, State& x, Cov& P) const;
  void Start(Time stamp, const PlanarTagPose& tag);

  VehicleTagConfig vehicle_;
  TrackingConfig config_;
  bool started_ = false;
  Time stamp_{};
  State x_ = State::Zero();
  Cov P_ = Cov::Zero();
  int outliers_in_a_row_ = 0;
  long long outliers_total_ = 0;
};

}  // namespace autodrive::eye
