#pragma once
/// @file
/// Rigid transforms in the plane (SE(2)) and in space (SE(3)), on Eigen, in Drake's monogram
/// notation: `X_AB` is the pose of frame B measured and expressed in frame A, `p_AQ` is the
/// position of point Q in frame A, so frames cancel when they are written next to each other:
///
///     const RigidTransform3 X_WT = X_WC * X_CT;  // tag T in world W, via camera C
///     const Eigen::Vector3d p_WQ = X_WT * p_TQ;  // a point Q of the tag, in the world
///     const RigidTransform3 X_CW = X_WC.inverse();
///
/// Units: translations in metres, angles in radians. Frames are right-handed and Z is up (ROS
/// REP 103; a car's body frame is X forward, Y left, Z up), so yaw, a rotation about +Z, is
/// counter-clockwise seen from above.
///
/// Roll-pitch-yaw angles follow ROS's convention (tf2 `setRPY`, URDF `rpy`): the rotation is
/// `R = Rz(yaw) * Ry(pitch) * Rx(roll)`, which is extrinsic X-Y-Z (roll about the fixed X, then
/// pitch about the fixed Y, then yaw about the fixed Z) or, equivalently, intrinsic Z-Y'-X''.

#include <iosfwd>
#include <numbers>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace autodrive {

class RigidTransform3;

/// pi, the double nearest to it (`std::numbers::pi`).
inline constexpr double kPi = std::numbers::pi;

/// Wraps an angle to the half-open interval (-pi, pi], in radians: the result differs from
/// `angle_rad` by an integer multiple of 2*kPi (computed exactly with `std::remainder`), and
/// odd multiples of kPi (kPi, -kPi, 3*kPi, -3*kPi, ...) all map to +kPi.
/// @throws InputError if `angle_rad` is not finite.
[[nodiscard]] double WrapAngle(double angle_rad);

/// Roll, pitch and yaw angles in radians, in ROS's convention (see the file comment):
/// `R = Rz(yaw_rad) * Ry(pitch_rad) * Rx(roll_rad)`.
struct RollPitchYaw {
  double roll_rad = 0.0;   ///< Rotation about X, applied first (extrinsic).
  double pitch_rad = 0.0;  ///< Rotation about Y, applied second (extrinsic).
  double yaw_rad = 0.0;    ///< Rotation about Z, applied last (extrinsic).
};

/// The unit quaternion of `R = Rz(yaw) * Ry(pitch) * Rx(roll)` (ROS's `setRPY`). Any finite
/// angles are accepted; they need not be wrapped.
/// @throws InputError if an angle is not finite.
[[nodiscard]] Eigen::Quaterniond QuaternionFromRollPitchYaw(const RollPitchYaw& rpy);

/// The roll-pitch-yaw angles of a rotation, with roll and yaw in (-pi, pi] and pitch in
/// [-pi/2, pi/2]. `q` need not be unit length (it is normalised first); q and -q give the same
/// angles. At gimbal lock (pitch = +-pi/2) only yaw - roll (pitch = +pi/2) or yaw + roll
/// (pitch = -pi/2) is defined; the returned angles still reproduce the rotation. The algorithm
/// (Mitiguy's, as in Drake's `RollPitchYaw`) stays accurate near gimbal lock.
/// @throws InputError if `q` has a non-finite coefficient or a norm below 1e-6.
[[nodiscard]] RollPitchYaw RollPitchYawFromQuaternion(const Eigen::Quaterniond& q);

/// The heading of a rotation about the world Z axis, in (-pi, pi]: the yaw of its roll-pitch-yaw
/// decomposition, i.e. the direction of the rotated X axis projected onto the XY plane,
/// `atan2(R(1,0), R(0,0))`. Roll and pitch do not change it. Ill-conditioned when the rotated X
/// axis is (nearly) vertical (pitch near +-pi/2), where it follows the gimbal-lock rule of
/// `RollPitchYawFromQuaternion`. `q` need not be unit length.
/// @throws InputError if `q` has a non-finite coefficient or a norm below 1e-6.
[[nodiscard]] double YawFromQuaternion(const Eigen::Quaterniond& q);

/// A rigid transform in the plane, SE(2): the pose `X_AB` of a frame B in a frame A, as the
/// translation `p_AB` (metres) of B's origin in A and the rotation angle of B's axes relative
/// to A's (radians, counter-clockwise). Transforms compose like their names read:
/// `X_WT = X_WC * X_CT`, and `X_WC * p_CQ` is the point Q in W.
///
/// The rotation is stored as its cosine and sine, so composition and point transforms need no
/// trigonometry; composition renormalises them so that long chains do not drift. Copyable and
/// movable; a plain value.
class RigidTransform2 {
 public:
  /// The identity transform.
  RigidTransform2() = default;

