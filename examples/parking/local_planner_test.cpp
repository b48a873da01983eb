// The parking agent's local planner on the Parking School's grid: which points of a scan are
// news, and whether they lie on the path ahead.
#include "examples/parking/local_planner.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/layout.h"

namespace autodrive::examples {
namespace {

maps::OccupancyGrid School() {
  return maps::MakeOccupancyGrid(
      maps::Build(
          maps::LoadLayout((test::SourceDir() / "config/maps/parking_school.yaml").string())),
      0.025, false);
}

constexpr double kLidarX = 0.1445;
constexpr float kNone = std::numeric_limits<float>::infinity();

// The beam's end point in the map frame for the car at X.
Eigen::Vector2d End(const RigidTransform2& X, int beam, double r) {
  const double a = 2 * std::numbers::pi * beam / 360.0;
  return X * Eigen::Vector2d(kLidarX + r * std::cos(a), r * std::sin(a));
}

TEST(LocalPlanner, NewsIsOffBothMapsAndInAClusterNotALoneReturn) {
  const maps::OccupancyGrid city = School();
  const RigidTransform2 X = RigidTransform2::FromXyYaw(0.6, 2.0, 0.0);
  std::vector<float> scan(360, kNone);
  // A box 0.5 m ahead on the open floor: 11 beams, 4 cm apart at most.
  for (int b = -5; b <= 5; ++b) scan[static_cast<std::size_t>((b + 360) % 360)] = 0.5f;
  // A lone return 0.7 m to the left, in the open: the LIDAR's noise.
  scan[90] = 0.7f;
  // Behind, the west wall: 5 beams ending on it, mapped.
  double wall = 0.2;
  while (Unmapped(city, End(X, 180, wall), 0.02) && wall < 1.0) wall += 0.005;
  ASSERT_LT(wall, 1.0) << "no wall behind the car";
  ASSERT_GT(End(X, 180, wall).x(), city.origin_m.x()) << "the wall's beam left the grid";
  for (int b = 178; b <= 182; ++b) scan[static_cast<std::size_t>(b)] = static_cast<float>(wall);

  const ObstacleParams params;
  std::vector<Eigen::Vector2d> news = NewObstacles(scan, X, kLidarX, city, nullptr, params);
  ASSERT_EQ(news.size(), 11U);
  for (const Eigen::Vector2d& q : news) EXPECT_NEAR(q.x(), 0.6 + kLidarX + 0.5, 0.01);
  // With the lone return in a cluster of 3, it is news too.
  scan[89] = scan[91] = 0.7f;
  EXPECT_EQ(NewObstacles(scan, X, kLidarX, city, nullptr, params).size(), 14U);
  // What its own map has (it saw the box standing at its fix) is not news.
  maps::OccupancyGrid own = city;
  for (int b = -5; b <= 5; ++b) {
    const Eigen::Vector2d q = End(X, (b + 360) % 360, 0.5);
    const auto c = static_cast<int>(std::floor((q.x() - own.origin_m.x()) / own.resolution_m));
    const auto r = static_cast<int>(std::floor((q.y() - own.origin_m.y()) / own.resolution_m));
    own.cells[static_cast<std::size_t>(r * own.width + c)] = maps::OccupancyGrid::kOccupied;
  }
  EXPECT_EQ(NewObstacles(scan, X, kLidarX, city, &own, params).size(), 3U);
  // Beyond range_m nothing is looked at.
  ObstacleParams short_sight = params;
  short_sight.range_m = 0.4;
  EXPECT_TRUE(NewObstacles(scan, X, kLidarX, city, nullptr, short_sight).empty());
}

TEST(LocalPlanner, InTheWayOnlyWithinTheBodyAlongThePathsNextMetres) {
  const HybridAStarParams body;  // Nigel: 0.318 x 0.175 m, its centre 7 cm ahead; 3 cm margin
  std::vector<PathPose> ahead;
  for (int k = 0; k <= 20; ++k) ahead.push_back({RigidTransform2::FromXyYaw(0.05 * k, 0, 0), 1});
  // The front bumper with its margin reaches 0.07 + 0.159 + 0.03 = 0.259 m ahead of a pose.
  const std::vector<Eigen::Vector2d> near{{0.6, 0.0}}, far{{0.75, 0.0}}, beside{{0.3, 0.2}};
  EXPECT_TRUE(InTheWay(near, ahead, body, 0.4));
  EXPECT_FALSE(InTheWay(far, ahead, body, 0.4));  // 0.4 m of path: up to 0.659 m
  EXPECT_TRUE(InTheWay(far, ahead, body, 0.6));
  EXPECT_FALSE(InTheWay(beside, ahead, body, 1.0));  // 0.2 m off the line: beyond 0.0875 + 0.03
  // Against its own body (not to be marked) within the clearance round it.
  const RigidTransform2 X = RigidTransform2::Identity();
  EXPECT_TRUE(AgainstBody({0.26, 0.0}, X, body, 0.06));
  EXPECT_FALSE(AgainstBody({0.32, 0.0}, X, body, 0.06));
}

}  // namespace
}  // namespace autodrive::examples
