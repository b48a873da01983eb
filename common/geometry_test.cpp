#include "common/geometry.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/test_support.h"

namespace autodrive {
namespace {

using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
// Tolerance for random cross-checks: translations up to ~30 m, a few roundings each.
constexpr double kRandomTolerance = 1e-10;

// Randomised cross-checks run kBaseCases cases, times AUTODRIVE_SOAK_FACTOR when it is set.
constexpr int kBaseCases = 1000;

int NumCases() { return kBaseCases * test::SoakFactor(); }

std::string InputErrorMessage(auto&& f) { return test::ErrorMessage(f); }

// --- Plain-matrix references, written out independently of the code under test. ---

Eigen::Matrix3d ReferenceHomogeneous2(double x, double y, double yaw) {
  Eigen::Matrix3d X;
  X << std::cos(yaw), -std::sin(yaw), x,  //
      std::sin(yaw), std::cos(yaw), y,    //
      0, 0, 1;
  return X;
}

Eigen::Matrix3d ReferenceRotation(double roll, double pitch, double yaw) {
  Eigen::Matrix3d Rx, Ry, Rz;
  Rx << 1, 0, 0,                           //
      0, std::cos(roll), -std::sin(roll),  //
      0, std::sin(roll), std::cos(roll);
  Ry << std::cos(pitch), 0, std::sin(pitch),  //
      0, 1, 0,                                //
      -std::sin(pitch), 0, std::cos(pitch);
  Rz << std::cos(yaw), -std::sin(yaw), 0,  //
      std::sin(yaw), std::cos(yaw), 0,     //
      0, 0, 1;
  return Rz * Ry * Rx;  // ROS: extrinsic X-Y-Z.
}

Eigen::Matrix4d ReferenceHomogeneous3(const Eigen::Vector3d& p, const RollPitchYaw& rpy) {
  Eigen::Matrix4d X = Eigen::Matrix4d::Identity();
  X.topLeftCorner<3, 3>() = ReferenceRotation(rpy.roll_rad, rpy.pitch_rad, rpy.yaw_rad);
  X.topRightCorner<3, 1>() = p;
  return X;
}

double MaxAbsDiff(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).cwiseAbs().maxCoeff();
}

// Random poses: translations within 10 m, angles well beyond (-pi, pi] so that unwrapped input
// is exercised; pitch kept away from +-pi/2 where yaw is ill-conditioned.
struct RandomPoses {
  explicit RandomPoses(unsigned seed) : gen(seed) {}
  double Translation() { return std::uniform_real_distribution<double>(-10.0, 10.0)(gen); }
  double Angle() { return std::uniform_real_distribution<double>(-4 * kPi, 4 * kPi)(gen); }
  double Pitch() { return std::uniform_real_distribution<double>(-1.5, 1.5)(gen); }
  Eigen::Vector2d Point2() { return {Translation(), Translation()}; }
  Eigen::Vector3d Point3() { return {Translation(), Translation(), Translation()}; }
  RollPitchYaw Rpy() { return {.roll_rad = Angle(), .pitch_rad = Pitch(), .yaw_rad = Angle()}; }
  std::mt19937 gen;
};

// ---------------------------------------------------------------------------------------------
// Angles

TEST(WrapAngle, MapsOddMultiplesOfPiToPlusPi) {
  EXPECT_EQ(WrapAngle(kPi), kPi);
  EXPECT_EQ(WrapAngle(-kPi), kPi);
  EXPECT_EQ(WrapAngle(3 * kPi), kPi);
  EXPECT_EQ(WrapAngle(-3 * kPi), kPi);
  EXPECT_EQ(WrapAngle(5 * kPi), kPi);
}

TEST(WrapAngle, KeepsAnglesInsideTheIntervalAndJustBelowTheCut) {
  EXPECT_EQ(WrapAngle(0.0), 0.0);
  EXPECT_EQ(WrapAngle(1.0), 1.0);
  EXPECT_EQ(WrapAngle(-1.0), -1.0);
  const double just_above_minus_pi = std::nextafter(-kPi, 0.0);
  EXPECT_EQ(WrapAngle(just_above_minus_pi), just_above_minus_pi);
  const double just_below_pi = std::nextafter(kPi, 0.0);
  EXPECT_EQ(WrapAngle(just_below_pi), just_below_pi);
}

TEST(WrapAngle, SubtractsWholeTurns) {
  EXPECT_NEAR(WrapAngle(2 * kPi + 0.25), 0.25, 1e-15);
  EXPECT_NEAR(WrapAngle(-2 * kPi - 0.25), -0.25, 1e-15);
  EXPECT_NEAR(WrapAngle(7 * kPi / 2), -kPi / 2, 1e-14);
  EXPECT_NEAR(WrapAngle(100.0), 100.0 - 32 * kPi, 1e-13);
}

TEST(WrapAngle, RandomAnglesLandInTheHalfOpenIntervalWithTheSameDirection) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<double> angle(-1000.0, 1000.0);
  for (int i = 0; i < NumCases(); ++i) {
    const double a = angle(gen);
    const double w = WrapAngle(a);
    ASSERT_GT(w, -kPi) << a;
    ASSERT_LE(w, kPi) << a;
    ASSERT_NEAR(std::cos(w), std::cos(a), 1e-12) << a;
    ASSERT_NEAR(std::sin(w), std::sin(a), 1e-12) << a;
  }
}

