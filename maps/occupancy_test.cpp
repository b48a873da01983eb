#include "maps/occupancy.h"

#include <gtest/gtest.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>
#include <tuple>

#include "common/error.h"
#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/test_layouts.h"

namespace autodrive::maps {
namespace {

namespace fs = std::filesystem;

Layout MakeLayout(const std::vector<std::vector<std::string>>& rows) {
  return maps::MakeLayout("test", rows);
}

using test_layouts::FourWay;

Layout LoopOfCurves() {
  return MakeLayout({{"curve", "straight", "curve@270"},
                     {"straight@90", "empty", "straight@90"},
                     {"curve@90", "straight", "curve@180"}});
}

// A straight road with two construction boxes on it and a box on the ground beside it.
Layout WithObstacles() {
  Layout l = MakeLayout({{"empty", "empty", "empty"}, {"straight", "straight", "straight"}});
  l.obstacles = {{"box", 0.5, 0.42, 0.0, 0.2, 0.1, 0.2},
                 {"box", 1.6, 0.55, 0.7, 0.15, 0.15, 0.2},
                 {"box", 2.5, 1.5, 0.0, 0.3, 0.3, 0.2}};
  return l;
}

double ShoelaceArea(const Polyline& ring) {
  double twice = 0.0;
  for (std::size_t i = 0; i < ring.size(); ++i) {
    const Eigen::Vector2d& a = ring[i];
    const Eigen::Vector2d& b = ring[(i + 1) % ring.size()];
    twice += a.x() * b.y() - b.x() * a.y();
  }
  return std::abs(twice) / 2;
}

double Area(const std::vector<Region>& regions) {
  double area = 0.0;
  for (const auto& r : regions) {
    area += ShoelaceArea(r.outer);
    for (const auto& h : r.holes) area -= ShoelaceArea(h);
  }
  return area;
}

// Even-odd point-in-polygon over every ring, the reference the scanline fill must agree with.
bool InsideRegions(const std::vector<Region>& regions, const Eigen::Vector2d& p) {
  bool inside = false;
  const auto ring_test = [&](const Polyline& ring) {
    for (std::size_t i = 0, j = ring.size() - 1; i < ring.size(); j = i++) {
      const Eigen::Vector2d& a = ring[i];
      const Eigen::Vector2d& b = ring[j];
      if ((a.y() > p.y()) != (b.y() > p.y()) &&
          p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) {
        inside = !inside;
      }
    }
  };
  for (const auto& r : regions) {
    ring_test(r.outer);
    for (const auto& h : r.holes) ring_test(h);
  }
  return inside;
}

// The distance from p to the nearest edge of any ring.
double DistanceToEdges(const std::vector<Region>& regions, const Eigen::Vector2d& p) {
  double best = std::numeric_limits<double>::infinity();
  const auto ring_test = [&](const Polyline& ring) {
    for (std::size_t i = 0; i < ring.size(); ++i) {
      const Eigen::Vector2d& a = ring[i];
      const Eigen::Vector2d& b = ring[(i + 1) % ring.size()];
      const Eigen::Vector2d ab = b - a;
      const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-300), 0.0, 1.0);
      const Eigen::Vector2d closest = a + t * ab;
      best = std::min(best, (p - closest).norm());
    }
  };
  for (const auto& r : regions) {
    ring_test(r.outer);
    for (const auto& h : r.holes) ring_test(h);
  }
  return best;
}

// The reference for "an obstacle touches a cell", independent of the rasteriser: the
// separating axis test of a convex polygon against the cell's square (axes x, y and the
// polygon's edge normals). Returns the largest gap along any axis (m): positive when they are
// apart by at least that much, zero when they only touch, minus the overlap depth when they
// overlap.
double SeparationFromCell(const Polyline& convex, const Eigen::Vector2d& lo,
                          const Eigen::Vector2d& hi) {
  const Eigen::Vector2d box[4] = {lo, {hi.x(), lo.y()}, hi, {lo.x(), hi.y()}};
  std::vector<Eigen::Vector2d> axes = {{1, 0}, {0, 1}};
  for (std::size_t i = 0; i < convex.size(); ++i) {
    const Eigen::Vector2d edge = convex[(i + 1) % convex.size()] - convex[i];
    if (edge.norm() > 0) axes.push_back(Eigen::Vector2d(-edge.y(), edge.x()).normalized());
  }
  double gap = -std::numeric_limits<double>::infinity();
  for (const Eigen::Vector2d& n : axes) {
    double p_lo = std::numeric_limits<double>::infinity();
    double p_hi = -p_lo;
    for (const auto& v : convex) {
      p_lo = std::min(p_lo, n.dot(v));
      p_hi = std::max(p_hi, n.dot(v));
    }
    double b_lo = std::numeric_limits<double>::infinity();
    double b_hi = -b_lo;
    for (const auto& v : box) {
      b_lo = std::min(b_lo, n.dot(v));
      b_hi = std::max(b_hi, n.dot(v));
    }
    gap = std::max(gap, std::max(p_lo - b_hi, b_lo - p_hi));
  }
  return gap;
}

