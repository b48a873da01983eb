// Rays per second of the LIDAR ray caster on one thread (goal: >= 2 million on the small town
// with 10 vehicles; f1tenth_gym's ray marching does about 0.5 million), against the
// brute-force loop over every face, and the time to build the static scene.
//
// Vehicles (Nigel's body, 0.318 x 0.175 x 0.257 m) stand on lane centrelines (random points of
// the free floor on maps without lanes), pitched with the ground; each casts full 360-beam
// scans from its LIDAR (0.1445 m ahead of the rear axle, 0.1757 m up) with the other vehicles
// as dynamic boxes and its own excluded.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/error.h"
#include "common/geometry.h"
#include "common/logging.h"
#include "common/process.h"
#include "maps/builder.h"
#include "maps/grid_city.h"
#include "maps/layout.h"
#include "maps/mesh.h"
#include "vehicle_sim/raycast.h"

namespace {

namespace fs = std::filesystem;
using autodrive::kPi;
using autodrive::vehicle_sim::BoxId;
using autodrive::vehicle_sim::DynamicBox;
using autodrive::vehicle_sim::Hit;
using autodrive::vehicle_sim::Ray;

constexpr double kWheelbase = 0.14154;
constexpr double kLidarAhead = 0.1445;
constexpr double kLidarHeight = 0.1757;
constexpr int kBeams = 360;
constexpr double kMaxRange = 12.0;
const Eigen::Vector3d kHalf(0.159, 0.0875, 0.1285);

// `path` as given when it exists (absolute or from the working directory), else from the
// repository root (the programs run from build/bin) or AUTODRIVE_SOURCE_DIR.
fs::path Resolve(const std::string& path) {
  if (fs::exists(path)) return path;
  std::vector<fs::path> roots = {fs::path(autodrive::ExecutableDir()) / ".." / ".."};
  if (const char* src = std::getenv("AUTODRIVE_SOURCE_DIR")) roots.emplace_back(src);
  for (const auto& root : roots) {
    if (fs::exists(root / path)) return fs::canonical(root / path);
  }
  throw autodrive::InputError("--map " + path + ": no such file here or in the repository root");
}

struct Vehicle {
  DynamicBox box;
  Eigen::Isometry3d X_MV;  // rear axle on the ground, x forward, z up
};

// A vehicle with its rear axle at `p` heading `yaw`, pitched with the ground along its length.
Vehicle Place(const autodrive::maps::Map& map, std::uint32_t id, const Eigen::Vector2d& p,
              double yaw) {
  const auto ground = [&](const Eigen::Vector2d& q) {
    const Eigen::Vector2d size = map.size_m();
    if (q.x() < 0 || q.y() < 0 || q.x() > size.x() || q.y() > size.y()) return 0.0;
    return autodrive::maps::TerrainHeight(map, q.x(), q.y());
  };
  const Eigen::Vector2d u(std::cos(yaw), std::sin(yaw));
  const double rise = ground(p + u * kWheelbase) - ground(p);
  const double pitch = -std::atan2(rise, kWheelbase);  // nose up is a negative pitch
  Eigen::Isometry3d X_MV = Eigen::Isometry3d::Identity();
  X_MV.translate(Eigen::Vector3d(p.x(), p.y(), ground(p)));
  X_MV.rotate(autodrive::QuaternionFromRollPitchYaw({0.0, pitch, yaw}));
  Eigen::Isometry3d X_VB = Eigen::Isometry3d::Identity();
  X_VB.translate(Eigen::Vector3d(kWheelbase / 2, 0.0, kHalf.z()));
  return {{BoxId(id), X_MV * X_VB, kHalf}, X_MV};
}

std::vector<Vehicle> PlaceVehicles(const autodrive::maps::Map& map, int count, std::mt19937& rng) {
  std::vector<std::pair<Eigen::Vector2d, double>> spots;  // (point, heading)
  for (const auto& lane : map.lanes) {
    for (std::size_t i = 0; i + 1 < lane.centreline.size(); ++i) {
      const Eigen::Vector2d d = lane.centreline[i + 1] - lane.centreline[i];
      spots.emplace_back(lane.centreline[i], std::atan2(d.y(), d.x()));
    }
  }
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  if (spots.empty()) {  // no lanes (the Parking School): free floor away from the obstacles
    for (int i = 0; i < 20000; ++i) {
      const Eigen::Vector2d p(u01(rng) * map.size_m().x(), u01(rng) * map.size_m().y());
      bool free = true;
      for (const auto& o : map.obstacles) {
        Eigen::AlignedBox2d box;
        for (const auto& q : o.footprint) box.extend(q);
        if (box.exteriorDistance(p) < 0.3) free = false;
      }
      if (free) spots.emplace_back(p, (u01(rng) * 2 - 1) * kPi);
    }
  }
  AUTODRIVE_THROW_UNLESS(!spots.empty(), "map " << map.name << ": nowhere to place a vehicle");
  std::vector<Vehicle> out;
  for (int attempt = 0; attempt < 100000 && static_cast<int>(out.size()) < count; ++attempt) {
    const auto& [p, yaw] =
        spots[static_cast<std::size_t>(u01(rng) * static_cast<double>(spots.size())) %
              spots.size()];
    bool clear = true;
    for (const auto& v : out) {
      if ((v.X_MV.translation().head<2>() - p).norm() < 0.45) clear = false;
    }
    if (clear) out.push_back(Place(map, static_cast<std::uint32_t>(out.size() + 1), p, yaw));
  }
  AUTODRIVE_THROW_UNLESS(
      static_cast<int>(out.size()) == count,
      "map " << map.name << ": room for only " << out.size() << " of " << count << " vehicles");
  return out;
}

// The 360 beams of each vehicle's LIDAR, in the map frame.
std::vector<std::vector<Ray>> Scans(const std::vector<Vehicle>& vehicles) {
  std::vector<std::vector<Ray>> scans;
  for (const auto& v : vehicles) {
    const Eigen::Vector3d p_ML = v.X_MV * Eigen::Vector3d(kLidarAhead, 0.0, kLidarHeight);
    std::vector<Ray> rays;
    for (int i = 0; i < kBeams; ++i) {
      const double a = i * 2 * kPi / kBeams;
      rays.push_back({p_ML, v.X_MV.linear() * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0)});
    }
    scans.push_back(std::move(rays));
  }
  return scans;
}

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