TEST(WrapAngle, RejectsNonFiniteAnglesNamingTheValue) {
  EXPECT_EQ(InputErrorMessage([] { (void)WrapAngle(kNaN); }),
            "WrapAngle: angle must be finite, got nan");
  EXPECT_EQ(InputErrorMessage([] { (void)WrapAngle(-kInf); }),
            "WrapAngle: angle must be finite, got -inf");
}

// ---------------------------------------------------------------------------------------------
// Roll-pitch-yaw and quaternions

TEST(RollPitchYaw, FollowsRosExtrinsicXyzConvention) {
  // Roll then yaw, both 90 degrees, about the fixed axes: x -> x -> y, y -> z -> z.
  // The other order (yaw first) would send x to z.
  const Eigen::Quaterniond q =
      QuaternionFromRollPitchYaw({.roll_rad = kPi / 2, .pitch_rad = 0, .yaw_rad = kPi / 2});
  EXPECT_LT(MaxAbsDiff(q * Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY()), 1e-15);
  EXPECT_LT(MaxAbsDiff(q * Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()), 1e-15);
  // Pitch of +90 degrees tips the nose (x) down to -z.
  const Eigen::Quaterniond pitch = QuaternionFromRollPitchYaw({.pitch_rad = kPi / 2});
  EXPECT_LT(MaxAbsDiff(pitch * Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitZ()), 1e-15);
}

TEST(RollPitchYaw, MatchesTheElementaryRotationMatrices) {
  RandomPoses random(11);
  for (int i = 0; i < NumCases(); ++i) {
    const RollPitchYaw rpy = random.Rpy();
    const Eigen::Quaterniond q = QuaternionFromRollPitchYaw(rpy);
    ASSERT_NEAR(q.norm(), 1.0, 1e-15);
    ASSERT_LT(MaxAbsDiff(q.toRotationMatrix(),
                         ReferenceRotation(rpy.roll_rad, rpy.pitch_rad, rpy.yaw_rad)),
              1e-14)
        << i;
  }
}

TEST(RollPitchYaw, RoundTripsThroughTheQuaternion) {
  std::mt19937 gen(12);
  std::uniform_real_distribution<double> angle(-kPi, kPi);
  std::uniform_real_distribution<double> pitch(-kPi / 2 + 1e-3, kPi / 2 - 1e-3);
  for (int i = 0; i < NumCases(); ++i) {
    const RollPitchYaw rpy{.roll_rad = angle(gen), .pitch_rad = pitch(gen), .yaw_rad = angle(gen)};
    const RollPitchYaw back = RollPitchYawFromQuaternion(QuaternionFromRollPitchYaw(rpy));
    ASSERT_NEAR(back.roll_rad, rpy.roll_rad, 1e-11) << i;
    ASSERT_NEAR(back.pitch_rad, rpy.pitch_rad, 1e-11) << i;
    ASSERT_NEAR(back.yaw_rad, rpy.yaw_rad, 1e-11) << i;
  }
}

TEST(RollPitchYaw, ReturnsWrappedAnglesForUnwrappedInput) {
  const RollPitchYaw back = RollPitchYawFromQuaternion(QuaternionFromRollPitchYaw(
      {.roll_rad = 0.5 + 2 * kPi, .pitch_rad = 0.25, .yaw_rad = -0.75 - 4 * kPi}));
  EXPECT_NEAR(back.roll_rad, 0.5, 1e-13);
  EXPECT_NEAR(back.pitch_rad, 0.25, 1e-13);
  EXPECT_NEAR(back.yaw_rad, -0.75, 1e-13);
}

TEST(RollPitchYaw, ReproducesTheRotationAtAndNearGimbalLock) {
  for (const double pitch : {kPi / 2, -kPi / 2, kPi / 2 - 1e-9, -kPi / 2 + 1e-9, kPi / 2 - 1e-13}) {
    for (const double roll : {0.0, 0.3, -2.0}) {
      const RollPitchYaw rpy{.roll_rad = roll, .pitch_rad = pitch, .yaw_rad = 1.1};
      const RollPitchYaw back = RollPitchYawFromQuaternion(QuaternionFromRollPitchYaw(rpy));
      EXPECT_LE(std::abs(back.pitch_rad), kPi / 2);
      EXPECT_LT(MaxAbsDiff(ReferenceRotation(back.roll_rad, back.pitch_rad, back.yaw_rad),
                           ReferenceRotation(roll, pitch, 1.1)),
                1e-12)
          << "pitch=" << pitch << " roll=" << roll;
    }
  }
}

TEST(RollPitchYaw, ReadsANoisyNinetyDegreePitchAsPurePitch) {
  // At gimbal lock, rounding noise in the quaternion must not turn into roll and yaw.
  const double h = std::sqrt(0.5);
  for (const double noise : {1e-17, -1e-17, 1e-16}) {
    const RollPitchYaw up = RollPitchYawFromQuaternion(Eigen::Quaterniond(h, noise, h, 0));
    EXPECT_NEAR(up.roll_rad, 0.0, 1e-15) << noise;
    EXPECT_NEAR(up.pitch_rad, kPi / 2, 1e-15) << noise;
    EXPECT_NEAR(up.yaw_rad, 0.0, 1e-15) << noise;
    const RollPitchYaw down = RollPitchYawFromQuaternion(Eigen::Quaterniond(h, 0, -h, noise));
    EXPECT_NEAR(down.roll_rad, 0.0, 1e-15) << noise;
    EXPECT_NEAR(down.pitch_rad, -kPi / 2, 1e-15) << noise;
    EXPECT_NEAR(down.yaw_rad, 0.0, 1e-15) << noise;
  }
}