  /// The transform with translation `translation_m` (metres) and rotation angle `yaw_rad`
  /// (radians; any finite value, it need not be wrapped).
  /// @throws InputError if a coefficient or the angle is not finite.
  RigidTransform2(const Eigen::Vector2d& translation_m, double yaw_rad);

  /// The transform with translation `translation_m` (metres) and rotation `rotation`.
  /// @throws InputError if a coefficient or the angle is not finite.
  RigidTransform2(const Eigen::Vector2d& translation_m, const Eigen::Rotation2Dd& rotation);

  /// The transform `(x_m, y_m, yaw_rad)`, the usual planar pose.
  /// @throws InputError if a value is not finite.
  [[nodiscard]] static RigidTransform2 FromXyYaw(double x_m, double y_m, double yaw_rad);

  /// The identity transform.
  [[nodiscard]] static RigidTransform2 Identity() { return RigidTransform2(); }

  /// The transform of a 3x3 homogeneous matrix `[R p; 0 0 1]`. R must be a rotation (R^T R = I,
  /// det R = +1) and the last row (0, 0, 1), each to within `tolerance` per element; the stored
  /// rotation is the rotation nearest to R.
  /// @throws InputError naming the matrix if it is not finite or not such a matrix.
  [[nodiscard]] static RigidTransform2 FromHomogeneous(const Eigen::Matrix3d& X,
                                                       double tolerance = 1e-6);

  /// The 3x3 homogeneous matrix `[R p; 0 0 1]`.
  [[nodiscard]] Eigen::Matrix3d ToHomogeneous() const;

  /// The translation `p_AB` of B's origin in A, metres.
  [[nodiscard]] const Eigen::Vector2d& translation() const { return translation_m_; }
  /// The rotation angle of B relative to A, radians, in (-pi, pi].
  [[nodiscard]] double yaw() const;
  /// cos(yaw), exact as stored.
  [[nodiscard]] double cos_yaw() const { return cos_; }
  /// sin(yaw), exact as stored.
  [[nodiscard]] double sin_yaw() const { return sin_; }
  /// The rotation as an Eigen rotation (angle `yaw()`).
  [[nodiscard]] Eigen::Rotation2Dd rotation() const { return Eigen::Rotation2Dd(yaw()); }
  /// The 2x2 rotation matrix `R_AB`.
  [[nodiscard]] Eigen::Matrix2d rotation_matrix() const;

  /// The inverse transform: `X_AB.inverse()` is `X_BA`.
  [[nodiscard]] RigidTransform2 inverse() const;

  /// Composition: `X_AB * X_BC` is `X_AC`.
  [[nodiscard]] RigidTransform2 operator*(const RigidTransform2& X_BC) const;

  /// Transforms a point: `X_AB * p_BQ` is `p_AQ`, metres.
  [[nodiscard]] Eigen::Vector2d operator*(const Eigen::Vector2d& p_BQ) const;

  /// True if every element of `[R p]` (2x3) of this and `other` differs by at most `tolerance`
  /// (metres for the translation, dimensionless for the rotation elements).
  [[nodiscard]] bool IsNearlyEqualTo(const RigidTransform2& other, double tolerance) const;

  /// This transform lifted into 3D: the same translation at height `z_m` (metres) and the same
  /// angle as a rotation about Z. `X.ToRigidTransform3(z).ToRigidTransform2()` equals X.
  /// @throws InputError if `z_m` is not finite.
  [[nodiscard]] RigidTransform3 ToRigidTransform3(double z_m = 0.0) const;

 private:
  // Unchecked: the caller guarantees finite values and cos^2 + sin^2 = 1 to rounding.
  struct Unchecked {};
  RigidTransform2(Unchecked, const Eigen::Vector2d& translation_m, double cos, double sin);
  void CheckInvariants() const;

  Eigen::Vector2d translation_m_{Eigen::Vector2d::Zero()};
  double cos_{1.0};
  double sin_{0.0};
};

/// Prints `RigidTransform2(x=1, y=2, yaw=0.5)` (metres, radians), for logs and test failures.
std::ostream& operator<<(std::ostream& os, const RigidTransform2& X);

