#include "common/geometry.h"

#include <cmath>
#include <ostream>
#include <sstream>
#include <string>
#include <string_view>

#include "common/eigen_text.h"
#include "common/error.h"

namespace autodrive {
namespace {

// Shortest quaternion accepted as a rotation: anything shorter is garbage, not a rotation
// someone meant (and its direction is dominated by rounding).
constexpr double kMinQuaternionNorm = 1e-6;
// Composition renormalises the rotation only when it has drifted this far from unit length,
// so that composing with the identity is bit-exact.
constexpr double kRenormaliseAbove = 1e-12;
// The unit-length invariant of the stored rotation (broken only by a bug).
constexpr double kUnitInvariantTolerance = 1e-9;

const Eigen::IOFormat kMatrixFormat(Eigen::StreamPrecision, Eigen::DontAlignCols, ", ", "; ", "",
                                    "", "[", "]");

std::string QuaternionText(const Eigen::Quaterniond& q) {
  std::ostringstream os;
  os << "(w=" << q.w() << ", x=" << q.x() << ", y=" << q.y() << ", z=" << q.z() << ")";
  return os.str();
}

// The unit quaternion along `q`, or InputError naming `where` and the value seen.
Eigen::Quaterniond NormalisedOrThrow(const Eigen::Quaterniond& q, std::string_view where) {
  AUTODRIVE_THROW_UNLESS(q.coeffs().allFinite(),
                         where << ": quaternion must be finite, got " << QuaternionText(q));
  const double norm = q.coeffs().stableNorm();
  AUTODRIVE_THROW_UNLESS(norm >= kMinQuaternionNorm,
                         where << ": quaternion must have norm >= " << kMinQuaternionNorm
                               << " to be a rotation, got " << QuaternionText(q) << " of norm "
                               << norm);
  return Eigen::Quaterniond(Eigen::Vector4d(q.coeffs() / norm));
}

// Half-angle sums of the roll-pitch-yaw decomposition of a unit quaternion, after Mitiguy's
// algorithm as used in Drake's RollPitchYaw: for q = Rz(yaw) Ry(pitch) Rx(roll),
// atan2(x + z, w - y) = (roll + yaw) / 2 and atan2(z - x, w + y) = (yaw - roll) / 2. Each is
// undefined (0/0) at one gimbal lock, where only the other sum matters; setting it to 0 then
// still reproduces the rotation.
struct HalfAngleSums {
  double sum_half_rad;   // (roll + yaw) / 2
  double diff_half_rad;  // (yaw - roll) / 2
};

HalfAngleSums HalfAngleSumsOfUnit(const Eigen::Quaterniond& q) {
  constexpr double kEpsilon = Eigen::NumTraits<double>::epsilon();
  const double y_a = q.x() + q.z();
  const double x_a = q.w() - q.y();
  const double y_b = q.z() - q.x();
  const double x_b = q.w() + q.y();
  const bool singular_a = std::abs(y_a) <= kEpsilon && std::abs(x_a) <= kEpsilon;
  const bool singular_b = std::abs(y_b) <= kEpsilon && std::abs(x_b) <= kEpsilon;
  return {singular_a ? 0.0 : std::atan2(y_a, x_a), singular_b ? 0.0 : std::atan2(y_b, x_b)};
}

double YawOfUnit(const Eigen::Quaterniond& q) {
  const HalfAngleSums h = HalfAngleSumsOfUnit(q);
  return WrapAngle(h.sum_half_rad + h.diff_half_rad) + 0.0;  // +0.0: no -0.0.
}

RollPitchYaw RollPitchYawOfUnit(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d R = q.toRotationMatrix();
  // |cos(pitch)| from four elements, which is better conditioned than asin(-R(2,0)).
  const double cos_pitch = std::sqrt(
      (R(2, 2) * R(2, 2) + R(2, 1) * R(2, 1) + R(1, 0) * R(1, 0) + R(0, 0) * R(0, 0)) / 2.0);
  const HalfAngleSums h = HalfAngleSumsOfUnit(q);
  // Adding +0.0 turns -0.0 into +0.0, which prints better.
  return RollPitchYaw{.roll_rad = WrapAngle(h.sum_half_rad - h.diff_half_rad) + 0.0,
                      .pitch_rad = std::atan2(-R(2, 0), cos_pitch) + 0.0,
                      .yaw_rad = WrapAngle(h.sum_half_rad + h.diff_half_rad) + 0.0};
}

// Max |R^T R - I| of a square block.
template <typename Matrix>
double OrthonormalityError(const Matrix& R) {
  return (R.transpose() * R - Matrix::Identity()).cwiseAbs().maxCoeff();
}

}  // namespace

double WrapAngle(double angle_rad) {
  AUTODRIVE_THROW_UNLESS(std::isfinite(angle_rad),
                         "WrapAngle: angle must be finite, got " << angle_rad);
  // std::remainder is exact and returns a value in [-pi, pi]; move -pi to +pi.
  double wrapped = std::remainder(angle_rad, 2.0 * kPi);
  if (wrapped <= -kPi) {
    wrapped += 2.0 * kPi;
  }
  return wrapped;
}

Eigen::Quaterniond QuaternionFromRollPitchYaw(const RollPitchYaw& rpy) {
  AUTODRIVE_THROW_UNLESS(
      std::isfinite(rpy.roll_rad) && std::isfinite(rpy.pitch_rad) && std::isfinite(rpy.yaw_rad),
      "QuaternionFromRollPitchYaw: angles must be finite, got roll="
          << rpy.roll_rad << ", pitch=" << rpy.pitch_rad << ", yaw=" << rpy.yaw_rad);
  const Eigen::Quaterniond q = Eigen::AngleAxisd(rpy.yaw_rad, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(rpy.pitch_rad, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(rpy.roll_rad, Eigen::Vector3d::UnitX());
  return q.normalized();
}

RollPitchYaw RollPitchYawFromQuaternion(const Eigen::Quaterniond& q) {
  return RollPitchYawOfUnit(NormalisedOrThrow(q, "RollPitchYawFromQuaternion"));
}

double YawFromQuaternion(const Eigen::Quaterniond& q) {
  return YawOfUnit(NormalisedOrThrow(q, "YawFromQuaternion"));
}

// ---------------------------------------------------------------------------------------------
// RigidTransform2

RigidTransform2::RigidTransform2(const Eigen::Vector2d& translation_m, double yaw_rad)
    : translation_m_(translation_m) {
  AUTODRIVE_THROW_UNLESS(
      translation_m.allFinite(),
      "RigidTransform2: translation must be finite, got " << VectorText(translation_m));
  AUTODRIVE_THROW_UNLESS(std::isfinite(yaw_rad),
                         "RigidTransform2: yaw must be finite, got " << yaw_rad);
  cos_ = std::cos(yaw_rad);
  sin_ = std::sin(yaw_rad);
  CheckInvariants();
}

RigidTransform2::RigidTransform2(const Eigen::Vector2d& translation_m,
                                 const Eigen::Rotation2Dd& rotation)
    : RigidTransform2(translation_m, rotation.angle()) {}

RigidTransform2::RigidTransform2(Unchecked, const Eigen::Vector2d& translation_m, double cos,
                                 double sin)
    : translation_m_(translation_m), cos_(cos), sin_(sin) {
  CheckInvariants();
}

RigidTransform2 RigidTransform2::FromXyYaw(double x_m, double y_m, double yaw_rad) {
  return RigidTransform2(Eigen::Vector2d(x_m, y_m), yaw_rad);
}

RigidTransform2 RigidTransform2::FromHomogeneous(const Eigen::Matrix3d& X, double tolerance) {
  AUTODRIVE_CHECK(tolerance >= 0.0, "tolerance=" << tolerance);
  AUTODRIVE_THROW_UNLESS(
      X.allFinite(),
      "RigidTransform2::FromHomogeneous: matrix must be finite, got " << X.format(kMatrixFormat));
  const Eigen::Matrix2d R = X.topLeftCorner<2, 2>();
  const double orthonormality_error = OrthonormalityError(R);
  const double determinant = R.determinant();
  const double last_row_error = (X.row(2) - Eigen::RowVector3d(0, 0, 1)).cwiseAbs().maxCoeff();
  AUTODRIVE_THROW_UNLESS(orthonormality_error <= tolerance &&
                             std::abs(determinant - 1.0) <= tolerance &&
                             last_row_error <= tolerance,
                         "RigidTransform2::FromHomogeneous: not a rigid transform to within "
                             << tolerance << " (max |R^T R - I| = " << orthonormality_error
                             << ", det R = " << determinant << ", last row " << VectorText(X.row(2))
                             << "), got " << X.format(kMatrixFormat));
  // The angle of the rotation nearest to R (in the Frobenius norm).
  const double yaw_rad = std::atan2(R(1, 0) - R(0, 1), R(0, 0) + R(1, 1));
  return RigidTransform2(X.topRightCorner<2, 1>(), yaw_rad);
}

Eigen::Matrix3d RigidTransform2::ToHomogeneous() const {
  Eigen::Matrix3d X;
  X << cos_, -sin_, translation_m_.x(),  //
      sin_, cos_, translation_m_.y(),    //
      0.0, 0.0, 1.0;
  return X;
}

double RigidTransform2::yaw() const {
  // atan2 returns -pi for (sin, cos) = (-0.0, -1), which composition can produce.
  const double yaw_rad = std::atan2(sin_, cos_);
  return yaw_rad <= -kPi ? kPi : yaw_rad + 0.0;  // +0.0: no -0.0.
}

Eigen::Matrix2d RigidTransform2::rotation_matrix() const {
  Eigen::Matrix2d R;
  R << cos_, -sin_,  //
      sin_, cos_;
  return R;
}

RigidTransform2 RigidTransform2::inverse() const {
  // X_BA = [R^T, -R^T p].
  const Eigen::Vector2d p_BA(-(cos_ * translation_m_.x() + sin_ * translation_m_.y()),
                             -(-sin_ * translation_m_.x() + cos_ * translation_m_.y()));
  return RigidTransform2(Unchecked{}, p_BA, cos_, -sin_);
}

RigidTransform2 RigidTransform2::operator*(const RigidTransform2& X_BC) const {
  double cos = cos_ * X_BC.cos_ - sin_ * X_BC.sin_;
  double sin = sin_ * X_BC.cos_ + cos_ * X_BC.sin_;
  const double norm_squared = cos * cos + sin * sin;
  if (std::abs(norm_squared - 1.0) > kRenormaliseAbove) {
    const double norm = std::sqrt(norm_squared);
    cos /= norm;
    sin /= norm;
  }
  return RigidTransform2(Unchecked{}, (*this) * X_BC.translation_m_, cos, sin);
}

Eigen::Vector2d RigidTransform2::operator*(const Eigen::Vector2d& p_BQ) const {
  return Eigen::Vector2d(cos_ * p_BQ.x() - sin_ * p_BQ.y() + translation_m_.x(),
                         sin_ * p_BQ.x() + cos_ * p_BQ.y() + translation_m_.y());
}

bool RigidTransform2::IsNearlyEqualTo(const RigidTransform2& other, double tolerance) const {
  const double rotation_error = (rotation_matrix() - other.rotation_matrix()).cwiseAbs().maxCoeff();
  const double translation_error = (translation_m_ - other.translation_m_).cwiseAbs().maxCoeff();
  return rotation_error <= tolerance && translation_error <= tolerance;
}

RigidTransform3 RigidTransform2::ToRigidTransform3(double z_m) const {
  AUTODRIVE_THROW_UNLESS(std::isfinite(z_m),
                         "RigidTransform2::ToRigidTransform3: z must be finite, got " << z_m);
  return RigidTransform3(Eigen::Vector3d(translation_m_.x(), translation_m_.y(), z_m),
                         Eigen::Quaterniond(Eigen::AngleAxisd(yaw(), Eigen::Vector3d::UnitZ())));
}

void RigidTransform2::CheckInvariants() const {
  AUTODRIVE_CHECK(
      translation_m_.allFinite() && std::isfinite(cos_) && std::isfinite(sin_) &&
          std::abs(cos_ * cos_ + sin_ * sin_ - 1.0) <= kUnitInvariantTolerance,
      "translation=" << VectorText(translation_m_) << " cos=" << cos_ << " sin=" << sin_);
}

std::ostream& operator<<(std::ostream& os, const RigidTransform2& X) {
  return os << "RigidTransform2(x=" << X.translation().x() << ", y=" << X.translation().y()
            << ", yaw=" << X.yaw() << ")";
}

// ---------------------------------------------------------------------------------------------
// RigidTransform3

RigidTransform3::RigidTransform3(const Eigen::Vector3d& translation_m,
                                 const Eigen::Quaterniond& rotation)
    : translation_m_(translation_m) {
  AUTODRIVE_THROW_UNLESS(
      translation_m.allFinite(),
      "RigidTransform3: translation must be finite, got " << VectorText(translation_m));
  rotation_ = NormalisedOrThrow(rotation, "RigidTransform3");
  CheckInvariants();
}

RigidTransform3::RigidTransform3(const Eigen::Vector3d& translation_m, const RollPitchYaw& rpy)
    : RigidTransform3(translation_m, QuaternionFromRollPitchYaw(rpy)) {}

RigidTransform3::RigidTransform3(Unchecked, const Eigen::Vector3d& translation_m,
                                 const Eigen::Quaterniond& rotation)
    : translation_m_(translation_m), rotation_(rotation) {
  CheckInvariants();
}

RigidTransform3 RigidTransform3::FromHomogeneous(const Eigen::Matrix4d& X, double tolerance) {
  AUTODRIVE_CHECK(tolerance >= 0.0, "tolerance=" << tolerance);
  AUTODRIVE_THROW_UNLESS(
      X.allFinite(),
      "RigidTransform3::FromHomogeneous: matrix must be finite, got " << X.format(kMatrixFormat));
  const Eigen::Matrix3d R = X.topLeftCorner<3, 3>();
  const double orthonormality_error = OrthonormalityError(R);
  const double determinant = R.determinant();
  const double last_row_error = (X.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff();
  AUTODRIVE_THROW_UNLESS(orthonormality_error <= tolerance &&
                             std::abs(determinant - 1.0) <= tolerance &&
                             last_row_error <= tolerance,
                         "RigidTransform3::FromHomogeneous: not a rigid transform to within "
                             << tolerance << " (max |R^T R - I| = " << orthonormality_error
                             << ", det R = " << determinant << ", last row " << VectorText(X.row(3))
                             << "), got " << X.format(kMatrixFormat));
  return RigidTransform3(X.topRightCorner<3, 1>(), Eigen::Quaterniond(R));
}

Eigen::Matrix4d RigidTransform3::ToHomogeneous() const {
  Eigen::Matrix4d X = Eigen::Matrix4d::Identity();
  X.topLeftCorner<3, 3>() = rotation_matrix();
  X.topRightCorner<3, 1>() = translation_m_;
  return X;
}

double RigidTransform3::yaw() const { return YawOfUnit(rotation_); }

RollPitchYaw RigidTransform3::roll_pitch_yaw() const { return RollPitchYawOfUnit(rotation_); }

RigidTransform3 RigidTransform3::inverse() const {
  const Eigen::Quaterniond q_BA = rotation_.conjugate();
  return RigidTransform3(Unchecked{}, -(q_BA * translation_m_), q_BA);
}

RigidTransform3 RigidTransform3::operator*(const RigidTransform3& X_BC) const {
  Eigen::Quaterniond q_AC = rotation_ * X_BC.rotation_;
  if (std::abs(q_AC.squaredNorm() - 1.0) > kRenormaliseAbove) {
    q_AC.normalize();
  }
  return RigidTransform3(Unchecked{}, (*this) * X_BC.translation_m_, q_AC);
}

Eigen::Vector3d RigidTransform3::operator*(const Eigen::Vector3d& p_BQ) const {
  return rotation_ * p_BQ + translation_m_;
}

bool RigidTransform3::IsNearlyEqualTo(const RigidTransform3& other, double tolerance) const {
  const double rotation_error = (rotation_matrix() - other.rotation_matrix()).cwiseAbs().maxCoeff();
  const double translation_error = (translation_m_ - other.translation_m_).cwiseAbs().maxCoeff();
  return rotation_error <= tolerance && translation_error <= tolerance;
}

RigidTransform2 RigidTransform3::ToRigidTransform2() const {
  return RigidTransform2(translation_m_.head<2>(), yaw());
}

void RigidTransform3::CheckInvariants() const {
  AUTODRIVE_CHECK(
      translation_m_.allFinite() && rotation_.coeffs().allFinite() &&
          std::abs(rotation_.squaredNorm() - 1.0) <= kUnitInvariantTolerance,
      "translation=" << VectorText(translation_m_) << " rotation=" << QuaternionText(rotation_));
}

std::ostream& operator<<(std::ostream& os, const RigidTransform3& X) {
  const RollPitchYaw rpy = X.roll_pitch_yaw();
  return os << "RigidTransform3(xyz=" << VectorText(X.translation()) << ", rpy=(" << rpy.roll_rad
            << ", " << rpy.pitch_rad << ", " << rpy.yaw_rad << "))";
}

}  // namespace autodrive