TEST(RollPitchYaw, IgnoresQuaternionScaleAndSign) {
  const RollPitchYaw rpy{.roll_rad = 0.1, .pitch_rad = -0.2, .yaw_rad = 2.9};
  const Eigen::Quaterniond q = QuaternionFromRollPitchYaw(rpy);
  for (const double scale : {-1.0, 3.0, -0.01}) {
    const RollPitchYaw back =
        RollPitchYawFromQuaternion(Eigen::Quaterniond(Eigen::Vector4d(scale * q.coeffs())));
    EXPECT_NEAR(back.roll_rad, rpy.roll_rad, 1e-13) << scale;
    EXPECT_NEAR(back.pitch_rad, rpy.pitch_rad, 1e-13) << scale;
    EXPECT_NEAR(back.yaw_rad, rpy.yaw_rad, 1e-13) << scale;
  }
}

TEST(YawFromQuaternion, IsTheHeadingWithRollAndPitchPresent) {
  RandomPoses random(13);
  for (int i = 0; i < NumCases(); ++i) {
    const RollPitchYaw rpy = random.Rpy();
    const Eigen::Quaterniond q = QuaternionFromRollPitchYaw(rpy);
    const double yaw = YawFromQuaternion(q);
    // The wrapped input yaw, compared on the circle (wrapping may flip +-pi).
    ASSERT_NEAR(std::cos(yaw), std::cos(rpy.yaw_rad), 1e-12) << i;
    ASSERT_NEAR(std::sin(yaw), std::sin(rpy.yaw_rad), 1e-12) << i;
    ASSERT_GT(yaw, -kPi);
    ASSERT_LE(yaw, kPi);
    // The direction of the body's x axis projected onto the ground plane.
    const Eigen::Vector3d x_axis = q * Eigen::Vector3d::UnitX();
    ASSERT_NEAR(yaw, std::atan2(x_axis.y(), x_axis.x()), 1e-12) << i;
  }
}

