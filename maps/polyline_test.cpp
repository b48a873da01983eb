#include "maps/polyline.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace autodrive::maps {
namespace {

// An L: 2 m east, then 1 m north (with a repeated point, which is skipped).
const Polyline kL = {{0, 0}, {2, 0}, {2, 0}, {2, 1}};

TEST(Polyline, TheNearestPointIsOnTheNearestSegmentWithItsArcLengthAndDirection) {
  const PolylinePoint a = NearestOnPolyline(kL, {1.0, -0.5});
  EXPECT_TRUE(a.point.isApprox(Eigen::Vector2d(1.0, 0.0)));
  EXPECT_DOUBLE_EQ(a.along_m, 1.0);
  EXPECT_DOUBLE_EQ(a.distance_m, 0.5);
  EXPECT_DOUBLE_EQ(a.direction_rad, 0.0);
  EXPECT_DOUBLE_EQ(a.length_m, 3.0);
  const PolylinePoint b = NearestOnPolyline(kL, {2.3, 0.6});
  EXPECT_TRUE(b.point.isApprox(Eigen::Vector2d(2.0, 0.6)));
  EXPECT_DOUBLE_EQ(b.along_m, 2.6);
  EXPECT_NEAR(b.distance_m, 0.3, 1e-12);
  EXPECT_DOUBLE_EQ(b.direction_rad, std::numbers::pi / 2);
  // Past the end: the end.
  const PolylinePoint c = NearestOnPolyline(kL, {2.0, 3.0});
  EXPECT_DOUBLE_EQ(c.along_m, 3.0);
  EXPECT_DOUBLE_EQ(c.distance_m, 2.0);
  EXPECT_TRUE(std::isinf(NearestOnPolyline({{1, 1}}, {0, 0}).distance_m));
}

TEST(Polyline, APointAlongIsClampedToTheEndsAndAgreesWithTheNearestPoint) {
  const auto [p, yaw] = PointAlong(kL, 2.5);
  EXPECT_TRUE(p.isApprox(Eigen::Vector2d(2.0, 0.5)));
  EXPECT_DOUBLE_EQ(yaw, std::numbers::pi / 2);
  EXPECT_TRUE(PointAlong(kL, -1.0).first.isApprox(Eigen::Vector2d(0.0, 0.0)));
  EXPECT_TRUE(PointAlong(kL, 9.0).first.isApprox(Eigen::Vector2d(2.0, 1.0)));
  EXPECT_DOUBLE_EQ(PolylineLength(kL), 3.0);
  for (double s = 0.0; s <= 3.0; s += 0.125) {
    const auto [q, direction] = PointAlong(kL, s);
    const PolylinePoint back = NearestOnPolyline(kL, q);
    EXPECT_NEAR(back.along_m, s, 1e-12) << s;
    EXPECT_NEAR(back.distance_m, 0.0, 1e-12) << s;
  }
}

}  // namespace
}  // namespace autodrive::maps
