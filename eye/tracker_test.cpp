#include "eye/tracker.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>

#include <Eigen/Geometry>

namespace autodrive::eye {
namespace {

// A car on a circle of radius 0.8 m at 0.2 m/s, its tag measured every 1/30 s with the noise
// the covariance states (2 mm, 0.6°).
TEST(VehicleTrack, FilteringBeatsTheRawMeasurementsOnACurve) {
  VehicleTagConfig car;
  car.name = "nigel_1";
  VehicleTrack track(car, TrackingConfig{});
  std::mt19937 rng(3);
  const double sp = 0.002, sy = 0.6 * kPi / 180;
  std::normal_distribution<double> np(0.0, sp), ny(0.0, sy);
  double raw2 = 0, filtered2 = 0, raw_yaw2 = 0, filtered_yaw2 = 0, speed = 0, yaw_rate = 0;
  int n = 0, outliers = 0;
  for (int i = 0; i < 600; ++i) {
    const double t = i / 30.0, w = 0.2 / 0.8, th = w * t;
    // The rear axle on the circle; the heading is its tangent.
    const Eigen::Vector2d p(0.8 * std::sin(th), 0.8 * (1 - std::cos(th)));
    const double yaw = th;
    const Eigen::Vector2d tag =
        p + car.mount.ahead_m * Eigen::Vector2d(std::cos(yaw), std::sin(yaw));
    PlanarTagPose m;
    m.p_M = tag + Eigen::Vector2d(np(rng), np(rng));
    m.yaw_rad = yaw - kPi / 2 + ny(rng);
    m.covariance = Eigen::Vector3d(sp * sp, sp * sp, sy * sy).asDiagonal();
    // Gaussian noise leaves about 1 in 1,000 measurements outside the 99.9% gate.
    outliers += track.Update(TimeFromSeconds(t), m) == TrackUpdate::kOutlier ? 1 : 0;
    if (i < 60) continue;  // settled
    const VehicleEstimate e = track.Last();
    raw2 += (m.p_M - tag).squaredNorm();
    filtered2 += (e.tag_centre_M - tag).squaredNorm();
    raw_yaw2 += std::pow(std::remainder(m.yaw_rad + kPi / 2 - yaw, 2 * kPi), 2);
    filtered_yaw2 += std::pow(std::remainder(e.pose.z() - yaw, 2 * kPi), 2);
    speed += e.speed_mps;
    yaw_rate += e.yaw_rate_radps;
    ++n;
  }
  const double raw = std::sqrt(raw2 / n), filtered = std::sqrt(filtered2 / n);
  const double raw_yaw = std::sqrt(raw_yaw2 / n), filtered_yaw = std::sqrt(filtered_yaw2 / n);
  std::cout << "[ measured ] position RMS raw " << raw * 1e3 << " mm, filtered " << filtered * 1e3
            << " mm; heading RMS raw " << raw_yaw * 180 / kPi << " deg, filtered "
            << filtered_yaw * 180 / kPi << " deg\n";
  EXPECT_LT(filtered, 0.7 * raw);
  EXPECT_LT(filtered_yaw, 0.7 * raw_yaw);
  EXPECT_LE(outliers, 3);
  // Speed and turn rate are estimated without bias.
  EXPECT_NEAR(speed / n, 0.2, 0.01);
  EXPECT_NEAR(yaw_rate / n, 0.2 / 0.8, 0.02);
}

PlanarTagPose At(double x, double y, double car_yaw) {
  PlanarTagPose m;
  m.p_M = {x, y};
  m.yaw_rad = car_yaw - kPi / 2;
  m.covariance = Eigen::Vector3d(4e-6, 4e-6, 1e-4).asDiagonal();
  return m;
}

TEST(VehicleTrack, AnOutlierIsGatedAndRepeatedOnesRestartTheTrack) {
  VehicleTagConfig car;
  car.name = "nigel_2";
  TrackingConfig config;
  config.restart_after_outliers = 3;
  VehicleTrack track(car, config);
  int i = 0;
  for (; i < 30; ++i) track.Update(TimeFromSeconds(i / 30.0), At(1.0, 1.0, 0.0));
  // A tag 0.5 m away in one frame: gated, the estimate stays.
  EXPECT_EQ(track.Update(TimeFromSeconds(i++ / 30.0), At(1.5, 1.0, 0.0)), TrackUpdate::kOutlier);
  EXPECT_NEAR(track.Last().tag_centre_M.x(), 1.0, 0.01);
  EXPECT_EQ(track.Update(TimeFromSeconds(i++ / 30.0), At(1.0, 1.0, 0.0)), TrackUpdate::kUpdated);
  // The car really is elsewhere (carried away by hand): the third outlier in a row restarts.
  EXPECT_EQ(track.Update(TimeFromSeconds(i++ / 30.0), At(3.0, 2.0, 1.0)), TrackUpdate::kOutlier);
  EXPECT_EQ(track.Update(TimeFromSeconds(i++ / 30.0), At(3.0, 2.0, 1.0)), TrackUpdate::kOutlier);
  EXPECT_EQ(track.Update(TimeFromSeconds(i++ / 30.0), At(3.0, 2.0, 1.0)), TrackUpdate::kRestarted);
  EXPECT_NEAR(track.Last().tag_centre_M.x(), 3.0, 1e-9);
  EXPECT_EQ(track.outliers(), 4);  // the one that restarted counts too
}

TEST(VehicleTrack, APredictionCarriesThroughMissedFramesAndTheTrackIsLostAfterItsTimeOut) {
  VehicleTagConfig car;
  car.name = "nigel_3";
  VehicleTrack track(car, TrackingConfig{});
  // Straight east at 0.2 m/s for 3 s.
  for (int i = 0; i <= 90; ++i) {
    track.Update(TimeFromSeconds(i / 30.0), At(0.5 + 0.2 * i / 30.0, 1.0, 0.0));
  }
  const VehicleEstimate later = track.Predict(TimeFromSeconds(3.3));
  EXPECT_NEAR(later.tag_centre_M.x(), 0.5 + 0.2 * 3.3, 0.005);
  EXPECT_GT(later.covariance(0, 0), track.Last().covariance(0, 0));
  EXPECT_TRUE(track.active(TimeFromSeconds(3.4)));
  EXPECT_FALSE(track.active(TimeFromSeconds(3.6)));  // lost_after_s 0.5
  // A late frame (out of order) is still fused; a much older one is not.
  EXPECT_EQ(track.Update(TimeFromSeconds(3.0 - 0.05), At(0.5 + 0.2 * 2.95, 1.0, 0.0)),
            TrackUpdate::kUpdated);
  EXPECT_EQ(track.Update(TimeFromSeconds(2.0), At(0.9, 1.0, 0.0)), TrackUpdate::kTooOld);
}

// A tag turned and moved on the roof, configured so: the filter follows the rear axle on a
// curve as with the default mounting, without outliers; configured the default way instead, it
// refuses most measurements.
TEST(VehicleTrack, ATagTurnedAndMovedOnTheRoofIsFollowedThroughItsMounting) {
  VehicleTagConfig car;
  car.name = "nigel_1";
  car.mount = {90.0, 0.05, 0.02};
  VehicleTagConfig unconfigured = car;
  unconfigured.mount = {};
  VehicleTrack track(car, TrackingConfig{});
  VehicleTrack wrong(unconfigured, TrackingConfig{});
  int outliers = 0, wrong_refused = 0;
  double max_error = 0, max_yaw_error = 0;
  for (int i = 0; i < 300; ++i) {
    const double t = i / 30.0, w = 0.2 / 0.8, th = w * t;
    const Eigen::Vector2d p(0.8 * std::sin(th), 0.8 * (1 - std::cos(th)));
    PlanarTagPose m;
    m.p_M = p + Eigen::Rotation2Dd(th) * car.mount.p_VT();
    m.yaw_rad = car.mount.TagYaw(th);
    m.covariance = Eigen::Vector3d(4e-6, 4e-6, 1e-4).asDiagonal();
    outliers += track.Update(TimeFromSeconds(t), m) == TrackUpdate::kOutlier ? 1 : 0;
    const TrackUpdate w_result = wrong.Update(TimeFromSeconds(t), m);
    wrong_refused +=
        w_result == TrackUpdate::kOutlier || w_result == TrackUpdate::kRestarted ? 1 : 0;
    if (i < 30) continue;
    const VehicleEstimate e = track.Last();
    max_error = std::max(max_error, (e.pose.head<2>() - p).norm());
    max_error = std::max(max_error, (e.tag_centre_M - m.p_M).norm());
    max_yaw_error = std::max(max_yaw_error, std::abs(std::remainder(e.pose.z() - th, 2 * kPi)));
  }
  EXPECT_EQ(outliers, 0);
  EXPECT_LT(max_error, 0.002);
  EXPECT_LT(max_yaw_error, 0.5 * kPi / 180);
  EXPECT_GT(wrong_refused, 200);
}

TEST(VehicleTrack, AnUpdateCanBeTakenBackOnce) {
  VehicleTagConfig car;
  car.name = "nigel_1";
  VehicleTrack track(car, TrackingConfig{});
  track.set_undoable(true);
  for (int i = 0; i < 10; ++i)
    track.Update(TimeFromSeconds(i / 30.0), At(1.0 + 0.2 * i / 30.0, 1.0, 0.0));
  const VehicleEstimate before = track.Last();
  EXPECT_EQ(track.Update(TimeFromSeconds(10 / 30.0), At(1.0 + 0.2 * 10 / 30.0, 1.0, 0.0)),
            TrackUpdate::kUpdated);
  EXPECT_NE(track.last_update(), before.stamp);
  track.UndoLastUpdate();
  EXPECT_EQ(track.last_update(), before.stamp);
  EXPECT_EQ(track.Last().pose, before.pose);
  EXPECT_EQ(track.Last().covariance, before.covariance);
  track.UndoLastUpdate();  // once only
  EXPECT_EQ(track.last_update(), before.stamp);
  // The first measurement, taken back: the track has not started.
  VehicleTrack fresh(car, TrackingConfig{});
  fresh.set_undoable(true);
  EXPECT_EQ(fresh.Update(TimeFromSeconds(0), At(1.0, 1.0, 0.0)), TrackUpdate::kStarted);
  fresh.UndoLastUpdate();
  EXPECT_FALSE(fresh.started());
  // Held: a track not allowed to start does not.
  EXPECT_EQ(fresh.Update(TimeFromSeconds(0.1), At(1.0, 1.0, 0.0), false), TrackUpdate::kHeld);
  EXPECT_FALSE(fresh.started());
}

}  // namespace
}  // namespace autodrive::eye