TEST(YawFromQuaternion, HandExamples) {
  EXPECT_EQ(YawFromQuaternion(Eigen::Quaterniond::Identity()), 0.0);
  const Eigen::Quaterniond quarter_turn(Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR(YawFromQuaternion(quarter_turn), kPi / 2, 1e-15);
  // A half turn about Z, given either way round, is +pi.
  EXPECT_EQ(YawFromQuaternion(Eigen::Quaterniond(0, 0, 0, 1)), kPi);
  EXPECT_EQ(YawFromQuaternion(Eigen::Quaterniond(0, 0, 0, -1)), kPi);
  // A pure roll or pitch has no heading.
  EXPECT_NEAR(YawFromQuaternion(QuaternionFromRollPitchYaw({.roll_rad = 2.5})), 0.0, 1e-15);
  EXPECT_NEAR(YawFromQuaternion(QuaternionFromRollPitchYaw({.pitch_rad = 1.2})), 0.0, 1e-15);
}

TEST(YawFromQuaternion, RejectsZeroAndNonFiniteQuaternionsNamingTheValue) {
  EXPECT_EQ(InputErrorMessage([] { (void)YawFromQuaternion(Eigen::Quaterniond(0, 0, 0, 0)); }),
            "YawFromQuaternion: quaternion must have norm >= 1e-06 to be a rotation, got (w=0, "
            "x=0, y=0, z=0) of norm 0");
  EXPECT_EQ(InputErrorMessage(
                [] { (void)RollPitchYawFromQuaternion(Eigen::Quaterniond(1, kNaN, 0, 0)); }),
            "RollPitchYawFromQuaternion: quaternion must be finite, got (w=1, x=nan, y=0, z=0)");
  EXPECT_EQ(InputErrorMessage(
                [] { (void)QuaternionFromRollPitchYaw({.roll_rad = 0, .pitch_rad = kInf}); }),
            "QuaternionFromRollPitchYaw: angles must be finite, got roll=0, pitch=inf, yaw=0");
}

// ---------------------------------------------------------------------------------------------
// RigidTransform2

TEST(RigidTransform2, DefaultIsTheIdentity) {
  const RigidTransform2 X;
  EXPECT_EQ(X.translation(), Eigen::Vector2d::Zero());
  EXPECT_EQ(X.yaw(), 0.0);
  EXPECT_EQ(X.ToHomogeneous(), Eigen::Matrix3d::Identity());
  EXPECT_EQ(RigidTransform2::Identity().ToHomogeneous(), Eigen::Matrix3d::Identity());
}

TEST(RigidTransform2, RotatesThenTranslatesAPoint) {
  // Rotating (1, 0) by 90 degrees gives (0, 1); translating by (2, 3) gives (2, 4).
  const RigidTransform2 X_AB = RigidTransform2::FromXyYaw(2.0, 3.0, kPi / 2);
  const Eigen::Vector2d p_AQ = X_AB * Eigen::Vector2d(1.0, 0.0);
  EXPECT_NEAR(p_AQ.x(), 2.0, 1e-15);
  EXPECT_NEAR(p_AQ.y(), 4.0, 1e-15);
  EXPECT_EQ(X_AB.translation(), Eigen::Vector2d(2.0, 3.0));
  EXPECT_NEAR(X_AB.yaw(), kPi / 2, 1e-15);
}

TEST(RigidTransform2, ComposesLikeTheNamesRead) {
  // W->C: at (1, 0) facing +y. C->T: 1 m ahead of C, turned a further 90 degrees.
  const RigidTransform2 X_WC = RigidTransform2::FromXyYaw(1.0, 0.0, kPi / 2);
  const RigidTransform2 X_CT = RigidTransform2::FromXyYaw(1.0, 0.0, kPi / 2);
  const RigidTransform2 X_WT = X_WC * X_CT;
  EXPECT_TRUE(X_WT.IsNearlyEqualTo(RigidTransform2::FromXyYaw(1.0, 1.0, kPi), 1e-15)) << X_WT;
  EXPECT_EQ(X_WT.yaw(), kPi);
  // The inverse brings world points into the camera frame.
  const Eigen::Vector2d p_CQ = X_WC.inverse() * Eigen::Vector2d(1.0, 2.0);
  EXPECT_NEAR(p_CQ.x(), 2.0, 1e-15);
  EXPECT_NEAR(p_CQ.y(), 0.0, 1e-15);
}

TEST(RigidTransform2, AcceptsUnwrappedAnglesAndReportsWrappedYaw) {
  EXPECT_NEAR(RigidTransform2::FromXyYaw(0, 0, 2 * kPi + 0.5).yaw(), 0.5, 1e-14);
  EXPECT_NEAR(RigidTransform2({0, 0}, Eigen::Rotation2Dd(-kPi / 2 - 2 * kPi)).yaw(), -kPi / 2,
              1e-14);
  // -pi is reported as +pi, including through composition.
  EXPECT_EQ(RigidTransform2::FromXyYaw(0, 0, -kPi).yaw(), kPi);
  const RigidTransform2 half_turn = RigidTransform2::FromXyYaw(0, 0, kPi);
  EXPECT_NEAR((half_turn * half_turn.inverse() * half_turn).yaw(), kPi, 1e-15);
}

TEST(RigidTransform2, ComposingWithTheIdentityIsExact) {
  const RigidTransform2 X = RigidTransform2::FromXyYaw(0.3, -7.0, 2.2);
  for (const RigidTransform2& Y : {X * RigidTransform2::Identity(), RigidTransform2() * X}) {
    EXPECT_EQ(Y.translation(), X.translation());
    EXPECT_EQ(Y.cos_yaw(), X.cos_yaw());
    EXPECT_EQ(Y.sin_yaw(), X.sin_yaw());
  }
}

TEST(RigidTransform2, LongChainsDoNotDrift) {
  // A million steps of a millionth of a turn around a circle come back to the start, with the
  // rotation still of unit length.
  constexpr int kSteps = 1'000'000;
  const RigidTransform2 step = RigidTransform2::FromXyYaw(1e-4, 0.0, 2 * kPi / kSteps);
  RigidTransform2 X;
  for (int i = 0; i < kSteps; ++i) {
    X = X * step;
    ASSERT_NEAR(X.cos_yaw() * X.cos_yaw() + X.sin_yaw() * X.sin_yaw(), 1.0, 2e-12) << i;
  }
  EXPECT_TRUE(X.IsNearlyEqualTo(RigidTransform2(), 1e-8)) << X;
}

TEST(RigidTransform2, GroupIdentitiesHoldOnRandomTransforms) {
  RandomPoses random(21);
  const auto draw = [&] { return RigidTransform2(random.Point2(), random.Angle()); };
  for (int i = 0; i < NumCases(); ++i) {
    const RigidTransform2 A = draw(), B = draw(), C = draw();
    ASSERT_TRUE((A * A.inverse()).IsNearlyEqualTo(RigidTransform2(), kRandomTolerance)) << A;
    ASSERT_TRUE((A.inverse() * A).IsNearlyEqualTo(RigidTransform2(), kRandomTolerance)) << A;
    ASSERT_TRUE(((A * B) * C).IsNearlyEqualTo(A * (B * C), kRandomTolerance)) << A << B << C;
    ASSERT_TRUE((A * B).inverse().IsNearlyEqualTo(B.inverse() * A.inverse(), kRandomTolerance))
        << A << B;
    const Eigen::Vector2d p = random.Point2();
    ASSERT_LT(MaxAbsDiff((A * B) * p, A * (B * p)), kRandomTolerance);
  }
}

TEST(RigidTransform2, MatchesAHomogeneousMatrixReference) {
  RandomPoses random(22);
  for (int i = 0; i < NumCases(); ++i) {
    const double xa = random.Translation(), ya = random.Translation(), yawa = random.Angle();
    const double xb = random.Translation(), yb = random.Translation(), yawb = random.Angle();
    const Eigen::Matrix3d MA = ReferenceHomogeneous2(xa, ya, yawa);
    const Eigen::Matrix3d MB = ReferenceHomogeneous2(xb, yb, yawb);
    const RigidTransform2 A = RigidTransform2::FromXyYaw(xa, ya, yawa);
    const RigidTransform2 B = RigidTransform2::FromXyYaw(xb, yb, yawb);
    ASSERT_LT(MaxAbsDiff(A.ToHomogeneous(), MA), 1e-15) << i;
    ASSERT_LT(MaxAbsDiff((A * B).ToHomogeneous(), MA * MB), kRandomTolerance) << i;
    ASSERT_LT(MaxAbsDiff(A.inverse().ToHomogeneous(), MA.inverse()), kRandomTolerance) << i;
    ASSERT_LT(MaxAbsDiff(A.rotation_matrix(), MA.topLeftCorner<2, 2>()), 1e-15) << i;
    const Eigen::Vector2d p = random.Point2();
    ASSERT_LT(MaxAbsDiff(A * p, (MA * p.homogeneous()).head<2>()), kRandomTolerance) << i;
    ASSERT_TRUE(RigidTransform2::FromHomogeneous(MA).IsNearlyEqualTo(A, 1e-14)) << i;
    ASSERT_NEAR(std::cos(A.yaw()), std::cos(yawa), 1e-14) << i;
    ASSERT_NEAR(std::sin(A.yaw()), std::sin(yawa), 1e-14) << i;
    ASSERT_EQ(A.rotation().angle(), A.yaw()) << i;
  }
}

TEST(RigidTransform2, IsNearlyEqualToComparesEveryElementAgainstTheTolerance) {
  const RigidTransform2 X = RigidTransform2::FromXyYaw(1.0, 2.0, 0.5);
  EXPECT_TRUE(X.IsNearlyEqualTo(X, 0.0));
  EXPECT_TRUE(X.IsNearlyEqualTo(RigidTransform2::FromXyYaw(1.0, 2.0 + 1e-7, 0.5), 2e-7));
  EXPECT_FALSE(X.IsNearlyEqualTo(RigidTransform2::FromXyYaw(1.0, 2.0 + 1e-7, 0.5), 5e-8));
  EXPECT_FALSE(X.IsNearlyEqualTo(RigidTransform2::FromXyYaw(1.0, 2.0, 0.5 + 1e-6), 5e-7));
  EXPECT_TRUE(X.IsNearlyEqualTo(RigidTransform2::FromXyYaw(1.0, 2.0, 0.5 + 2 * kPi), 1e-14));
}

TEST(RigidTransform2, FromHomogeneousAcceptsSmallErrorsWithinTheTolerance) {
  Eigen::Matrix3d M = ReferenceHomogeneous2(1.0, -2.0, 0.7);
  M(0, 0) += 1e-8;  // As read from a file printed with 8 digits.
  const RigidTransform2 X = RigidTransform2::FromHomogeneous(M);
  EXPECT_TRUE(X.IsNearlyEqualTo(RigidTransform2::FromXyYaw(1.0, -2.0, 0.7), 1e-8)) << X;
  EXPECT_NO_THROW((void)RigidTransform2::FromHomogeneous(M, 1e-7));
  EXPECT_THROW((void)RigidTransform2::FromHomogeneous(M, 1e-9), InputError);
}

TEST(RigidTransform2, FromHomogeneousRejectsNonRigidMatricesNamingThem) {
  Eigen::Matrix3d reflection = Eigen::Matrix3d::Identity();
  reflection(1, 1) = -1.0;
  EXPECT_EQ(InputErrorMessage([&] { (void)RigidTransform2::FromHomogeneous(reflection); }),
            "RigidTransform2::FromHomogeneous: not a rigid transform to within 1e-06 (max |R^T R "
            "- I| = 0, det R = -1, last row (0, 0, 1)), got [1, 0, 0; 0, -1, 0; 0, 0, 1]");
  Eigen::Matrix3d scaled = 2.0 * ReferenceHomogeneous2(0, 0, 0);
  scaled(2, 2) = 1.0;
  EXPECT_THAT(InputErrorMessage([&] { (void)RigidTransform2::FromHomogeneous(scaled); }),
              HasSubstr("max |R^T R - I| = 3, det R = 4"));
  Eigen::Matrix3d last_row = Eigen::Matrix3d::Identity();
  last_row(2, 0) = 0.5;
  EXPECT_THAT(InputErrorMessage([&] { (void)RigidTransform2::FromHomogeneous(last_row); }),
              HasSubstr("last row (0.5, 0, 1)"));
  Eigen::Matrix3d not_finite = Eigen::Matrix3d::Identity();
  not_finite(0, 2) = kNaN;
  EXPECT_EQ(InputErrorMessage([&] { (void)RigidTransform2::FromHomogeneous(not_finite); }),
            "RigidTransform2::FromHomogeneous: matrix must be finite, got [1, 0, nan; 0, 1, 0; "
            "0, 0, 1]");
}

TEST(RigidTransform2DeathTest, NegativeToleranceIsAProgrammerError) {
  EXPECT_DEATH((void)RigidTransform2::FromHomogeneous(Eigen::Matrix3d::Identity(), -1.0),
               "AUTODRIVE_CHECK failed: tolerance >= 0.0 \\(tolerance=-1\\)");
}

TEST(RigidTransform2, RejectsNonFiniteInputNamingTheValue) {
  EXPECT_EQ(InputErrorMessage([] { (void)RigidTransform2::FromXyYaw(kNaN, 1.5, 0.0); }),
            "RigidTransform2: translation must be finite, got (nan, 1.5)");
  EXPECT_EQ(InputErrorMessage([] { (void)RigidTransform2(Eigen::Vector2d(1, 2), kInf); }),
            "RigidTransform2: yaw must be finite, got inf");
  EXPECT_EQ(InputErrorMessage([] { (void)RigidTransform2().ToRigidTransform3(kNaN); }),
            "RigidTransform2::ToRigidTransform3: z must be finite, got nan");
}

TEST(RigidTransform2, PrintsTranslationAndYaw) {
  std::ostringstream os;
  os << RigidTransform2::FromXyYaw(1.0, -2.5, 0.5);
  EXPECT_EQ(os.str(), "RigidTransform2(x=1, y=-2.5, yaw=0.5)");
}

// ---------------------------------------------------------------------------------------------
// RigidTransform3

TEST(RigidTransform3, DefaultIsTheIdentity) {
  const RigidTransform3 X;
  EXPECT_EQ(X.translation(), Eigen::Vector3d::Zero());
  EXPECT_EQ(X.ToHomogeneous(), Eigen::Matrix4d::Identity());
  EXPECT_EQ(RigidTransform3::Identity().ToHomogeneous(), Eigen::Matrix4d::Identity());
}

TEST(RigidTransform3, RotatesThenTranslatesAPoint) {
  const RigidTransform3 X_AB(Eigen::Vector3d(1, 2, 3), RollPitchYaw{.yaw_rad = kPi / 2});
  EXPECT_LT(MaxAbsDiff(X_AB * Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 3, 3)), 1e-15);
  const RigidTransform3 roll(Eigen::Vector3d::Zero(), RollPitchYaw{.roll_rad = kPi / 2});
  EXPECT_LT(MaxAbsDiff(roll * Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(0, 0, 1)), 1e-15);
}

