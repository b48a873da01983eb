// The checks on a car's measurements: its tag's mounting against its motion, and the episodes
// of another tag with its id. A car is driven here on an explicit clock, its tag measured with
// noise as the Eye measures it, through the filter that decides what is refused.
#include "eye/track_checks.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <iostream>
#include <random>

#include "eye/tracker.h"

namespace autodrive::eye {
namespace {

constexpr double kDeg = kPi / 180.0;
constexpr double kRateHz = 30.0;

// The car's rear axle and heading at a time.
struct Motion {
  Eigen::Vector2d p;
  double heading;
};

// Round a circle of `radius_m` (left turn) at `speed_mps` from the origin heading east; a
// negative speed drives it backwards; radius 0: straight.
std::function<Motion(double)> Drive(double speed_mps, double radius_m) {
  return [=](double t) {
    if (radius_m == 0.0) return Motion{{speed_mps * t, 0.0}, 0.0};
    const double th = speed_mps / radius_m * t;
    return Motion{{radius_m * std::sin(th), radius_m * (1 - std::cos(th))}, th};
  };
}

// A car whose tag is mounted as `truth` while the Eye is configured with `configured`: its
// measurements through the filter and the check, from `t0` for `duration_s`.
class Car {
 public:
  Car(const camera::RoofTagMount& truth, const camera::RoofTagMount& configured, unsigned seed = 1)
      : truth_(truth),
        track_(Vehicle(configured), TrackingConfig{}),
        check_(configured),
        rng_(seed) {}

  // Drives `motion` (shifted to start where the car is) for `duration_s`; returns the time of
  // each report of the check.
  void Run(const std::function<Motion(double)>& motion, double duration_s) {
    const Motion start = motion(0.0);
    const double steps = std::round(duration_s * kRateHz);
    for (int i = 0; i < static_cast<int>(steps); ++i) {
      const double t = t_ + i / kRateHz;
      Motion m = motion(i / kRateHz);
      // Continue from where the last run ended: motion's start put at the car's pose.
      const Eigen::Rotation2Dd R(heading_ - start.heading);
      m.p = p_ + R * (m.p - start.p);
      m.heading += heading_ - start.heading;
      last_ = m;
      Measure(t, m);
    }
    t_ += steps / kRateHz;
    p_ = last_.p;
    heading_ = last_.heading;
  }
  void Stand(double duration_s) {
    Run([](double) { return Motion{{0.0, 0.0}, 0.0}; }, duration_s);
  }

  int raised = 0, cleared = 0;
  std::optional<double> first_raised_s;
  MountingFinding first;
  const MountingCheck& check() const { return check_; }

 private:
  static VehicleTagConfig Vehicle(const camera::RoofTagMount& mount) {
    VehicleTagConfig v;
    v.name = "nigel_1";
    v.tag_id = 1;
    v.mount = mount;
    return v;
  }
  void Measure(double t, const Motion& m) {
    std::normal_distribution<double> np(0.0, 0.0005), ny(0.0, 0.2 * kDeg);
    PlanarTagPose tag;
    tag.p_M =
        m.p + Eigen::Rotation2Dd(m.heading) * truth_.p_VT() + Eigen::Vector2d(np(rng_), np(rng_));
    tag.yaw_rad = truth_.TagYaw(m.heading) + ny(rng_);
    tag.covariance =
        Eigen::Vector3d(0.0005 * 0.0005, 0.0005 * 0.0005, std::pow(0.2 * kDeg, 2)).asDiagonal();
    const Time stamp = TimeFromSeconds(t);
    const TrackUpdate result = track_.Update(stamp, tag);
    const bool refused = result == TrackUpdate::kOutlier || result == TrackUpdate::kRestarted;
    switch (check_.Add(stamp, tag.p_M, track_.VehicleYawOfTag(tag.yaw_rad), refused)) {
      case MountingCheck::Report::kRaised:
        if (raised++ == 0) {
          first_raised_s = t;
          first = check_.finding();
        }
        break;
      case MountingCheck::Report::kCleared:
        ++cleared;
        break;
      case MountingCheck::Report::kNothing:
        break;
    }
  }

