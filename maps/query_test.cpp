// CGAL queries cross-checked against brute force on random points (fixed seed; raise the
// count with AUTODRIVE_SOAK_FACTOR).
#include "maps/query.h"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <random>

#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/grid_city.h"

namespace autodrive::maps {
namespace {

double SegmentDistance(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                       const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (a + t * ab - p).norm();
}

// Winding-number point-in-polygon; returns 0 outside, non-zero inside. Points on the boundary
// are excluded by the callers.
int Winding(const Polyline& ring, const Eigen::Vector2d& p) {
  int w = 0;
  for (std::size_t i = 0; i < ring.size(); ++i) {
    const Eigen::Vector2d& a = ring[i];
    const Eigen::Vector2d& b = ring[(i + 1) % ring.size()];
    const double cross = (b.x() - a.x()) * (p.y() - a.y()) - (p.x() - a.x()) * (b.y() - a.y());
    if (a.y() <= p.y()) {
      if (b.y() > p.y() && cross > 0) ++w;
    } else if (b.y() <= p.y() && cross < 0) {
      --w;
    }
  }
  return w;
}

double DistanceToRing(const Polyline& ring, const Eigen::Vector2d& p) {
  double d = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < ring.size(); ++i) {
    d = std::min(d, SegmentDistance(p, ring[i], ring[(i + 1) % ring.size()]));
  }
  return d;
}

void CrossCheck(const Map& map, std::uint32_t seed) {
  const MapIndex index(map);
  std::mt19937 rng(seed);
  const Eigen::Vector2d size = map.size_m();
  std::uniform_real_distribution<double> ux(-0.2, size.x() + 0.2), uy(-0.2, size.y() + 0.2);
  const int n = 2000 * test::SoakFactor();
  int drivable = 0, checked = 0;
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector2d p(ux(rng), uy(rng));
    // Nearest lane, brute force over every segment.
    double best = std::numeric_limits<double>::infinity();
    for (const auto& lane : map.lanes) {
      for (std::size_t i = 1; i < lane.centreline.size(); ++i) {
        best = std::min(best, SegmentDistance(p, lane.centreline[i - 1], lane.centreline[i]));
      }
    }
    const auto match = index.NearestLane(p);
    ASSERT_TRUE(match.has_value());
    ASSERT_NEAR(match->distance_m, best, 1e-9) << "at " << p.transpose();
    // The match's point is on its lane, and its arc length is consistent with it.
    const auto& c = map.lane(match->lane).centreline;
    double on_lane = std::numeric_limits<double>::infinity();
    for (std::size_t i = 1; i < c.size(); ++i)
      on_lane = std::min(on_lane, SegmentDistance(match->point, c[i - 1], c[i]));
    EXPECT_LT(on_lane, 1e-9);
    EXPECT_GE(match->along_m, 0.0);
    EXPECT_LE(match->along_m, map.lane(match->lane).length_m + 1e-9);

    // Drivable, brute force over every region (skip points within 1e-7 m of a boundary).
    bool inside = false, near_boundary = false;
    for (const auto& r : map.drivable) {
      near_boundary = near_boundary || DistanceToRing(r.outer, p) < 1e-7;
      bool in = Winding(r.outer, p) != 0;
      for (const auto& h : r.holes) {
        near_boundary = near_boundary || DistanceToRing(h, p) < 1e-7;
        if (Winding(h, p) != 0) in = false;
      }
      inside = inside || in;
    }
    if (near_boundary) continue;
    ++checked;
    drivable += inside;
    ASSERT_EQ(index.IsDrivable(p), inside) << "at " << p.transpose();
  }
  // The samples cover both answers.
  EXPECT_GT(drivable, checked / 20);
  EXPECT_LT(drivable, checked);
}

TEST(MapIndex, NearestLaneAndDrivableMatchBruteForceOnTheSmallTown) {
  CrossCheck(Build(LoadLayout((test::SourceDir() / "config/maps/small_town.yaml").string())), 7);
}

TEST(MapIndex, NearestLaneAndDrivableMatchBruteForceOnAGridCityWithObstacles) {
  Layout l = GridCity(2, 3, "mixed");
  l.obstacles = {{"box", 1.5, 1.35, 0.3, 0.2, 0.2, 0.2}, {"box", 3.5, 3.5, 0.0, 0.3, 0.3, 0.2}};
  CrossCheck(Build(l), 11);
}

// Nearest lane that runs a car's way, against brute force: random points and headings on the
// small town, 0.2 m at most, 60 degrees at most.
TEST(MapIndex, NearestLaneHeadingMatchesBruteForce) {
  const Map map = Build(LoadLayout((test::SourceDir() / "config/maps/small_town.yaml").string()));
  const MapIndex index(map);
  std::mt19937 rng(5);
  const Eigen::Vector2d size = map.size_m();
  std::uniform_real_distribution<double> ux(0, size.x()), uy(0, size.y()), uyaw(-M_PI, M_PI);
  constexpr double kMax = 0.2, kAngle = M_PI / 3;
  int found = 0, refused_for_heading = 0;
  for (int k = 0; k < 4000 * test::SoakFactor(); ++k) {
    const Eigen::Vector2d p(ux(rng), uy(rng));
    const double yaw = uyaw(rng);
    const Eigen::Vector2d heading(std::cos(yaw), std::sin(yaw));
    std::optional<std::pair<double, LaneId>> best;
    for (const auto& lane : map.lanes) {
      for (std::size_t i = 1; i < lane.centreline.size(); ++i) {
        const Eigen::Vector2d ab = lane.centreline[i] - lane.centreline[i - 1];
        if (ab.norm() <= 0 || ab.normalized().dot(heading) < std::cos(kAngle)) continue;
        const double d = SegmentDistance(p, lane.centreline[i - 1], lane.centreline[i]);
        if (d <= kMax && (!best || d < best->first)) best = {d, lane.id};
      }
    }
    const auto match = index.NearestLaneHeading(p, yaw, kMax, kAngle);
    ASSERT_EQ(match.has_value(), best.has_value()) << "at " << p.transpose() << ", " << yaw;
    if (!match) continue;
    ++found;
    ASSERT_NEAR(match->distance_m, best->first, 1e-9) << "at " << p.transpose();
    const auto any = index.NearestLane(p);
    if (any && any->distance_m < match->distance_m - 1e-9) ++refused_for_heading;
    const Lane& lane = map.lane(match->lane);
    EXPECT_GE(match->along_m, 0.0);
    EXPECT_LE(match->along_m, lane.length_m + 1e-9);
  }
  // Both cases are covered: a lane found, and a nearer lane that runs the other way passed over.
  EXPECT_GT(found, 200);
  EXPECT_GT(refused_for_heading, 50);
}

TEST(MapIndex, MaxDistanceAndEmptyMaps) {
  const Map map = Build(GridCity(1, 1));
  const MapIndex index(map);
  EXPECT_FALSE(index.NearestLane({-50, -50}, 1.0).has_value());
  EXPECT_TRUE(index.NearestLane({1.5, 1.35}, 1.0).has_value());
  Layout empty;
  empty.name = "empty";
  empty.grid = {{Cell{}}};
  const Map nothing = Build(empty);
  const MapIndex none(nothing);
  EXPECT_FALSE(none.NearestLane({0.5, 0.5}).has_value());
  EXPECT_FALSE(none.IsDrivable({0.5, 0.5}));
  EXPECT_FALSE(none.NearestLaneHeading({0.5, 0.5}, 0.0, 1.0, 1.0).has_value());
}

}  // namespace
}  // namespace autodrive::maps