TEST(RigidTransform3, ComposesLikeTheNamesRead) {
  // A camera 2 m up looking straight down (its z axis is the world's -z, x along world x);
  // a tag 2 m in front of it lies on the ground below the camera, facing up.
  const RigidTransform3 X_WC(Eigen::Vector3d(0.5, 0.0, 2.0), RollPitchYaw{.roll_rad = kPi});
  const RigidTransform3 X_CT(Eigen::Vector3d(0.0, 0.0, 2.0), RollPitchYaw{.roll_rad = kPi});
  const RigidTransform3 X_WT = X_WC * X_CT;
  EXPECT_TRUE(X_WT.IsNearlyEqualTo(
      RigidTransform3(Eigen::Vector3d(0.5, 0, 0), Eigen::Quaterniond::Identity()), 1e-15))
      << X_WT;
}

TEST(RigidTransform3, NormalisesTheQuaternionItIsGiven) {
  const Eigen::Quaterniond q = QuaternionFromRollPitchYaw({.roll_rad = 0.3, .yaw_rad = -1.0});
  const RigidTransform3 X(Eigen::Vector3d(1, 2, 3),
                          Eigen::Quaterniond(Eigen::Vector4d(-5.0 * q.coeffs())));
  EXPECT_NEAR(X.rotation().norm(), 1.0, 1e-15);
  EXPECT_TRUE(X.IsNearlyEqualTo(RigidTransform3(Eigen::Vector3d(1, 2, 3), q), 1e-15)) << X;
}