/// A rigid transform in space, SE(3): the pose `X_AB` of a frame B in a frame A, as the
/// translation `p_AB` (metres) of B's origin in A and the rotation `R_AB` of B's axes relative to
/// A's, stored as a unit quaternion. Transforms compose like their names read:
/// `X_WT = X_WC * X_CT` (a tag T seen by camera C, in the world W), and `X_WC * p_CQ` is the
/// point Q in W.
///
/// The quaternion is kept at unit length (an invariant, checked); composition renormalises it
/// so long chains do not drift. Copyable and movable; a plain value.
class RigidTransform3 {
 public:
  /// The identity transform.
  RigidTransform3() = default;

  /// The transform with translation `translation_m` (metres) and rotation `rotation`. The
  /// quaternion need not be unit length: it is normalised (as in Drake).
  /// @throws InputError if a coefficient is not finite or the quaternion's norm is below 1e-6.
  RigidTransform3(const Eigen::Vector3d& translation_m, const Eigen::Quaterniond& rotation);

  /// The transform with translation `translation_m` and rotation from roll-pitch-yaw angles.
  /// @throws InputError if a value is not finite.
  RigidTransform3(const Eigen::Vector3d& translation_m, const RollPitchYaw& rpy);

  /// The identity transform.
  [[nodiscard]] static RigidTransform3 Identity() { return RigidTransform3(); }

  /// The transform of a 4x4 homogeneous matrix `[R p; 0 0 0 1]`. R must be a rotation
  /// (R^T R = I, det R = +1) and the last row (0, 0, 0, 1), each to within `tolerance` per
  /// element.
  /// @throws InputError naming the matrix if it is not finite or not such a matrix.
  [[nodiscard]] static RigidTransform3 FromHomogeneous(const Eigen::Matrix4d& X,
                                                       double tolerance = 1e-6);

  /// The 4x4 homogeneous matrix `[R p; 0 0 0 1]`.
  [[nodiscard]] Eigen::Matrix4d ToHomogeneous() const;

  /// The translation `p_AB` of B's origin in A, metres.
  [[nodiscard]] const Eigen::Vector3d& translation() const { return translation_m_; }
  /// The rotation `R_AB` as a unit quaternion (w >= 0 is not guaranteed: q and -q are the same
  /// rotation).
  [[nodiscard]] const Eigen::Quaterniond& rotation() const { return rotation_; }
  /// The 3x3 rotation matrix `R_AB`.
  [[nodiscard]] Eigen::Matrix3d rotation_matrix() const { return rotation_.toRotationMatrix(); }
  /// The heading about A's Z axis, radians in (-pi, pi]; see `YawFromQuaternion`.
  [[nodiscard]] double yaw() const;
  /// The roll-pitch-yaw angles of the rotation; see `RollPitchYawFromQuaternion`.
  [[nodiscard]] RollPitchYaw roll_pitch_yaw() const;

  /// The inverse transform: `X_AB.inverse()` is `X_BA`.
  [[nodiscard]] RigidTransform3 inverse() const;

  /// Composition: `X_AB * X_BC` is `X_AC`.
  [[nodiscard]] RigidTransform3 operator*(const RigidTransform3& X_BC) const;

  /// Transforms a point: `X_AB * p_BQ` is `p_AQ`, metres.
  [[nodiscard]] Eigen::Vector3d operator*(const Eigen::Vector3d& p_BQ) const;

  /// True if every element of `[R p]` (3x4) of this and `other` differs by at most `tolerance`
  /// (metres for the translation, dimensionless for the rotation elements). Comparing rotation
  /// matrices makes q and -q equal.
  [[nodiscard]] bool IsNearlyEqualTo(const RigidTransform3& other, double tolerance) const;

  /// The planar part of this transform: translation (x, y), dropping z, and the rotation about
  /// Z by `yaw()`, dropping roll and pitch. This is the pose of a car on the track from a full
  /// 3D pose. It is exact for transforms whose rotation is about Z only; with roll or pitch
  /// present, the projection of a composition is in general not the composition of the
  /// projections.
  [[nodiscard]] RigidTransform2 ToRigidTransform2() const;

 private:
  // Unchecked: the caller guarantees finite values and a quaternion of unit norm to rounding.
  struct Unchecked {};
  RigidTransform3(Unchecked, const Eigen::Vector3d& translation_m,
                  const Eigen::Quaterniond& rotation);
  void CheckInvariants() const;

  Eigen::Vector3d translation_m_{Eigen::Vector3d::Zero()};
  Eigen::Quaterniond rotation_{Eigen::Quaterniond::Identity()};
};

/// Prints `RigidTransform3(xyz=(1, 2, 3), rpy=(0, 0, 0.5))` (metres, radians), for logs and
/// test failures.
std::ostream& operator<<(std::ostream& os, const RigidTransform3& X);

}  // namespace autodrive
