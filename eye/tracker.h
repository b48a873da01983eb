#pragma once
/// @file
/// A filter per car: an extended Kalman filter on the constant-turn-rate-and-velocity model of
/// the car's origin (the middle of its rear axle, where a car's velocity lies along its
/// heading), updated with its roof tag's planar pose (turned and placed on the car as its
/// mounting says), with outlier gating and prediction through missed frames.

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
  kHeld,       ///< not started (or restarted): the caller did not allow it for now
};

/// The filter of one car. Plain value: copyable and movable; not thread-safe.
class VehicleTrack {
 public:
  VehicleTrack(const VehicleTagConfig& vehicle, const TrackingConfig& config);

  /// Fuses the roof tag's pose measured at `stamp` (predicting the state to it first). A
  /// measurement up to 0.2 s older than the last is fused against the state predicted back to
  /// its time (cameras' frames can arrive out of order); older ones are ignored. With
  /// `may_restart` false a track that has not started is not started by it, and outliers do
  /// not restart the track (`kHeld`, `kOutlier`): the car's id is in doubt (another tag with
  /// it was seen), and only a measurement that agrees with the track may move it.
  TrackUpdate Update(Time stamp, const PlanarTagPose& tag, bool may_restart = true);

  /// Keep what each `Update` changes so that `UndoLastUpdate` can take it back (off by
  /// default: a copy of the state per update; the localiser turns it on with two or more
  /// cameras, whose frames of one instant come one after the other).
  void set_undoable(bool on) { remember_ = on; }
  /// Takes back the last `Update` (the state, stamp and outlier counts as they were before it),
  /// once; nothing when `set_undoable` is off or nothing was updated since the last undo.
  void UndoLastUpdate();

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
  /// The car's heading (rad, in (−π, π]) that its tag's yaw in the map (from M's x to T's x)
  /// gives with the configured mounting.
  [[nodiscard]] double VehicleYawOfTag(double tag_yaw_rad) const;

 private:
  using State = Eigen::Matrix<double, 5, 1>;
  using Cov = Eigen::Matrix<double, 5, 5>;
  void PredictInPlace(double dt_s, State& x, Cov& P) const;
  void Start(Time stamp, const PlanarTagPose& tag);
  void Remember();

  VehicleTagConfig vehicle_;
  TrackingConfig config_;
  Eigen::Vector2d p_VT_;  // the tag's centre in V, from the mounting
  double yaw_VT_rad_;     // T's yaw in V
  bool started_ = false;
  Time stamp_{};
  State x_ = State::Zero();
  Cov P_ = Cov::Zero();
  int outliers_in_a_row_ = 0;
  long long outliers_total_ = 0;
  // What the last Update changed, when remember_ is on.
  struct Saved {
    bool started = false;
    Time stamp{};
    State x = State::Zero();
    Cov P = Cov::Zero();
    int outliers_in_a_row = 0;
    long long outliers_total = 0;
  };
  bool remember_ = false;
  bool can_undo_ = false;
  Saved before_;
};

}  // namespace autodrive::eye