TEST(RigidTransform3, ComposingWithTheIdentityIsExact) {
  const RigidTransform3 X(Eigen::Vector3d(0.3, -7.0, 1.0),
                          RollPitchYaw{.roll_rad = 0.1, .pitch_rad = 0.2, .yaw_rad = 2.2});
  for (const RigidTransform3& Y : {X * RigidTransform3::Identity(), RigidTransform3() * X}) {
    EXPECT_EQ(Y.translation(), X.translation());
    EXPECT_EQ(Y.rotation().coeffs(), X.rotation().coeffs());
  }
}

TEST(RigidTransform3, LongChainsDoNotDrift) {
  // A million screw steps of a millionth of a turn about n = (1, 1, 1)/sqrt(3) make a whole
  // turn: the rotation comes back to the identity and the translation adds up to its component
  // along n, kSteps * (t . n) n = (100/3, 100/3, 100/3).
  constexpr int kSteps = 1'000'000;
  const Eigen::Vector3d n = Eigen::Vector3d(1, 1, 1).normalized();
  const RigidTransform3 step(Eigen::Vector3d(1e-4, 0.0, 0.0),
                             Eigen::Quaterniond(Eigen::AngleAxisd(2 * kPi / kSteps, n)));
  RigidTransform3 X;
  for (int i = 0; i < kSteps; ++i) {
    X = X * step;
    ASSERT_NEAR(X.rotation().squaredNorm(), 1.0, 2e-12) << i;
  }
  EXPECT_TRUE(X.IsNearlyEqualTo(
      RigidTransform3(Eigen::Vector3d::Constant(100.0 / 3), Eigen::Quaterniond::Identity()), 1e-8))
      << X;
}

TEST(RigidTransform3, GroupIdentitiesHoldOnRandomTransforms) {
  RandomPoses random(31);
  const auto draw = [&] { return RigidTransform3(random.Point3(), random.Rpy()); };
  for (int i = 0; i < NumCases(); ++i) {
    const RigidTransform3 A = draw(), B = draw(), C = draw();
    ASSERT_TRUE((A * A.inverse()).IsNearlyEqualTo(RigidTransform3(), kRandomTolerance)) << A;
    ASSERT_TRUE((A.inverse() * A).IsNearlyEqualTo(RigidTransform3(), kRandomTolerance)) << A;
    ASSERT_TRUE(((A * B) * C).IsNearlyEqualTo(A * (B * C), kRandomTolerance)) << A << B << C;
    ASSERT_TRUE((A * B).inverse().IsNearlyEqualTo(B.inverse() * A.inverse(), kRandomTolerance))
        << A << B;
    const Eigen::Vector3d p = random.Point3();
    ASSERT_LT(MaxAbsDiff((A * B) * p, A * (B * p)), kRandomTolerance);
  }
}