namespace vs = autodrive::vehicle_sim;

struct GridRun {
  std::size_t returns[4] = {0, 0, 0, 0};  // by Hit::What
  double range_sum = 0;                   // over the rays that hit something (m)
  double seconds = 0;
};

// `scans` full scans of every vehicle with the grid caster.
GridRun RunGrid(const vs::StaticScene& scene, const std::vector<DynamicBox>& boxes,
                const std::vector<Vehicle>& placed, const std::vector<std::vector<Ray>>& rays,
                int scans) {
  GridRun run;
  std::vector<Hit> hits(kBeams);
  const auto t0 = std::chrono::steady_clock::now();
  for (int s = 0; s < scans; ++s) {
    for (std::size_t v = 0; v < placed.size(); ++v) {
      vs::CastScan(scene, boxes, rays[v], kMaxRange, placed[v].box.id, hits);
      for (const Hit& h : hits) {
        ++run.returns[static_cast<int>(h.what)];
        if (h.what != Hit::What::kNothing) run.range_sum += h.range_m;
      }
    }
  }
  run.seconds = Seconds(t0);
  return run;
}

struct BruteRun {
  std::size_t disagreements = 0;  // rays of the first scans where brute force and grid differ
  double seconds = 0;
};

// `scans` full scans of every vehicle with the brute force, comparing its first with the grid's.
BruteRun RunBrute(const vs::StaticScene& scene, const std::vector<DynamicBox>& boxes,
                  const std::vector<Vehicle>& placed, const std::vector<std::vector<Ray>>& rays,
                  int scans) {
  BruteRun run;
  const auto t0 = std::chrono::steady_clock::now();
  for (int s = 0; s < scans; ++s) {
    for (std::size_t v = 0; v < placed.size(); ++v) {
      for (int i = 0; i < kBeams; ++i) {
        const auto& ray = rays[v][static_cast<std::size_t>(i)];
        const Hit b = vs::CastBruteForce(scene, boxes, ray, kMaxRange, placed[v].box.id);
        if (s == 0) {
          const Hit g = vs::Cast(scene, boxes, ray, kMaxRange, placed[v].box.id);
          const bool same = g.what == b.what && (g.what == Hit::What::kNothing ||
                                                 std::abs(g.range_m - b.range_m) <= 1e-9);
          run.disagreements += same ? 0 : 1;
        }
      }
    }
  }
  run.seconds = Seconds(t0);
  return run;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Rays per second of the LIDAR ray caster (vehicle_sim/raycast.h) on one thread: full "
      "360-beam scans from vehicles on a map's lanes, against the brute-force loop"};
  std::string map_path = "config/maps/small_town.yaml";
  int vehicles = 10;
  int scans = 300;
  int brute_scans = 100;
  double cell_m = 0.1;
  unsigned seed = 1;
  int grid_city = 0;
  app.add_option("--map", map_path,
                 "map layout (YAML), from the working directory or the repository root")
      ->capture_default_str();
  app.add_option("--vehicles", vehicles, "vehicles on the map")
      ->check(CLI::Range(1, 200))
      ->capture_default_str();
  app.add_option("--scans", scans, "full scans cast by each vehicle with the grid")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--brute-scans", brute_scans, "full scans per vehicle with the brute force")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--cell", cell_m, "grid cell size (m)")->capture_default_str();
  app.add_option("--seed", seed, "seed of the vehicles' placement")->capture_default_str();
  app.add_option("--grid-city", grid_city,
                 "instead of --map, a generated grid city of N x N intersections (to see how the "
                 "casters scale with the size of the scene)")
      ->check(CLI::Range(0, 64));
  std::string log_level = "warn";
  app.add_option("--log-level", log_level, "log level");
  CLI11_PARSE(app, argc, argv);
  autodrive::InitLogging("autodrive-bench-raycast", autodrive::ParseLogLevel(log_level));
  try {
    const fs::path path = grid_city > 0 ? fs::path("generated") : Resolve(map_path);
    const auto map = autodrive::maps::Build(
        grid_city > 0 ? autodrive::maps::GridCity(grid_city, grid_city, "mixed")
                      : autodrive::maps::LoadLayout(path.string()));
    vs::StaticSceneOptions options;
    options.cell_size_m = cell_m;
    options.Validate();

    double build_s = 1e300;
    for (int i = 0; i < 5; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      const vs::StaticScene s = vs::StaticScene::FromMap(map, options);
      build_s = std::min(build_s, Seconds(t0));
    }
    const vs::StaticScene scene = vs::StaticScene::FromMap(map, options);

    std::mt19937 rng(seed);
    const std::vector<Vehicle> placed = PlaceVehicles(map, vehicles, rng);
    std::vector<DynamicBox> boxes;
    for (const auto& v : placed) boxes.push_back(v.box);
    const auto rays = Scans(placed);

    std::printf("map %s (%s): %d x %d tiles, %zu prisms, %zu poles, %d vehicles\n",
                map.name.c_str(), path.string().c_str(), map.cols, map.rows,
                scene.geometry().prisms.size(), scene.geometry().cylinders.size(), vehicles);
    std::printf("scene: %d x %d cells of %.3f m, %zu cell entries, built in %.3f ms\n",
                scene.cells_x(), scene.cells_y(), scene.cell_size_m(), scene.num_cell_entries(),
                build_s * 1e3);

    const GridRun grid = RunGrid(scene, boxes, placed, rays, scans);
    const BruteRun brute = RunBrute(scene, boxes, placed, rays, brute_scans);
    const double grid_rays = static_cast<double>(scans) * vehicles * kBeams;
    const double brute_rays = static_cast<double>(brute_scans) * vehicles * kBeams;
    const double total = grid_rays;
    std::printf(
        "returns: %.1f%% static, %.1f%% terrain, %.1f%% vehicles, %.1f%% none; mean "
        "range %.3f m\n",
        100.0 * static_cast<double>(grid.returns[1]) / total,
        100.0 * static_cast<double>(grid.returns[2]) / total,
        100.0 * static_cast<double>(grid.returns[3]) / total,
        100.0 * static_cast<double>(grid.returns[0]) / total,
        grid.range_sum / std::max(1.0, static_cast<double>(grid.returns[1] + grid.returns[2] +
                                                           grid.returns[3])));
    std::printf("%-12s %12s %10s %14s %14s\n", "caster", "rays", "time (s)", "rays/s",
                "scans/s (360)");
    std::printf("%-12s %12.0f %10.3f %14.0f %14.0f\n", "grid", grid_rays, grid.seconds,
                grid_rays / grid.seconds, grid_rays / grid.seconds / kBeams);
    std::printf("%-12s %12.0f %10.3f %14.0f %14.0f\n", "brute force", brute_rays, brute.seconds,
                brute_rays / brute.seconds, brute_rays / brute.seconds / kBeams);
    std::printf("speed-up %.1fx; grid and brute force disagree on %zu of %d rays\n",
                (grid_rays / grid.seconds) / (brute_rays / brute.seconds), brute.disagreements,
                vehicles * kBeams);
    const std::size_t disagreements = brute.disagreements;
    return disagreements == 0 ? 0 : 1;
  } catch (const autodrive::InputError& e) {
    std::fprintf(stderr, "autodrive-bench-raycast: %s\n", e.what());
    return 2;
  }
}
