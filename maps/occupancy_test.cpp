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

fs::path TempDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() /
                       ("autodrive_occupancy_test_" + name + "_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

TEST(OccupancyGrid, FreeAreaEqualsTheDrivableArea) {
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
      EXPECT_NEAR(free_area / drivable, 1.0, 0.02) << "resolution " << res;
    }
  }
}

TEST(OccupancyGrid, AgreesWithPointInPolygonAtEveryCellCentre) {
  for (const Layout& layout : {FourWay(), LoopOfCurves(), WithObstacles()}) {
    const Map map = Build(layout);
    const OccupancyGrid grid = MakeOccupancyGrid(map, 0.05);
    int checked = 0;
    for (int r = 0; r < grid.height; ++r) {
      for (int c = 0; c < grid.width; ++c) {
        const Eigen::Vector2d p = grid.CellCentre(c, r);
        if (DistanceToEdges(map.drivable, p) < 1e-9) continue;  // on an edge: either is right
        ASSERT_EQ(grid.IsFree(c, r), InsideRegions(map.drivable, p))
            << "cell (" << c << ", " << r << ") at " << p.transpose();
        ++checked;
      }
    }
    EXPECT_GT(checked, grid.width * grid.height * 9 / 10);
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
  // Only the obstacles are occupied without road_only: their total area, within 3%.
  double obstacle_area = 0.0;
  for (const Obstacle& o : map.obstacles) obstacle_area += ShoelaceArea(o.footprint);
  const double occupied = static_cast<double>(all.cells.size() - all.FreeCount()) * 0.02 * 0.02;
  EXPECT_NEAR(occupied / obstacle_area, 1.0, 0.03);
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