// Whether obstacles touch cell (c, r) of `grid` by the reference: +1 when one overlaps it by
// more than 10^-5 of a cell, -1 when none comes within contact of it, 0 when it is too close
// to call (an obstacle's edge within rounding of the cell's edge): such cells are skipped.
int ReferenceTouch(const std::vector<Obstacle>& obstacles, const OccupancyGrid& grid, int c,
                   int r) {
  const Eigen::Vector2d lo = grid.origin_m + Eigen::Vector2d(c, r) * grid.resolution_m;
  const Eigen::Vector2d hi = lo + Eigen::Vector2d::Constant(grid.resolution_m);
  int verdict = -1;
  for (const Obstacle& o : obstacles) {
    const double gap = SeparationFromCell(o.footprint, lo, hi);
    if (gap < -1e-5 * grid.resolution_m) return 1;
    if (gap <= 1e-9 * grid.resolution_m) verdict = 0;
  }
  return verdict;
}

// The cells (col, row) of `grid` whose open square meets the open interval box
// (x_lo, x_hi) x (y_lo, y_hi), from their indices alone.
std::vector<std::pair<int, int>> CellsOverlapping(const OccupancyGrid& grid, double x_lo,
                                                  double x_hi, double y_lo, double y_hi) {
  std::vector<std::pair<int, int>> out;
  const double res = grid.resolution_m;
  for (int r = 0; r < grid.height; ++r) {
    for (int c = 0; c < grid.width; ++c) {
      if (c * res < x_hi && (c + 1) * res > x_lo && r * res < y_hi && (r + 1) * res > y_lo) {
        out.emplace_back(c, r);
      }
    }
  }
  return out;
}

// One open 1 x 1 m tile (drivable floor without lanes), with `obstacles`.
Map OpenTileWith(const std::vector<ObstacleSpec>& obstacles) {
  Layout l = MakeLayout({{"open"}});
  l.obstacles = obstacles;
  return Build(l);
}