TEST(RigidTransform3, MatchesAHomogeneousMatrixReference) {
  RandomPoses random(32);
  for (int i = 0; i < NumCases(); ++i) {
    const Eigen::Vector3d pa = random.Point3(), pb = random.Point3();
    const RollPitchYaw rpya = random.Rpy(), rpyb = random.Rpy();
    const Eigen::Matrix4d MA = ReferenceHomogeneous3(pa, rpya);
    const Eigen::Matrix4d MB = ReferenceHomogeneous3(pb, rpyb);
    const RigidTransform3 A(pa, rpya);
    const RigidTransform3 B(pb, rpyb);
    ASSERT_LT(MaxAbsDiff(A.ToHomogeneous(), MA), 1e-14) << i;
    ASSERT_LT(MaxAbsDiff((A * B).ToHomogeneous(), MA * MB), kRandomTolerance) << i;
    ASSERT_LT(MaxAbsDiff(A.inverse().ToHomogeneous(), MA.inverse()), kRandomTolerance) << i;
    const Eigen::Vector3d p = random.Point3();
    ASSERT_LT(MaxAbsDiff(A * p, (MA * p.homogeneous()).head<3>()), kRandomTolerance) << i;
    ASSERT_TRUE(RigidTransform3::FromHomogeneous(MA).IsNearlyEqualTo(A, 1e-14)) << i;
    ASSERT_NEAR(A.yaw(), std::atan2(MA(1, 0), MA(0, 0)), 1e-12) << i;
    const RollPitchYaw rpy = A.roll_pitch_yaw();
    ASSERT_LT(MaxAbsDiff(ReferenceRotation(rpy.roll_rad, rpy.pitch_rad, rpy.yaw_rad),
                         MA.topLeftCorner<3, 3>()),
              1e-12)
        << i;
  }
}

TEST(RigidTransform3, IsNearlyEqualToTreatsQAndMinusQAsTheSameRotation) {
  const Eigen::Quaterniond q = QuaternionFromRollPitchYaw({.roll_rad = 1, .pitch_rad = 0.5});
  const RigidTransform3 X(Eigen::Vector3d(1, 2, 3), q);
  const RigidTransform3 Y(Eigen::Vector3d(1, 2, 3),
                          Eigen::Quaterniond(Eigen::Vector4d(-q.coeffs())));
  EXPECT_TRUE(X.IsNearlyEqualTo(Y, 1e-15));
  EXPECT_FALSE(X.IsNearlyEqualTo(RigidTransform3(Eigen::Vector3d(1, 2, 3 + 1e-6), q), 5e-7));
  EXPECT_FALSE(
      X.IsNearlyEqualTo(RigidTransform3(Eigen::Vector3d(1, 2, 3),
                                        RollPitchYaw{.roll_rad = 1 + 1e-6, .pitch_rad = 0.5}),
                        5e-7));
}

TEST(RigidTransform3, FromHomogeneousRejectsNonRigidMatricesNamingThem) {
  Eigen::Matrix4d reflection = Eigen::Matrix4d::Identity();
  reflection(2, 2) = -1.0;
  EXPECT_EQ(InputErrorMessage([&] { (void)RigidTransform3::FromHomogeneous(reflection); }),
            "RigidTransform3::FromHomogeneous: not a rigid transform to within 1e-06 (max |R^T R "
            "- I| = 0, det R = -1, last row (0, 0, 0, 1)), got [1, 0, 0, 0; 0, 1, 0, 0; 0, 0, "
            "-1, 0; 0, 0, 0, 1]");
  Eigen::Matrix4d sheared = Eigen::Matrix4d::Identity();
  sheared(0, 1) = 0.1;
  EXPECT_THAT(InputErrorMessage([&] { (void)RigidTransform3::FromHomogeneous(sheared); }),
              HasSubstr("max |R^T R - I| = 0.1"));
  Eigen::Matrix4d last_row = Eigen::Matrix4d::Identity();
  last_row(3, 3) = 2.0;
  EXPECT_THAT(InputErrorMessage([&] { (void)RigidTransform3::FromHomogeneous(last_row); }),
              HasSubstr("last row (0, 0, 0, 2)"));
  Eigen::Matrix4d not_finite = Eigen::Matrix4d::Identity();
  not_finite(1, 3) = -kInf;
  EXPECT_THAT(InputErrorMessage([&] { (void)RigidTransform3::FromHomogeneous(not_finite); }),
              HasSubstr("matrix must be finite, got [1, 0, 0, 0; 0, 1, 0, -inf;"));
}

TEST(RigidTransform3DeathTest, NegativeToleranceIsAProgrammerError) {
  EXPECT_DEATH((void)RigidTransform3::FromHomogeneous(Eigen::Matrix4d::Identity(), -0.5),
               "AUTODRIVE_CHECK failed: tolerance >= 0.0 \\(tolerance=-0.5\\)");
}

