// Every shipped map (config/maps/*.yaml) builds, is fully connected, and round-trips through
// map.yaml; the grid-city generator, the mesh and the terrain work.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/grid_city.h"
#include "maps/lane_graph.h"
#include "maps/map_io.h"
#include "maps/mesh.h"
#include "maps/occupancy.h"
#include "maps/outputs.h"

namespace autodrive::maps {
namespace {

namespace fs = std::filesystem;

std::vector<fs::path> ShippedLayouts() {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(test::SourceDir() / "config" / "maps")) {
    if (e.path().extension() == ".yaml") out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

fs::path TempDir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("autodrive_maps_" + name + "_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

TEST(ShippedMaps, TheThreeLabMapsAreShipped) {
  std::set<std::string> names;
  for (const auto& p : ShippedLayouts()) names.insert(p.stem().string());
  for (const char* n : {"parking_school", "driving_school", "small_town"}) {
    EXPECT_TRUE(names.count(n)) << n;
  }
}

TEST(ShippedMaps, EveryShippedMapBuildsAndEveryLaneIsConnected) {
  for (const auto& path : ShippedLayouts()) {
    SCOPED_TRACE(path.string());
    const Map map = Build(LoadLayout(path.string()));
    EXPECT_EQ(CheckReachability(map), std::vector<std::string>{});
    for (const auto& m : map.movements) {
      EXPECT_EQ(m.path.front(), map.lane(m.from).centreline.back()) << m.name;
      EXPECT_EQ(m.path.back(), map.lane(m.to).centreline.front()) << m.name;
    }
    EXPECT_GT(Area(map.drivable), 0.0);
  }
}

TEST(ShippedMaps, TheyHoldWhatTheIssueAsks) {
  const auto dir = test::SourceDir() / "config" / "maps";
  const Map parking = Build(LoadLayout((dir / "parking_school.yaml").string()));
  EXPECT_TRUE(parking.lanes.empty());
  EXPECT_GE(parking.obstacles.size(), 5u + 4u);  // boxes and the four boundary walls
  // All free space is drivable: the floor minus the obstacles.
  double obstacle_area = 0;
  for (const auto& o : parking.obstacles) obstacle_area += Area({Region{o.footprint, {}}});
  EXPECT_NEAR(Area(parking.drivable), 16.0 - obstacle_area, 1e-6);

  const Map school = Build(LoadLayout((dir / "driving_school.yaml").string()));
  ASSERT_EQ(school.intersections.size(), 1u);
  EXPECT_EQ(school.intersections[0].control, Control::kSignal);
  EXPECT_EQ(school.intersections[0].approaches.size(), 4u);
  EXPECT_EQ(school.signal_heads.size(), 4u);

  const Map town = Build(LoadLayout((dir / "small_town.yaml").string()));
  EXPECT_GE(town.intersections.size(), 4u);
  int signal = 0, stop = 0, tees = 0;
  for (const auto& x : town.intersections) {
    signal += x.control == Control::kSignal;
    stop += x.control == Control::kStop;
    tees += x.approaches.size() == 3;
  }
  EXPECT_GE(signal, 1);
  EXPECT_GE(stop, 1);
  EXPECT_GE(tees, 1);
}

TEST(MapFile, SavedMapLoadsBackToTheSameMap) {
  const auto dir = TempDir("io");
  for (const auto& path : ShippedLayouts()) {
    SCOPED_TRACE(path.string());
    const Map map = Build(LoadLayout(path.string()));
    const std::string file = (dir / (path.stem().string() + ".map.yaml")).string();
    SaveMap(map, file);
    const Map back = LoadMap(file);
    EXPECT_TRUE(Summarise(back).Matches(Summarise(map)));
    ASSERT_EQ(back.lanes.size(), map.lanes.size());
    for (std::size_t i = 0; i < map.lanes.size(); ++i) {
      EXPECT_EQ(back.lanes[i].name, map.lanes[i].name);
    }
  }
  fs::remove_all(dir);
}

TEST(MapFile, AFileWhoseSummaryNoLongerMatchesIsRefused) {
  const auto dir = TempDir("stale");
  const Map map =
      Build(LoadLayout((test::SourceDir() / "config/maps/driving_school.yaml").string()));
  const std::string file = (dir / "map.yaml").string();
  SaveMap(map, file);
  // Pretend an older builder made one lane more.
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  std::string s = text.str();
  const std::string from = "lanes: " + std::to_string(map.lanes.size());
  ASSERT_NE(s.find(from), std::string::npos);
  s.replace(s.find(from), from.size(), "lanes: " + std::to_string(map.lanes.size() + 1));
  std::ofstream(file) << s;
  const std::string error = test::ErrorMessage([&] { (void)LoadMap(file); });
  EXPECT_NE(error.find("the map rebuilt from its layout differs from the one saved"),
            std::string::npos)
      << error;
  fs::remove_all(dir);
}

TEST(GridCity, BuildsTheRequestedIntersectionsAllConnected) {
  const Map map = Build(GridCity(3, 4, "mixed"));
  EXPECT_EQ(map.rows, 7);
  EXPECT_EQ(map.cols, 9);
  EXPECT_EQ(map.intersections.size(), 12u);
  EXPECT_EQ(CheckReachability(map), std::vector<std::string>{});
  int signal = 0;
  for (const auto& x : map.intersections) signal += x.control == Control::kSignal;
  EXPECT_EQ(signal, 6);
  EXPECT_EQ(test::ErrorMessage([] { (void)GridCity(0, 3); }),
            "a grid city has 1 to 200 rows and columns of intersections, got 0 x 3");
}

TEST(LaneGraph, RoutesThroughIntersections) {
  const Map map = Build(GridCity(2, 2, "signal"));
  // From the first lane to the last, a route exists and is a chain of next lanes.
  const LaneId from = map.lanes.front().id;
  for (const auto& target : map.lanes) {
    const auto route = Route(map, from, target.id);
    if (route.empty()) continue;
    EXPECT_EQ(route.front(), from);
    EXPECT_EQ(route.back(), target.id);
    for (std::size_t i = 1; i < route.size(); ++i) {
      const auto next = NextLanes(map, route[i - 1]);
      EXPECT_NE(std::find(next.begin(), next.end(), route[i]), next.end());
    }
  }
}

TEST(Terrain, RampsRiseAndTheMeshFollowsThem) {
  const Map town = Build(LoadLayout((test::SourceDir() / "config/maps/small_town.yaml").string()));
  // Row 0 (y in [4, 5]) is the terrace at 0.05 m; row 1 holds ramps rising northwards.
  EXPECT_DOUBLE_EQ(TerrainHeight(town, 0.5, 4.5), 0.05);
  EXPECT_DOUBLE_EQ(TerrainHeight(town, 2.5, 2.5), 0.0);
  EXPECT_NEAR(TerrainHeight(town, 0.5, 3.5), 0.025, 1e-12);  // middle of a ramp
  EXPECT_NEAR(TerrainHeight(town, 0.5, 3.25), 0.0125, 1e-12);
  EXPECT_EQ(test::ErrorMessage([&] { (void)TerrainHeight(town, -1, 0); }),
            "point (-1, 0) is outside the map [0, 5] x [0, 5]");

  const auto dir = TempDir("mesh");
  const auto stats = WriteMeshObj(town, (dir / "mesh.obj").string());
  EXPECT_EQ(stats.faces, 25u * 2 + town.obstacles.size() * 12);
  std::ifstream in(dir / "mesh.obj");
  std::string line;
  std::size_t v = 0, f = 0;
  double zmax = 0;
  while (std::getline(in, line)) {
    if (line.rfind("v ", 0) == 0) {
      ++v;
      double x, y, z;
      std::sscanf(line.c_str(), "v %lf %lf %lf", &x, &y, &z);
      zmax = std::max(zmax, z);
    }
    f += line.rfind("f ", 0) == 0;
  }
  EXPECT_EQ(v, stats.vertices);
  EXPECT_EQ(f, stats.faces);
  EXPECT_NEAR(zmax, 0.25, 1e-9);  // a 0.25 m box on the ground
  fs::remove_all(dir);
}

TEST(ShippedMaps, OccupancyGridFreeAreaEqualsTheDrivableAreaWithinTwoPercent) {
  for (const auto& path : ShippedLayouts()) {
    SCOPED_TRACE(path.string());
    const Map map = Build(LoadLayout(path.string()));
    const OccupancyGrid grid = MakeOccupancyGrid(map, 0.05);
    const double free_m2 = static_cast<double>(grid.FreeCount()) * 0.05 * 0.05;
    EXPECT_NEAR(free_m2, Area(map.drivable), 0.02 * Area(map.drivable));
  }
}

// Every output of every shipped map, written where a person can look at them after a test
// run: <build>/maps_out/<map>/ (map.png, map.svg, occupancy.pgm, mesh.obj, sumo/...).
TEST(ShippedMaps, EveryOutputIsWrittenForEveryShippedMap) {
  const char* bin = std::getenv("AUTODRIVE_BINARY_DIR");
  ASSERT_NE(bin, nullptr) << "run through ctest";
  for (const auto& path : ShippedLayouts()) {
    SCOPED_TRACE(path.string());
    const Map map = Build(LoadLayout(path.string()));
    const fs::path dir = fs::path(bin) / "maps_out" / map.name;
    fs::create_directories(dir);
    const auto files = WriteOutputs(map, dir.string(), OutputOptions{});
    for (const char* name :
         {"map.yaml", "mesh.obj", "occupancy.pgm", "occupancy.yaml", "map.png", "map.svg"}) {
      ASSERT_TRUE(fs::exists(dir / name)) << name;
      EXPECT_GT(fs::file_size(dir / name), 100u) << name;
    }
    std::ifstream png(dir / "map.png", std::ios::binary);
    char magic[8] = {};
    png.read(magic, 8);
    EXPECT_EQ(std::string(magic + 1, 3), "PNG");
    EXPECT_EQ(fs::exists(dir / "sumo" / (map.name + ".net.xml")), !map.lanes.empty());
    EXPECT_NO_THROW((void)LoadMap((dir / "map.yaml").string()));
  }
}

}  // namespace
}  // namespace autodrive::maps