  camera::RoofTagMount truth_;
  VehicleTrack track_;
  MountingCheck check_;
  std::mt19937 rng_;
  double t_ = 0.0;
  Eigen::Vector2d p_ = Eigen::Vector2d(1.0, 1.0);
  double heading_ = 0.3;
  Motion last_{};
};

camera::RoofTagMount Turned(double yaw_deg, double ahead_m = 0.07077, double left_m = 0.0) {
  return {yaw_deg, ahead_m, left_m};
}

TEST(MountingCheck, ACorrectlyMountedCarStandingTurningAndReversingRaisesNothing) {
  for (const camera::RoofTagMount& mount :
       {Turned(0.0), Turned(90.0, 0.05, 0.02), Turned(270.0, 0.10, -0.01)}) {
    Car car(mount, mount);
    car.Stand(10.0);
    car.Run(Drive(0.2, 0.0), 3.0);
    car.Run(Drive(0.25, 0.6), 10.0);   // a tight left turn
    car.Run(Drive(0.15, -0.8), 10.0);  // right
    car.Run(Drive(-0.1, 0.0), 3.0);    // reversing into a parking place
    car.Stand(5.0);
    EXPECT_EQ(car.raised, 0) << mount.yaw_deg << ": raised at " << car.first_raised_s.value_or(-1)
                             << " s, turn " << car.first.turn_rad.value_or(0.0) / kDeg << " deg";
  }
}

TEST(MountingCheck, ATagTurnedOnTheRoofRaisesOnceWithin2SecondsSayingHowFar) {
  struct Case {
    double true_yaw_deg;
    double configured_yaw_deg;
    double turn_deg;  // the turn the check should find
  };
  for (const Case& c :
       {Case{90, 0, 90}, Case{270, 0, -90}, Case{0, 90, -90}, Case{45, 0, 45}, Case{180, 90, 90}}) {
    for (const double radius : {0.0, 0.8}) {
      Car car(Turned(c.true_yaw_deg), Turned(c.configured_yaw_deg), 7);
      car.Stand(2.0);
      car.Run(Drive(0.2, radius), 12.0);
      const std::string what = std::to_string(c.true_yaw_deg) + " configured " +
                               std::to_string(c.configured_yaw_deg) + ", radius " +
                               std::to_string(radius);
      ASSERT_TRUE(car.first_raised_s.has_value()) << what;
      ASSERT_TRUE(car.first.turn_rad.has_value()) << what;
      std::cout << "[ measured ] " << what << ": raised " << *car.first_raised_s - 2.0
                << " s after it started moving, " << car.first.refused << " of " << car.first.of
                << " refused, turn " << *car.first.turn_rad / kDeg << " deg\n";
      EXPECT_LE(*car.first_raised_s - 2.0, 2.0) << what;
      EXPECT_NEAR(*car.first.turn_rad / kDeg, c.turn_deg, 3.0) << what;
      EXPECT_FALSE(car.first.only_backwards) << what;
      EXPECT_EQ(car.raised, 1) << what;  // once for the episode, which does not clear
      EXPECT_EQ(car.cleared, 0) << what;
    }
  }
}

TEST(MountingCheck, ATagTurned180DegreesLooksLikeACarOnlyEverReversingAndRaises) {
  Car car(Turned(180.0), Turned(0.0), 3);
  car.Stand(1.0);
  car.Run(Drive(0.2, 1.2), 8.0);
  ASSERT_TRUE(car.first_raised_s.has_value());
  EXPECT_LE(*car.first_raised_s - 1.0, 2.0);
  ASSERT_TRUE(car.first.turn_rad.has_value());
  EXPECT_NEAR(std::abs(*car.first.turn_rad) / kDeg, 180.0, 3.0);
  EXPECT_TRUE(car.first.only_backwards);
  EXPECT_EQ(car.raised, 1);
}

TEST(MountingCheck, AnEpisodeClearsWhenTheMeasurementsAgreeAgainAndRaisesAgainAfter) {
  // A check fed by hand: refusals and a heading 90° off the motion, then agreement.
  MountingCheck check(Turned(0.0));
  int raised = 0, cleared = 0;
  double t = 0.0;
  const auto feed = [&](double seconds, double turn_rad, bool refused) {
    for (int i = 0; i < static_cast<int>(seconds * kRateHz); ++i, t += 1 / kRateHz) {
      const Eigen::Vector2d p(0.2 * t, 0.0);  // east at 0.2 m/s
      const auto r = check.Add(TimeFromSeconds(t), p, turn_rad, refused);
      raised += r == MountingCheck::Report::kRaised;
      cleared += r == MountingCheck::Report::kCleared;
    }
  };
  feed(3.0, 0.0, false);
  EXPECT_EQ(raised, 0);
  feed(2.0, kPi / 2, true);
  EXPECT_EQ(raised, 1);
  EXPECT_TRUE(check.raised());
  EXPECT_NEAR(*check.finding().turn_rad, kPi / 2, 1e-6);
  EXPECT_GE(check.finding().refused, MountingCheck::kRaiseRefused);
  feed(1.0, 0.0, false);  // agreeing, but not yet for kClearAfter
  EXPECT_EQ(cleared, 0);
  feed(2.0, 0.0, false);
  EXPECT_EQ(cleared, 1);
  EXPECT_FALSE(check.raised());
  feed(2.0, kPi / 2, true);
  EXPECT_EQ(raised, 2);
}

TEST(MountingCheck, RefusalsWithoutMotionRaiseAfterASecondWithoutAFigure) {
  MountingCheck check(Turned(0.0));
  std::optional<double> raised_at;
  for (int i = 0; i < 90; ++i) {
    const double t = i / kRateHz;
    if (check.Add(TimeFromSeconds(t), Eigen::Vector2d(1.0, 1.0), 0.0, true) ==
        MountingCheck::Report::kRaised) {
      raised_at = t;
    }
  }
  ASSERT_TRUE(raised_at.has_value());
  // The run of refusals starts at the 10th measurement; a second later it raises.
  EXPECT_NEAR(*raised_at, 9 / kRateHz + 1.0, 1.5 / kRateHz);
  EXPECT_FALSE(check.finding().turn_rad.has_value());
  EXPECT_NEAR(check.finding().refusing_for_s, 1.0, 1.5 / kRateHz);
}

TEST(DuplicateCheck, AnEpisodeIsRaisedOnceAndEndsAfterThreeSecondsWithoutASighting) {
  DuplicateCheck check;
  EXPECT_FALSE(check.active());
  EXPECT_TRUE(check.Seen(TimeFromSeconds(1.0)));
  EXPECT_FALSE(check.Seen(TimeFromSeconds(2.0)));  // the same episode
  EXPECT_TRUE(check.active());
  EXPECT_FALSE(check.Clears(TimeFromSeconds(4.9)));
  EXPECT_TRUE(check.Clears(TimeFromSeconds(5.0)));
  EXPECT_FALSE(check.active());
  EXPECT_FALSE(check.Clears(TimeFromSeconds(9.0)));
  EXPECT_TRUE(check.Seen(TimeFromSeconds(9.5)));  // a new episode
}

}  // namespace
}  // namespace autodrive::eye