TEST(RigidTransform3, RejectsBadInputNamingTheValue) {
  EXPECT_EQ(InputErrorMessage([] {
              (void)RigidTransform3(Eigen::Vector3d(0, 0, 0), Eigen::Quaterniond(0, 0, 0, 0));
            }),
            "RigidTransform3: quaternion must have norm >= 1e-06 to be a rotation, got (w=0, x=0, "
            "y=0, z=0) of norm 0");
  EXPECT_EQ(InputErrorMessage([] {
              (void)RigidTransform3(Eigen::Vector3d(0, 0, 0), Eigen::Quaterniond(1e-7, 0, 0, 0));
            }),
            "RigidTransform3: quaternion must have norm >= 1e-06 to be a rotation, got (w=1e-07, "
            "x=0, y=0, z=0) of norm 1e-07");
  EXPECT_EQ(InputErrorMessage([] {
              (void)RigidTransform3(Eigen::Vector3d(0, 0, 0), Eigen::Quaterniond(kNaN, 0, 0, 1));
            }),
            "RigidTransform3: quaternion must be finite, got (w=nan, x=0, y=0, z=1)");
  EXPECT_EQ(InputErrorMessage([] {
              (void)RigidTransform3(Eigen::Vector3d(1, kInf, 0), Eigen::Quaterniond::Identity());
            }),
            "RigidTransform3: translation must be finite, got (1, inf, 0)");
  EXPECT_EQ(InputErrorMessage([] {
              (void)RigidTransform3(Eigen::Vector3d(0, 0, 0), RollPitchYaw{.yaw_rad = kNaN});
            }),
            "QuaternionFromRollPitchYaw: angles must be finite, got roll=0, pitch=0, yaw=nan");
}

TEST(RigidTransform3, PrintsTranslationAndRollPitchYaw) {
  std::ostringstream os;
  os << RigidTransform3(Eigen::Vector3d(1, 2, -3), RollPitchYaw{.yaw_rad = 0.5});
  EXPECT_EQ(os.str(), "RigidTransform3(xyz=(1, 2, -3), rpy=(0, 0, 0.5))");
}

// ---------------------------------------------------------------------------------------------
// 2D <-> 3D

TEST(PlanarTransforms, TwoAndThreeDimensionalClassesAgree) {
  RandomPoses random(41);
  for (int i = 0; i < NumCases(); ++i) {
    const RigidTransform2 A2(random.Point2(), random.Angle());
    const RigidTransform2 B2(random.Point2(), random.Angle());
    const double za = random.Translation(), zb = random.Translation();
    const RigidTransform3 A3 = A2.ToRigidTransform3(za);
    const RigidTransform3 B3 = B2.ToRigidTransform3(zb);
    // Lifting and projecting back is the identity.
    ASSERT_TRUE(A3.ToRigidTransform2().IsNearlyEqualTo(A2, 1e-14)) << A2 << A3;
    ASSERT_EQ(A3.translation().z(), za);
    // The homogeneous matrices agree on x, y and the rotation about z.
    const Eigen::Matrix3d M2 = A2.ToHomogeneous();
    const Eigen::Matrix4d M3 = A3.ToHomogeneous();
    const Eigen::Matrix3d M3_planar = M3(std::vector<int>{0, 1, 3}, std::vector<int>{0, 1, 3});
    ASSERT_LT(MaxAbsDiff(M3_planar, M2), 1e-14) << i;
    // Composition, inversion and points agree; heights add up.
    const RigidTransform3 AB3 = A3 * B3;
    ASSERT_TRUE(AB3.ToRigidTransform2().IsNearlyEqualTo(A2 * B2, kRandomTolerance)) << i;
    ASSERT_NEAR(AB3.translation().z(), za + zb, kRandomTolerance);
    const RollPitchYaw rpy = AB3.roll_pitch_yaw();
    ASSERT_NEAR(rpy.roll_rad, 0.0, 1e-14);
    ASSERT_NEAR(rpy.pitch_rad, 0.0, 1e-14);
    ASSERT_TRUE(A3.inverse().ToRigidTransform2().IsNearlyEqualTo(A2.inverse(), kRandomTolerance));
    const Eigen::Vector2d p = random.Point2();
    const Eigen::Vector3d p3 = A3 * Eigen::Vector3d(p.x(), p.y(), 0.25);
    ASSERT_LT(MaxAbsDiff(p3.head<2>(), A2 * p), kRandomTolerance);
    ASSERT_NEAR(p3.z(), za + 0.25, kRandomTolerance);
  }
}

TEST(PlanarTransforms, LiftDefaultsToTheGroundPlane) {
  const RigidTransform3 X = RigidTransform2::FromXyYaw(1.0, 2.0, -0.5).ToRigidTransform3();
  EXPECT_EQ(X.translation(), Eigen::Vector3d(1.0, 2.0, 0.0));
  EXPECT_NEAR(X.yaw(), -0.5, 1e-15);
}

TEST(PlanarTransforms, ProjectionDropsRollPitchAndHeight) {
  const RigidTransform3 X(Eigen::Vector3d(1.0, -2.0, 0.7),
                          RollPitchYaw{.roll_rad = 0.2, .pitch_rad = -0.3, .yaw_rad = 2.5});
  const RigidTransform2 X2 = X.ToRigidTransform2();
  EXPECT_EQ(X2.translation(), Eigen::Vector2d(1.0, -2.0));
  EXPECT_NEAR(X2.yaw(), 2.5, 1e-14);
}

}  // namespace
}  // namespace autodrive