fs::path TempDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() /
                       ("autodrive_occupancy_test_" + name + "_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

// The free area is the drivable area, within 2%, less (with obstacles) the ring of cells
// that an obstacle touches without covering their centre: at most the obstacle's outline
// widened by a cell, sqrt(2) * perimeter * res + 4 res^2 (the footprint grown by a cell's
// square, less the footprint).
TEST(OccupancyGrid, FreeAreaEqualsTheDrivableAreaLessTheCellsObstaclesTouch) {
  for (const auto& [name, layout] :
       std::vector<std::pair<std::string, Layout>>{{"four_way", FourWay()},
                                                   {"loop_of_curves", LoopOfCurves()},
                                                   {"with_obstacles", WithObstacles()}}) {
    SCOPED_TRACE(name);
    const Map map = Build(layout);
    const double drivable = Area(map.drivable);
    ASSERT_GT(drivable, 1.0);
    for (double res : {0.05, 0.02}) {
      const OccupancyGrid grid = MakeOccupancyGrid(map, res);
      EXPECT_EQ(grid.width, static_cast<int>(std::lround(map.size_m().x() / res)));
      EXPECT_EQ(grid.height, static_cast<int>(std::lround(map.size_m().y() / res)));
      const double free_area = static_cast<double>(grid.FreeCount()) * res * res;
      double ring = 0.0;
      for (const Obstacle& o : map.obstacles) {
        double perimeter = 0.0;
        for (std::size_t i = 0; i < o.footprint.size(); ++i) {
          perimeter += (o.footprint[(i + 1) % o.footprint.size()] - o.footprint[i]).norm();
        }
        ring += std::sqrt(2.0) * perimeter * res + 4 * res * res;
      }
      EXPECT_LE(free_area, drivable * 1.02) << "resolution " << res;
      EXPECT_GE(free_area, (drivable - ring) * 0.98) << "resolution " << res;
      if (map.obstacles.empty()) {
        EXPECT_NEAR(free_area / drivable, 1.0, 0.02) << "resolution " << res;
      }
    }
  }
}

// Road-only: a cell is free exactly when its centre is on the drivable area (point in
// polygon) and no obstacle touches it (the separating axis test).
TEST(OccupancyGrid, FreeCellsHaveTheirCentreOnTheRoadAndNoObstacleTouchingThem) {
  for (const Layout& layout : {FourWay(), LoopOfCurves(), WithObstacles()}) {
    const Map map = Build(layout);
    const OccupancyGrid grid = MakeOccupancyGrid(map, 0.05);
    int checked = 0;
    int touched = 0;
    for (int r = 0; r < grid.height; ++r) {
      for (int c = 0; c < grid.width; ++c) {
        const Eigen::Vector2d p = grid.CellCentre(c, r);
        if (DistanceToEdges(map.drivable, p) < 1e-9) continue;  // on an edge: either is right
        const int touch = ReferenceTouch(map.obstacles, grid, c, r);
        if (touch == 0) continue;
        touched += touch > 0 ? 1 : 0;
        ASSERT_EQ(grid.IsFree(c, r), touch < 0 && InsideRegions(map.drivable, p))
            << "cell (" << c << ", " << r << ") at " << p.transpose();
        ++checked;
      }
    }
    EXPECT_GT(checked, grid.width * grid.height * 9 / 10);
    EXPECT_EQ(touched > 0, !map.obstacles.empty());
  }
}

TEST(OccupancyGrid, RandomResolutionsAndOffsetsAgreeWithPointInPolygon) {
  // A fixed seed; AUTODRIVE_SOAK_FACTOR raises the number of cases.
  std::mt19937 rng(20240611);
  std::uniform_real_distribution<double> resolution(0.013, 0.11);
  const Map map = Build(LoopOfCurves());
  const int cases = 5 * test::SoakFactor();
  for (int k = 0; k < cases; ++k) {
    const double res = resolution(rng);
    const OccupancyGrid grid = MakeOccupancyGrid(map, res);
    for (int r = 0; r < grid.height; ++r) {
      for (int c = 0; c < grid.width; ++c) {
        const Eigen::Vector2d p = grid.CellCentre(c, r);
        if (DistanceToEdges(map.drivable, p) < 1e-9) continue;
        ASSERT_EQ(grid.IsFree(c, r), InsideRegions(map.drivable, p))
            << "resolution " << res << ", cell (" << c << ", " << r << ")";
      }
    }
  }
}

TEST(OccupancyGrid, ObstacleCellsAreOccupiedAndTheGroundIsFreeWhenNotRoadOnly) {
  const Map map = Build(WithObstacles());
  ASSERT_EQ(map.obstacles.size(), 3u);
  const OccupancyGrid road = MakeOccupancyGrid(map, 0.02, true);
  const OccupancyGrid all = MakeOccupancyGrid(map, 0.02, false);
  for (const Obstacle& o : map.obstacles) {
    Polyline ring = o.footprint;
    int inside = 0;
    for (int r = 0; r < road.height; ++r) {
      for (int c = 0; c < road.width; ++c) {
        if (!InsideRegions({Region{ring, {}}}, road.CellCentre(c, r))) continue;
        ++inside;
        EXPECT_FALSE(road.IsFree(c, r));
        EXPECT_FALSE(all.IsFree(c, r));
      }
    }
    EXPECT_GT(inside, 20);
  }
  // The first box sits on the road: the road cells beside it are free.
  EXPECT_TRUE(road.IsFree(static_cast<int>(0.5 / 0.02), static_cast<int>(0.7 / 0.02)));
  EXPECT_FALSE(road.IsFree(static_cast<int>(0.5 / 0.02), static_cast<int>(0.42 / 0.02)));
  // Off the road: occupied in a road-only grid, free otherwise (but for the third box).
  EXPECT_FALSE(road.IsFree(static_cast<int>(1.5 / 0.02), static_cast<int>(1.5 / 0.02)));
  EXPECT_TRUE(all.IsFree(static_cast<int>(1.5 / 0.02), static_cast<int>(1.5 / 0.02)));
  EXPECT_FALSE(all.IsFree(static_cast<int>(2.5 / 0.02), static_cast<int>(1.5 / 0.02)));
  // Only the obstacles are occupied without road_only: the cells they touch, no others.
  double obstacle_area = 0.0;
  for (const Obstacle& o : map.obstacles) obstacle_area += ShoelaceArea(o.footprint);
  const double occupied = static_cast<double>(all.cells.size() - all.FreeCount()) * 0.02 * 0.02;
  EXPECT_GE(occupied, obstacle_area);
  for (int r = 0; r < all.height; ++r) {
    for (int c = 0; c < all.width; ++c) {
      const int touch = ReferenceTouch(map.obstacles, all, c, r);
      if (touch != 0) {
        ASSERT_EQ(all.IsFree(c, r), touch < 0) << "cell (" << c << ", " << r << ")";
      }
    }
  }
}

// The issue: the Parking School's bay dividers (walls 0.03 m thick, centred on a cell edge,
// so between two rows of cell centres) vanished at 0.05 m and a planner drove through them.
TEST(OccupancyGrid, TheParkingSchoolsBayDividersAreOccupiedAlongTheirWholeLength) {
  const Map map =
      Build(LoadLayout((test::SourceDir() / "config" / "maps" / "parking_school.yaml").string()));
  const double res = 0.05;
  for (bool road_only : {true, false}) {
    SCOPED_TRACE(road_only ? "road only" : "obstacles only");
    const OccupancyGrid grid = MakeOccupancyGrid(map, res, road_only);
    int dividers = 0;
    for (const ObstacleSpec& wall : map.layout.obstacles) {
      if (wall.kind != "wall" || wall.width_m >= res) continue;
      ++dividers;
      ASSERT_EQ(wall.yaw_rad, 0.0);  // along x
      const double x_lo = wall.x_m - wall.length_m / 2;
      const double x_hi = wall.x_m + wall.length_m / 2;
      const double y_lo = wall.y_m - wall.width_m / 2;
      const double y_hi = wall.y_m + wall.width_m / 2;
      const auto cells = CellsOverlapping(grid, x_lo, x_hi, y_lo, y_hi);
      // 0.7 m long across a cell edge: two rows of 14 cells, no cell centre inside it.
      EXPECT_EQ(cells.size(), 28u);
      for (const auto& [c, r] : cells) {
        const double cy = grid.CellCentre(c, r).y();
        EXPECT_TRUE(cy < y_lo || cy > y_hi);
        EXPECT_FALSE(grid.IsFree(c, r))
            << "cell (" << c << ", " << r << ") of the divider at y " << wall.y_m;
      }
      // The floor beside it stays free: the rows below and above (35 mm away) and the cells
      // west of its end, which it only meets along their edge (x 3.25 m).
      const int col_west = static_cast<int>(std::lround(x_lo / res)) - 1;
      const int row_lo = static_cast<int>(std::floor(y_lo / res));
      for (int c = col_west + 1; c < static_cast<int>(std::lround(x_hi / res)); ++c) {
        EXPECT_TRUE(grid.IsFree(c, row_lo - 1)) << "col " << c;
        EXPECT_TRUE(grid.IsFree(c, row_lo + 2)) << "col " << c;
      }
      EXPECT_TRUE(grid.IsFree(col_west, row_lo));
      EXPECT_TRUE(grid.IsFree(col_west, row_lo + 1));
    }
    EXPECT_EQ(dividers, 2);
  }
}

// A box whose sides lie on cell edges (the Parking School's 0.3 m boxes at 0.05 m) occupies
// its own 6 x 6 cells and not the ring of cells it only meets along their edges.
TEST(OccupancyGrid, ABoxWhoseSidesLieOnCellEdgesOccupiesOnlyItsOwnCells) {
  const Map map = OpenTileWith({{"box", 0.5, 0.5, 0.0, 0.3, 0.3, 0.3}});
  for (bool road_only : {true, false}) {
    const OccupancyGrid grid = MakeOccupancyGrid(map, 0.05, road_only);
    EXPECT_EQ(grid.FreeCount(), 400u - 36u);
    for (int r = 7; r < 13; ++r) {
      for (int c = 7; c < 13; ++c) EXPECT_FALSE(grid.IsFree(c, r));
    }
  }
}

// A wall thinner than a cell that lies between two rows of cell centres, within one row or
// across a row's edge, occupies every cell along it.
TEST(OccupancyGrid, AWallThinnerThanACellBetweenCellCentresIsOccupied) {
  // Within row 10 ([0.50, 0.55], centre 0.525): y in [0.53, 0.545]. Across the edge between
  // rows 10 and 11 (centres 0.525, 0.575): y in [0.53, 0.565].
  for (const auto& [y_lo, y_hi, rows] : std::vector<std::tuple<double, double, std::vector<int>>>{
           {0.53, 0.545, {10}}, {0.53, 0.565, {10, 11}}}) {
    SCOPED_TRACE(y_hi);
    // From x 0.2 to 0.8: columns 4 to 15.
    const Map map = OpenTileWith({{"wall", 0.5, (y_lo + y_hi) / 2, 0.0, 0.6, y_hi - y_lo, 0.15}});
    for (bool road_only : {true, false}) {
      const OccupancyGrid grid = MakeOccupancyGrid(map, 0.05, road_only);
      for (int r : rows) {
        for (int c = 4; c < 16; ++c) EXPECT_FALSE(grid.IsFree(c, r)) << c << ", " << r;
      }
      EXPECT_EQ(grid.FreeCount(), 400u - 12u * rows.size());
    }
  }
  // A thin wall at a slant: every cell it crosses, by the separating axis test.
  const Map map = OpenTileWith({{"wall", 0.5, 0.5, 0.3, 0.7, 0.01, 0.15}});
  const OccupancyGrid grid = MakeOccupancyGrid(map, 0.05, false);
  int touched = 0;
  for (int r = 0; r < grid.height; ++r) {
    for (int c = 0; c < grid.width; ++c) {
      const int touch = ReferenceTouch(map.obstacles, grid, c, r);
      touched += touch > 0 ? 1 : 0;
      if (touch != 0) {
        EXPECT_EQ(grid.IsFree(c, r), touch < 0) << c << ", " << r;
      }
    }
  }
  EXPECT_GT(touched, 14);  // at least its length in cells along x: 0.7 cos 0.3 / 0.05
}

// An obstacle smaller than a cell, inside one cell and clear of its centre, occupies it.
TEST(OccupancyGrid, AnObstacleSmallerThanACellOccupiesTheCellItIsIn) {
  // Cell (10, 10) covers [0.50, 0.55]^2, centre (0.525, 0.525); the box [0.53, 0.54] x
  // [0.51, 0.52].
  const Map map = OpenTileWith({{"box", 0.535, 0.515, 0.0, 0.01, 0.01, 0.1}});
  for (bool road_only : {true, false}) {
    const OccupancyGrid grid = MakeOccupancyGrid(map, 0.05, road_only);
    EXPECT_FALSE(grid.IsFree(10, 10));
    EXPECT_EQ(grid.FreeCount(), 399u);
  }
  // A box the size of a cell centred on a cell corner occupies the four cells around it.
  const Map corner = OpenTileWith({{"box", 0.5, 0.5, 0.0, 0.05, 0.05, 0.1}});
  const OccupancyGrid grid = MakeOccupancyGrid(corner, 0.05, false);
  EXPECT_EQ(grid.FreeCount(), 396u);
  for (const auto& [c, r] : {std::pair{9, 9}, {10, 9}, {9, 10}, {10, 10}}) {
    EXPECT_FALSE(grid.IsFree(c, r));
  }
}

// No dilation: cells whose edge or corner is 1 mm from an obstacle stay free.
TEST(OccupancyGrid, CellsAMillimetreFromAnObstacleStayFree) {
  // A wall from x 0.2 to 0.749 (1 mm short of column 15's west edge) and from y 0.551 to
  // 0.58 (1 mm above row 10's north edge): columns 4 to 14 of row 11.
  const Map wall = OpenTileWith({{"wall", 0.4745, 0.5655, 0.0, 0.549, 0.029, 0.15}});
  // A square turned 45 degrees whose south corner is 1 mm above the middle of cell (10, 10)'s
  // north edge, (0.525, 0.551): it reaches down into row 11 only.
  const double half_diagonal = 0.02 / std::sqrt(2.0);
  const Map diamond =
      OpenTileWith({{"box", 0.525, 0.551 + half_diagonal, kPi / 4, 0.02, 0.02, 0.1}});
  for (bool road_only : {true, false}) {
    SCOPED_TRACE(road_only);
    const OccupancyGrid g = MakeOccupancyGrid(wall, 0.05, road_only);
    for (int c = 4; c < 15; ++c) {
      EXPECT_FALSE(g.IsFree(c, 11)) << c;
      EXPECT_TRUE(g.IsFree(c, 10)) << c;
      EXPECT_TRUE(g.IsFree(c, 12)) << c;
    }
    EXPECT_TRUE(g.IsFree(15, 11));
    EXPECT_TRUE(g.IsFree(3, 11));
    EXPECT_EQ(g.FreeCount(), 400u - 11u);

    const OccupancyGrid d = MakeOccupancyGrid(diamond, 0.05, road_only);
    EXPECT_FALSE(d.IsFree(10, 11));
    EXPECT_TRUE(d.IsFree(10, 10));
    EXPECT_EQ(d.FreeCount(), 399u);
  }
}

// Random boxes and walls, thin, tiny and turned, at random resolutions: a cell is occupied
// exactly when the separating axis test says an obstacle overlaps it (cells within rounding
// of contact are skipped, and must be rare). A fixed seed; AUTODRIVE_SOAK_FACTOR raises the
// number of cases.
TEST(OccupancyGrid, RandomObstaclesOccupyExactlyTheCellsTheyTouch) {
  std::mt19937 rng(20261126);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const int cases = 20 * test::SoakFactor();
  long checked = 0;
  long skipped = 0;
  long touched = 0;
  for (int k = 0; k < cases; ++k) {
    Map map;
    map.name = "random";
    map.rows = 2;
    map.cols = 3;
    for (int i = 0; i < 30; ++i) {
      const Eigen::Vector2d centre(0.1 + 2.8 * unit(rng), 0.1 + 1.8 * unit(rng));
      // Half of them thinner than any cell; a tenth of them axis-aligned.
      const double length = 0.002 + 0.3 * unit(rng);
      const double width = i % 2 == 0 ? 0.001 + 0.01 * unit(rng) : 0.002 + 0.2 * unit(rng);
      const double yaw = i % 10 == 0 ? 0.0 : 2 * kPi * unit(rng);
      const Eigen::Vector2d u(std::cos(yaw), std::sin(yaw));
      const Eigen::Vector2d v(-u.y(), u.x());
      Obstacle o;
      o.kind = "box";
      o.footprint = {
          centre - u * length / 2 - v * width / 2, centre + u * length / 2 - v * width / 2,
          centre + u * length / 2 + v * width / 2, centre - u * length / 2 + v * width / 2};
      map.obstacles.push_back(std::move(o));
    }
    const double res = 0.013 + 0.1 * unit(rng);
    const OccupancyGrid grid = MakeOccupancyGrid(map, res, false);
    for (int r = 0; r < grid.height; ++r) {
      for (int c = 0; c < grid.width; ++c) {
        const int touch = ReferenceTouch(map.obstacles, grid, c, r);
        if (touch == 0) {
          ++skipped;
          continue;
        }
        ++checked;
        touched += touch > 0 ? 1 : 0;
        ASSERT_EQ(grid.IsFree(c, r), touch < 0)
            << "case " << k << ", resolution " << res << ", cell (" << c << ", " << r << ")";
      }
    }
  }
  EXPECT_GT(checked, 1000L * cases);
  EXPECT_GT(touched, 100L * cases);
  EXPECT_LT(skipped * 1000, checked);
}

TEST(OccupancyGrid, ARoadInTheNorthRowShowsInTheTopRowsOfThePgm) {
  const Map map = Build(MakeLayout({{"straight"}, {"empty"}}));
  const OccupancyGrid grid = MakeOccupancyGrid(map, 0.05);
  ASSERT_EQ(grid.width, 20);
  ASSERT_EQ(grid.height, 40);
  // In the grid (row 0 south), the road is in rows 20..39.
  EXPECT_TRUE(grid.IsFree(10, 30));
  EXPECT_FALSE(grid.IsFree(10, 10));

  const fs::path dir = TempDir("north");
  WriteOccupancyGrid(grid, (dir / "map.pgm").string(), (dir / "map.yaml").string());
  std::ifstream in(dir / "map.pgm", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t data = bytes.size() - 20u * 40u;
  int free_top = 0;
  int free_bottom = 0;
  for (std::size_t row = 0; row < 40; ++row) {
    for (std::size_t col = 0; col < 20; ++col) {
      const bool is_free = static_cast<unsigned char>(bytes[data + row * 20 + col]) == 254;
      (row < 20 ? free_top : free_bottom) += is_free ? 1 : 0;
    }
  }
  EXPECT_GT(free_top, 20 * 8);  // a 0.6 m road across a 1 m tile: 12 of 20 rows
  EXPECT_EQ(free_bottom, 0);
  fs::remove_all(dir);
}

// Reads a binary PGM as map_server does, returning (width, height, maxval, pixels).
struct Pgm {
  int width = 0;
  int height = 0;
  int maxval = 0;
  std::vector<std::uint8_t> pixels;
};

Pgm ReadPgm(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::size_t pos = 0;
  // Header tokens separated by whitespace; '#' comments run to the end of the line.
  const auto token = [&]() {
    while (pos < bytes.size()) {
      if (bytes[pos] == '#') {
        while (pos < bytes.size() && bytes[pos] != '\n') ++pos;
      } else if (std::isspace(static_cast<unsigned char>(bytes[pos])) != 0) {
        ++pos;
      } else {
        break;
      }
    }
    const std::size_t start = pos;
    while (pos < bytes.size() && std::isspace(static_cast<unsigned char>(bytes[pos])) == 0) ++pos;
    return bytes.substr(start, pos - start);
  };
  Pgm pgm;
  EXPECT_EQ(token(), "P5");
  pgm.width = std::stoi(token());
  pgm.height = std::stoi(token());
  pgm.maxval = std::stoi(token());
  ++pos;  // the single whitespace character before the data
  pgm.pixels.assign(bytes.begin() + static_cast<std::ptrdiff_t>(pos), bytes.end());
  return pgm;
}

TEST(OccupancyGrid, WrittenFilesReadBackToTheSameGrid) {
  const Map map = Build(WithObstacles());
  const OccupancyGrid grid = MakeOccupancyGrid(map, 0.05);
  const fs::path dir = TempDir("roundtrip");
  fs::create_directories(dir / "maps");
  WriteOccupancyGrid(grid, (dir / "maps" / "city.pgm").string(), (dir / "city.yaml").string());

  const YAML::Node yaml = YAML::LoadFile((dir / "city.yaml").string());
  EXPECT_EQ(yaml.size(), 7u);
  EXPECT_EQ(yaml["image"].as<std::string>(), "maps/city.pgm");
  EXPECT_EQ(yaml["resolution"].as<double>(), 0.05);
  ASSERT_EQ(yaml["origin"].size(), 3u);
  EXPECT_EQ(yaml["origin"][0].as<double>(), 0.0);
  EXPECT_EQ(yaml["origin"][1].as<double>(), 0.0);
  EXPECT_EQ(yaml["origin"][2].as<double>(), 0.0);
  EXPECT_EQ(yaml["negate"].as<int>(), 0);
  EXPECT_EQ(yaml["occupied_thresh"].as<double>(), 0.65);
  EXPECT_EQ(yaml["free_thresh"].as<double>(), 0.196);
  EXPECT_EQ(yaml["mode"].as<std::string>(), "trinary");

  const Pgm pgm = ReadPgm(dir / yaml["image"].as<std::string>());
  EXPECT_EQ(pgm.maxval, 255);
  ASSERT_EQ(pgm.width, grid.width);
  ASSERT_EQ(pgm.height, grid.height);
  ASSERT_EQ(pgm.pixels.size(), grid.cells.size());

  // Interpret the image as map_server does (trinary, negate 0) and rebuild the grid.
  OccupancyGrid back;
  back.resolution_m = yaml["resolution"].as<double>();
  back.origin_m = {yaml["origin"][0].as<double>(), yaml["origin"][1].as<double>()};
  back.width = pgm.width;
  back.height = pgm.height;
  back.cells.resize(pgm.pixels.size());
  for (int row = 0; row < pgm.height; ++row) {
    for (int col = 0; col < pgm.width; ++col) {
      const std::uint8_t value = pgm.pixels[static_cast<std::size_t>(row * pgm.width + col)];
      const double occ = (255.0 - value) / 255.0;
      ASSERT_TRUE(occ > 0.65 || occ < 0.196) << "an unknown cell: " << int{value};
      back.cells[static_cast<std::size_t>((pgm.height - 1 - row) * pgm.width + col)] =
          occ > 0.65 ? OccupancyGrid::kOccupied : OccupancyGrid::kFree;
    }
  }
  EXPECT_EQ(back, grid);
  fs::remove_all(dir);
}

TEST(OccupancyGrid, ImagePathInTheYamlIsRelativeToTheYamlsDirectory) {
  const Map map = Build(MakeLayout({{"straight"}}));
  const OccupancyGrid grid = MakeOccupancyGrid(map, 0.1);
  const fs::path dir = TempDir("relative");
  fs::create_directories(dir / "yaml");
  fs::create_directories(dir / "img");
  WriteOccupancyGrid(grid, (dir / "img" / "a b.pgm").string(), (dir / "yaml" / "m.yaml").string());
  const YAML::Node yaml = YAML::LoadFile((dir / "yaml" / "m.yaml").string());
  EXPECT_EQ(yaml["image"].as<std::string>(), "../img/a b.pgm");
  EXPECT_TRUE(fs::exists(dir / "yaml" / yaml["image"].as<std::string>()));
  fs::remove_all(dir);
}

TEST(OccupancyGrid, BadResolutionsAndUnwritablePathsThrow) {
  const Map map = Build(MakeLayout({{"straight"}}));
  EXPECT_EQ(test::ErrorMessage([&] { (void)MakeOccupancyGrid(map, 0.0); }),
            "the occupancy grid resolution must be a finite number > 0 m, got 0");
  EXPECT_EQ(test::ErrorMessage([&] { (void)MakeOccupancyGrid(map, -0.05); }),
            "the occupancy grid resolution must be a finite number > 0 m, got -0.05");
  EXPECT_EQ(test::ErrorMessage([&] { (void)MakeOccupancyGrid(map, std::nan("")); }),
            "the occupancy grid resolution must be a finite number > 0 m, got nan");
  EXPECT_EQ(test::ErrorMessage([&] { (void)MakeOccupancyGrid(map, 1e-5); }),
            "the occupancy grid resolution 1e-05 m is too fine for a 1 x 1 m map: 100000 x "
            "100000 cells, more than 100 million");

  const OccupancyGrid grid = MakeOccupancyGrid(map, 0.05);
  const fs::path dir = TempDir("unwritable");
  const std::string missing = (dir / "no_such_dir" / "map.pgm").string();
  EXPECT_EQ(
      test::ErrorMessage([&] { WriteOccupancyGrid(grid, missing, (dir / "map.yaml").string()); }),
      "cannot write the occupancy grid image \"" + missing + "\": No such file or directory");
  const std::string missing_yaml = (dir / "no_such_dir" / "map.yaml").string();
  EXPECT_EQ(
      test::ErrorMessage(
          [&] { WriteOccupancyGrid(grid, (dir / "map.pgm").string(), missing_yaml); }),
      "cannot write the occupancy grid YAML \"" + missing_yaml + "\": No such file or directory");
  // A directory where the file should be.
  EXPECT_EQ(test::ErrorMessage(
                [&] { WriteOccupancyGrid(grid, dir.string(), (dir / "map.yaml").string()); }),
            "cannot write the occupancy grid image \"" + dir.string() + "\": Is a directory");
  fs::remove_all(dir);
}

// A synthetic 64 x 64-tile map (no builder: CGAL would dominate the time) with one
// 400-vertex annulus per tile: 3.3 million edges, 1.6 million cells at 0.05 m.
// A large map with many annuli (holes): the area stays right at scale. (Its time is a
// benchmark matter, not a test's: timings on a shared machine are noisy.)
TEST(OccupancyGrid, A64By64TileMapOfAnnuliRasterisesToTheirArea) {
  Map map;
  map.name = "big";
  map.rows = 64;
  map.cols = 64;
  double expected_area = 0.0;
  for (int r = 0; r < 64; ++r) {
    for (int c = 0; c < 64; ++c) {
      const Eigen::Vector2d centre(c + 0.5, r + 0.5);
      Region region;
      for (int k = 0; k < 400; ++k) {
        const double a = 2 * kPi * k / 400;
        region.outer.push_back(centre + 0.45 * Eigen::Vector2d(std::cos(a), std::sin(a)));
      }
      Polyline hole;
      for (int k = 399; k >= 0; --k) {
        const double a = 2 * kPi * k / 400;
        hole.push_back(centre + 0.15 * Eigen::Vector2d(std::cos(a), std::sin(a)));
      }
      region.holes.push_back(hole);
      expected_area += ShoelaceArea(region.outer) - ShoelaceArea(hole);
      map.drivable.push_back(std::move(region));
    }
  }
  const OccupancyGrid grid = MakeOccupancyGrid(map, 0.05);
  EXPECT_EQ(grid.width, 1280);
  EXPECT_EQ(grid.height, 1280);
  EXPECT_NEAR(static_cast<double>(grid.FreeCount()) * 0.0025 / expected_area, 1.0, 0.02);
}

}  // namespace
}  // namespace autodrive::maps
