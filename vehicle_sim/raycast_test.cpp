// The ray caster against analytic geometry (walls, box tops, poles, ramps, steps, vehicles) and
// against a brute-force reference written independently here (every face of every obstacle,
// pole, tile and box, from the map itself), on random rays over the shipped maps.
#include "vehicle_sim/raycast.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <random>
#include <thread>

#include "common/config.h"
#include "common/geometry.h"
#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/layout.h"
#include "maps/mesh.h"
#include "maps/test_layouts.h"

// Counts the C++ allocations of this program, to check that casting allocates nothing (as in
// scm/daemon_test.cpp).
namespace {
std::atomic<long> g_allocations{0};
}  // namespace

// GCC cannot see that these replace the global operators as a pair.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
// The nothrow forms too (std::stable_sort's buffer uses them): under AddressSanitizer they
// would otherwise come from its allocator and be freed by ours.
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  return std::malloc(size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, const std::nothrow_t& tag) noexcept {
  return operator new(size, tag);
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
#pragma GCC diagnostic pop

namespace autodrive::vehicle_sim {
namespace {

using What = Hit::What;
constexpr double kTol = 1e-9;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kLidarHeight = 0.1757;
// Nigel's body (L x W x H = 0.318 x 0.175 x 0.257 m), as half extents.
const Eigen::Vector3d kNigelHalf(0.159, 0.0875, 0.1285);

maps::Map Shipped(const std::string& name) {
  return maps::Build(
      maps::LoadLayout((test::SourceDir() / "config" / "maps" / (name + ".yaml")).string()));
}

Ray RayTo(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  return {from, (to - from).normalized()};
}

Ray Horizontal(double x, double y, double z, double heading_rad) {
  return {{x, y, z}, {std::cos(heading_rad), std::sin(heading_rad), 0.0}};
}

DynamicBox Box(std::uint32_t id, const Eigen::Vector3d& centre, double yaw_rad,
               const Eigen::Vector3d& half, double pitch_rad = 0.0, double roll_rad = 0.0) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translate(centre);
  X.rotate(QuaternionFromRollPitchYaw({roll_rad, pitch_rad, yaw_rad}));
  return {BoxId(id), X, half};
}

// ---------------------------------------------------------------------------------------------
// The reference: every surface tested one by one, built from the map (not from the scene), with
// its own formulas: faces as planes, boxes as six faces in the map frame, a winding-number
// point-in-polygon test, terrain planes fitted to maps::TerrainHeight.

struct RefFace {  // a vertical side face over a -> b
  Eigen::Vector2d a, b;
  double z0, z1;
};
struct RefPoly {
  maps::Polyline v;
  double z0, z1;
};
struct RefPole {
  Eigen::Vector2d c;
  double r, z0, z1;
};
struct RefTile {
  double x0, y0, x1, y1, gx, gy, z0;  // z = z0 + gx x + gy y
};

struct Reference {
  std::vector<RefFace> faces;
  std::vector<RefPoly> caps;
  std::vector<RefPole> poles;
  std::vector<RefTile> tiles;
  double width = 0, height = 0;
};

Reference MakeReference(const maps::Map& map, const StaticSceneOptions& o = {}) {
  Reference ref;
  ref.width = map.size_m().x();
  ref.height = map.size_m().y();
  const auto ground = [&](const Eigen::Vector2d& p) {
    return maps::TerrainHeight(map, p.x(), p.y());
  };
  for (const auto& ob : map.obstacles) {
    // The lab maps' obstacles stand on flat ground: any corner gives the base (as the mesh).
    const double base = ground(ob.footprint[0]);
    for (std::size_t i = 0; i < ob.footprint.size(); ++i) {
      ref.faces.push_back(
          {ob.footprint[i], ob.footprint[(i + 1) % ob.footprint.size()], base, base + ob.height_m});
    }
    ref.caps.push_back({ob.footprint, base, base + ob.height_m});
  }
  for (const auto& h : map.signal_heads) {
    const Eigen::Vector2d p = h.X_MH.translation();
    ref.poles.push_back({p, o.pole_radius_m, ground(p), ground(p) + o.signal_head_height_m});
  }
  for (const auto& s : map.signs) {
    const Eigen::Vector2d p = s.X_MS.translation();
    ref.poles.push_back({p, o.pole_radius_m, ground(p), ground(p) + o.sign_height_m});
  }
  const double T = map.tile_size_m;
  for (int c = 0; c < map.cols; ++c) {
    for (int r = 0; r < map.rows; ++r) {
      const double x0 = c * T, y0 = r * T;
      const double xa = x0 + 0.25 * T, xb = x0 + 0.75 * T, ya = y0 + 0.25 * T, yb = y0 + 0.75 * T;
      const double h00 = maps::TerrainHeight(map, xa, ya);
      const double gx = (maps::TerrainHeight(map, xb, ya) - h00) / (xb - xa);
      const double gy = (maps::TerrainHeight(map, xa, yb) - h00) / (yb - ya);
      ref.tiles.push_back({x0, y0, x0 + T, y0 + T, gx, gy, h00 - gx * xa - gy * ya});
    }
  }
  return ref;
}

// Winding number of the polygon around p (non-zero inside).
bool InsideByWinding(const maps::Polyline& v, const Eigen::Vector2d& p) {
  int winding = 0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const Eigen::Vector2d& a = v[i];
    const Eigen::Vector2d& b = v[(i + 1) % v.size()];
    const double side = (b.x() - a.x()) * (p.y() - a.y()) - (p.x() - a.x()) * (b.y() - a.y());
    if (a.y() <= p.y()) {
      if (b.y() > p.y() && side > 0) ++winding;
    } else if (b.y() <= p.y() && side < 0) {
      --winding;
    }
  }
  return winding != 0;
}

// The nearest range per kind of surface; +inf where none.
struct RefResult {
  double statics = kInf, terrain = kInf, box = kInf;
  std::vector<std::uint32_t> boxes_at;  // ids of the boxes hit at `box` (to rounding)
  [[nodiscard]] double best() const { return std::min({statics, terrain, box}); }
};

// The t range where the ray's (x, y) lies in the closed rectangle, or false.
bool Slabs(const Ray& ray, double x0, double y0, double x1, double y1, double& lo, double& hi) {
  lo = -kInf;
  hi = kInf;
  const double o[2] = {ray.origin_M.x(), ray.origin_M.y()};
  const double d[2] = {ray.direction_M.x(), ray.direction_M.y()};
  const double mins[2] = {x0, y0}, maxs[2] = {x1, y1};
  for (int i = 0; i < 2; ++i) {
    if (d[i] == 0) {
      if (o[i] < mins[i] || o[i] > maxs[i]) return false;
      continue;
    }
    const double a = (mins[i] - o[i]) / d[i], b = (maxs[i] - o[i]) / d[i];
    lo = std::max(lo, std::min(a, b));
    hi = std::min(hi, std::max(a, b));
  }
  return lo <= hi;
}

// The first t in [lo, hi] (clipped to t >= 0) where z(t) <= g(t) for the linear gap
// f(t) = f0 + f1 t = z(t) - ground(t); +inf when none.
double FirstBelow(double f0, double f1, double lo, double hi) {
  lo = std::max(lo, 0.0);
  if (lo > hi) return kInf;
  if (f0 + f1 * lo <= 0) return lo;
  if (f1 < 0) {
    const double t = -f0 / f1;
    if (t <= hi) return t;
  }
  return kInf;
}

RefResult ReferenceCast(const Reference& ref, std::span<const DynamicBox> boxes, const Ray& ray,
                        double max_range, std::optional<BoxId> exclude) {
  RefResult out;
  const Eigen::Vector3d& o = ray.origin_M;
  const Eigen::Vector3d& d = ray.direction_M;
  const auto keep = [&](double& slot, double t) {
    if (t >= 0 && t < max_range) slot = std::min(slot, t);
  };
  for (const auto& f : ref.faces) {
    const Eigen::Vector2d e = f.b - f.a;
    const Eigen::Vector3d n(-e.y(), e.x(), 0.0);
    const double denom = n.dot(d);
    if (denom == 0) continue;
    const double t = n.dot(Eigen::Vector3d(f.a.x(), f.a.y(), 0.0) - o) / denom;
    const Eigen::Vector3d p = o + t * d;
    const double s = (p.head<2>() - f.a).dot(e) / e.squaredNorm();
    if (s >= 0 && s <= 1 && p.z() >= f.z0 && p.z() <= f.z1) keep(out.statics, t);
  }
  for (const auto& c : ref.caps) {
    if (d.z() == 0) continue;
    for (const double z : {c.z0, c.z1}) {
      const double t = (z - o.z()) / d.z();
      if (InsideByWinding(c.v, (o + t * d).head<2>())) keep(out.statics, t);
    }
  }
  for (const auto& p : ref.poles) {
    const Eigen::Vector2d f = o.head<2>() - p.c;
    const Eigen::Vector2d u = d.head<2>();
    const double a = u.squaredNorm(), b = 2 * f.dot(u), c = f.squaredNorm() - p.r * p.r;
    if (a > 0 && b * b - 4 * a * c >= 0) {
      for (const double sign : {-1.0, 1.0}) {
        const double t = (-b + sign * std::sqrt(b * b - 4 * a * c)) / (2 * a);
        const double z = o.z() + t * d.z();
        if (z >= p.z0 && z <= p.z1) keep(out.statics, t);
      }
    }
    if (d.z() != 0) {
      for (const double z : {p.z0, p.z1}) {
        const double t = (z - o.z()) / d.z();
        if (((o + t * d).head<2>() - p.c).norm() <= p.r) keep(out.statics, t);
      }
    }
  }
  // Terrain: each tile's plane over the part of the ray above the tile; z = 0 outside the map.
  for (const auto& tile : ref.tiles) {
    double lo = 0, hi = 0;
    if (!Slabs(ray, tile.x0, tile.y0, tile.x1, tile.y1, lo, hi)) continue;
    const double f0 = o.z() - (tile.z0 + tile.gx * o.x() + tile.gy * o.y());
    const double f1 = d.z() - (tile.gx * d.x() + tile.gy * d.y());
    keep(out.terrain, FirstBelow(f0, f1, lo, hi));
  }
  double lo = kInf, hi = kInf;
  if (!Slabs(ray, 0, 0, ref.width, ref.height, lo, hi) || hi < 0) lo = hi = kInf;
  const double before = FirstBelow(o.z(), d.z(), 0, std::max(lo, 0.0));
  if (before < std::max(lo, 0.0)) keep(out.terrain, before);  // the open interval [0, lo)
  keep(out.terrain, FirstBelow(o.z(), d.z(), hi, kInf));
  // Boxes: their six faces.
  std::vector<std::pair<double, std::uint32_t>> box_hits;
  for (const auto& b : boxes) {
    if (exclude && b.id == *exclude) continue;
    const Eigen::Matrix3d R = b.X_MB.linear();
    const Eigen::Vector3d c = b.X_MB.translation();
    for (int i = 0; i < 3; ++i) {
      for (const double sign : {-1.0, 1.0}) {
        const Eigen::Vector3d n = sign * R.col(i);
        const double denom = n.dot(d);
        if (denom == 0) continue;
        const double t = n.dot(c + n * b.half_extents_m[i] - o) / denom;
        const Eigen::Vector3d local = R.transpose() * (o + t * d - c);
        bool inside = true;
        for (int j = 0; j < 3; ++j) {
          if (j != i && std::abs(local[j]) > b.half_extents_m[j] + 1e-12) inside = false;
        }
        if (inside && t >= 0 && t < max_range) box_hits.emplace_back(t, b.id.value());
      }
    }
  }
  for (const auto& [t, id] : box_hits) out.box = std::min(out.box, t);
  for (const auto& [t, id] : box_hits) {
    if (t <= out.box + kTol) out.boxes_at.push_back(id);
  }
  return out;
}

// Expects `hit` to be the reference's answer: the same range, and a kind (and box) hit there.
::testing::AssertionResult SameAsReference(const Hit& hit, const RefResult& ref) {
  const double best = ref.best();
  if (!std::isfinite(best)) {
    if (hit.what == What::kNothing && std::isinf(hit.range_m)) {
      return ::testing::AssertionSuccess();
    }
    return ::testing::AssertionFailure()
           << "reference: nothing; cast: " << hit.range_m << " kind " << static_cast<int>(hit.what);
  }
  if (hit.what == What::kNothing || std::abs(hit.range_m - best) > kTol) {
    return ::testing::AssertionFailure()
           << "reference: static " << ref.statics << " terrain " << ref.terrain << " box "
           << ref.box << "; cast: " << hit.range_m << " kind " << static_cast<int>(hit.what);
  }
  const double at = hit.what == What::kStatic    ? ref.statics
                    : hit.what == What::kTerrain ? ref.terrain
                                                 : ref.box;
  if (std::abs(at - best) > kTol) {
    return ::testing::AssertionFailure() << "kind " << static_cast<int>(hit.what) << " at " << at
                                         << " but the nearest is at " << best;
  }
  if (hit.what == What::kBox && (!hit.box || std::find(ref.boxes_at.begin(), ref.boxes_at.end(),
                                                       hit.box->value()) == ref.boxes_at.end())) {
    return ::testing::AssertionFailure() << "wrong box";
  }
  return ::testing::AssertionSuccess();
}

// ---------------------------------------------------------------------------------------------
// Building the scene

TEST(StaticScene, HoldsTheMapsObstaclesPolesAndTerrain) {
  const maps::Map town = Shipped("small_town");
  const StaticScene scene = StaticScene::FromMap(town);
  const auto& g = scene.geometry();
  ASSERT_EQ(g.prisms.size(), town.obstacles.size());
  EXPECT_EQ(g.prisms[0].footprint_M, town.obstacles[0].footprint);
  EXPECT_DOUBLE_EQ(g.prisms[0].z_bottom_m, 0.0);
  EXPECT_DOUBLE_EQ(g.prisms[0].z_top_m, 0.25);
  ASSERT_EQ(g.cylinders.size(), town.signal_heads.size() + town.signs.size());
  EXPECT_GT(town.signal_heads.size(), 0u);
  EXPECT_EQ(g.cylinders[0].centre_M, town.signal_heads[0].X_MH.translation());
  EXPECT_DOUBLE_EQ(g.cylinders[0].radius_m, 0.01);
  EXPECT_NEAR(g.cylinders[0].z_top_m - g.cylinders[0].z_bottom_m, 0.21, 1e-12);
  const auto& last = g.cylinders.back();
  EXPECT_NEAR(last.z_top_m - last.z_bottom_m, 0.15, 1e-12);
  // 5 m x 5 m in cells of 0.1 m.
  EXPECT_EQ(scene.cells_x(), 50);
  EXPECT_EQ(scene.cells_y(), 50);
  EXPECT_DOUBLE_EQ(scene.cell_size_m(), 0.1);
  EXPECT_GT(scene.num_cell_entries(), 0u);
  // A cell size that does not divide the tile is adjusted to one that does.
  StaticSceneOptions o;
  o.cell_size_m = 0.3;
  const StaticScene coarse = StaticScene::FromMap(town, o);
  EXPECT_DOUBLE_EQ(coarse.cell_size_m(), 1.0 / 3.0);
  EXPECT_EQ(coarse.cells_x(), 15);
}

TEST(TerrainModel, AgreesWithTheMapsTerrainHeight) {
  const maps::Map town = Shipped("small_town");
  const TerrainModel terrain = TerrainModel::FromMap(town);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 5.0);
  for (int i = 0; i < 2000; ++i) {
    const double x = u(rng), y = u(rng);
    EXPECT_NEAR(terrain.HeightAt(x, y), maps::TerrainHeight(town, x, y), 1e-12) << x << " " << y;
  }
  EXPECT_DOUBLE_EQ(terrain.HeightAt(-1.0, 2.0), 0.0);
  EXPECT_NEAR(terrain.MaxHeight(), 0.05, 1e-12);
  // A footprint across the foot of the terrace: the lower side counts.
  EXPECT_NEAR(terrain.MinHeightUnder({{1.4, 3.9}, {1.6, 3.9}, {1.6, 4.1}, {1.4, 4.1}}), 0.0, 1e-12);
  EXPECT_NEAR(terrain.MinHeightUnder({{1.4, 4.1}, {1.6, 4.1}, {1.6, 4.3}, {1.4, 4.3}}), 0.05,
              1e-12);
  // Half-way up a ramp rising northwards from y = 3 to 4: the lowest point is the south edge.
  EXPECT_NEAR(terrain.MinHeightUnder({{0.4, 3.4}, {0.6, 3.4}, {0.6, 3.6}, {0.4, 3.6}}), 0.02,
              1e-12);
}

TEST(StaticScene, RejectsBadGeometryAndOptions) {
  StaticGeometry g;
  g.prisms.push_back({{{0, 0}, {1, 0}}, 0.0, 1.0});
  EXPECT_EQ(test::ErrorMessage([&] { StaticScene s(g, 0.1); }),
            "prism 0: a footprint needs at least 3 vertices, got 2");
  g.prisms[0] = {{{0, 0}, {1, 0}, {1, 1}}, 0.5, 0.2};
  EXPECT_EQ(test::ErrorMessage([&] { StaticScene s(g, 0.1); }),
            "prism 0: z_top_m 0.2 must be finite and >= z_bottom_m 0.5");
  g.prisms.clear();
  g.cylinders.push_back({{0, 0}, -0.1, 0.0, 1.0});
  EXPECT_EQ(test::ErrorMessage([&] { StaticScene s(g, 0.1); }),
            "cylinder 0: radius_m must be >= 0, got -0.1");
  EXPECT_EQ(test::ErrorMessage([&] { StaticScene s(StaticGeometry{}, 0.0); }),
            "StaticScene: cell size must be in [0.01, 10] m, got 0");
  StaticSceneOptions o;
  o.pole_radius_m = 0;
  EXPECT_EQ(test::ErrorMessage([&] { o.Validate(); }),
            "StaticSceneOptions: pole_radius_m must be in [0.001, 1], got 0");
}

TEST(StaticSceneOptions, RoundTripsThroughYaml) {
  StaticSceneOptions o;
  o.cell_size_m = 0.05;
  o.sign_height_m = 0.3;
  EXPECT_EQ(config::LoadString<StaticSceneOptions>(config::SaveString(o)), o);
  const std::string error = test::ErrorMessage<ConfigError>(
      [] { (void)config::LoadString<StaticSceneOptions>("cell_size_m: 0.001\n", "<test>"); });
  EXPECT_NE(error.find("cell_size_m"), std::string::npos) << error;
}

// ---------------------------------------------------------------------------------------------
// Analytic cases

// Two open tiles inside 0.02 m boundary walls 0.2 m high, with a 0.2 m box at (1.0, 0.5) 0.1 m
// high.
maps::Map WalledRoom() {
  maps::Layout l = maps::MakeLayout("room", {{"open", "open"}});
  l.boundary_walls = true;
  l.obstacles = {{"box", 1.0, 0.5, 0.0, 0.2, 0.2, 0.1}};
  return maps::Build(l);
}

TEST(Cast, AHorizontalRayHitsAWallAtItsDistance) {
  const StaticScene scene = StaticScene::FromMap(WalledRoom());
  // East wall's inner face at x = 2 - 0.02; the ray runs north of the box.
  Hit hit = Cast(scene, {}, Horizontal(0.3, 0.8, 0.1, 0.0), 12.0);
  EXPECT_EQ(hit.what, What::kStatic);
  EXPECT_NEAR(hit.range_m, 1.98 - 0.3, kTol);
  // North wall's inner face at y = 1 - 0.02, seen at 30 degrees.
  hit = Cast(scene, {}, Horizontal(0.3, 0.2, 0.1, kPi / 3), 12.0);
  EXPECT_NEAR(hit.range_m, (0.98 - 0.2) / std::sin(kPi / 3), kTol);
  // The box's west face at x = 0.9.
  hit = Cast(scene, {}, Horizontal(0.3, 0.5, 0.05, 0.0), 12.0);
  EXPECT_EQ(hit.what, What::kStatic);
  EXPECT_NEAR(hit.range_m, 0.6, kTol);
  // Above the walls: nothing (the ground is never reached by a horizontal ray).
  hit = Cast(scene, {}, Horizontal(0.3, 0.8, 0.25, 0.0), 12.0);
  EXPECT_EQ(hit.what, What::kNothing);
  EXPECT_TRUE(std::isinf(hit.range_m));
}

TEST(Cast, NothingWithinTheMaximumRange) {
  const StaticScene scene = StaticScene::FromMap(WalledRoom());
  const Ray ray = Horizontal(0.3, 0.8, 0.1, 0.0);
  EXPECT_EQ(Cast(scene, {}, ray, 1.0).what, What::kNothing);
  EXPECT_TRUE(std::isinf(Cast(scene, {}, ray, 1.0).range_m));
  EXPECT_EQ(Cast(scene, {}, ray, 1.67).what, What::kNothing);  // the wall is at 1.68
  EXPECT_NEAR(Cast(scene, {}, ray, 1.69).range_m, 1.68, kTol);
  // Downwards onto the ground beyond the maximum range.
  EXPECT_EQ(Cast(scene, {}, RayTo({0.3, 0.8, 0.1}, {1.3, 0.8, 0.0}), 0.5).what, What::kNothing);
}

TEST(Cast, ARayAboveALowBoxMissesItAndOneComingDownHitsItsTop) {
  maps::Layout l = maps::MakeLayout("box", {{"empty", "empty", "empty"}});
  l.obstacles = {{"box", 1.5, 0.5, 0.0, 0.2, 0.2, 0.1}};
  const StaticScene scene = StaticScene::FromMap(maps::Build(l));
  // Over the top at 0.15 m: nothing (no walls, horizontal).
  EXPECT_EQ(Cast(scene, {}, Horizontal(0.5, 0.5, 0.15, 0.0), 12.0).what, What::kNothing);
  // Just below the top: the west face.
  EXPECT_NEAR(Cast(scene, {}, Horizontal(0.5, 0.5, 0.099, 0.0), 12.0).range_m, 0.9, kTol);
  // Down onto a point of the top face, inside the footprint [1.4, 1.6] x [0.4, 0.6].
  const Eigen::Vector3d from(0.5, 0.5, 0.3);
  for (const Eigen::Vector3d& target :
       {Eigen::Vector3d(1.45, 0.52, 0.1), Eigen::Vector3d(1.59, 0.41, 0.1)}) {
    const Hit hit = Cast(scene, {}, RayTo(from, target), 12.0);
    EXPECT_EQ(hit.what, What::kStatic);
    EXPECT_NEAR(hit.range_m, (target - from).norm(), kTol);
  }
  // Straight down onto the top, and from under a floating prism up onto its bottom.
  EXPECT_NEAR(Cast(scene, {}, {{1.5, 0.5, 0.4}, {0, 0, -1}}, 12.0).range_m, 0.3, kTol);
  StaticGeometry g = GeometryFromMap(maps::Build(l));
  g.prisms.push_back({{{0.2, 0.2}, {0.4, 0.2}, {0.3, 0.4}}, 0.3, 0.35});
  const StaticScene floating(g, 0.1);
  const Hit up = Cast(floating, {}, RayTo({0.0, 0.0, 0.1}, {0.3, 0.3, 0.3}), 12.0);
  EXPECT_EQ(up.what, What::kStatic);
  EXPECT_NEAR(up.range_m, Eigen::Vector3d(0.3, 0.3, 0.2).norm(), kTol);
  // Over the box (0.165 m above the ground at its west face): the ground behind it.
  const Hit ground = Cast(scene, {}, RayTo(from, {2.5, 0.5, 0.0}), 12.0);
  EXPECT_EQ(ground.what, What::kTerrain);
  EXPECT_NEAR(ground.range_m, (Eigen::Vector3d(2.5, 0.5, 0.0) - from).norm(), kTol);
}

TEST(Cast, ARayThroughASignalHeadHitsItsPole) {
  const maps::Map map = maps::Build(maps::test_layouts::FourWay("signal"));
  ASSERT_EQ(map.signal_heads.size(), 4u);
  const StaticScene scene = StaticScene::FromMap(map);
  const Eigen::Vector2d centre(1.5, 1.5);
  for (const auto& head : map.signal_heads) {
    const Eigen::Vector2d p = head.X_MH.translation();
    // From 1 m outside the corner, towards the head (the other heads are behind it).
    const Eigen::Vector2d out = (p - centre).normalized();
    const Eigen::Vector2d from = p + out;
    const Hit hit =
        Cast(scene, {},
             Horizontal(from.x(), from.y(), kLidarHeight, std::atan2(-out.y(), -out.x())), 12.0);
    EXPECT_EQ(hit.what, What::kStatic);
    EXPECT_NEAR(hit.range_m, 1.0 - 0.01, kTol);
    // Above the pole's top (0.21 m) the ray passes; the next head is too low too.
    EXPECT_EQ(
        Cast(scene, {}, Horizontal(from.x(), from.y(), 0.22, std::atan2(-out.y(), -out.x())), 12.0)
            .what,
        What::kNothing);
  }
}

// A single column: flat at y in [0, 1], a ramp rising 0.3 m northwards over y in [1, 2], a
// terrace at 0.3 m over y in [2, 3].
maps::Map SteepRamp() {
  return maps::Build(maps::MakeLayout(
      "ramp", {{"straight@90 elevation=0.3"}, {"ramp@90 rise=0.3"}, {"straight@90"}}));
}

TEST(Cast, AHorizontalLidarRayHitsARisingRampWhereItReachesTheRaysHeight) {
  const maps::Map map = SteepRamp();
  ASSERT_NEAR(maps::TerrainHeight(map, 0.5, 1.5), 0.15, 1e-12);
  const StaticScene scene = StaticScene::FromMap(map);
  const Hit hit = Cast(scene, {}, Horizontal(0.5, 0.5, kLidarHeight, kPi / 2), 12.0);
  EXPECT_EQ(hit.what, What::kTerrain);
  EXPECT_NEAR(hit.range_m, 0.5 + kLidarHeight / 0.3, kTol);
  // Over flat ground (east, west, south): nothing.
  for (const double heading : {0.0, kPi, -kPi / 2}) {
    EXPECT_EQ(Cast(scene, {}, Horizontal(0.5, 0.5, kLidarHeight, heading), 12.0).what,
              What::kNothing);
  }
}

TEST(Cast, ALidarTiltedOnARampSeesTheFloor) {
  const StaticScene scene = StaticScene::FromMap(SteepRamp());
  // A car half-way up the ramp, facing north, pitched up with it: its plane is parallel to
  // the ramp, so looking back (south and down) it meets the flat floor.
  const double slope = std::atan(0.3);
  const Eigen::Vector3d from(0.5, 1.5, 0.15 + kLidarHeight);
  const Hit back = Cast(scene, {}, {from, {0, -std::cos(slope), -std::sin(slope)}}, 12.0);
  EXPECT_EQ(back.what, What::kTerrain);
  EXPECT_NEAR(back.range_m, from.z() / std::sin(slope), kTol);
  // Looking forward it runs parallel to the ramp, then above the terrace: nothing.
  EXPECT_EQ(Cast(scene, {}, {from, {0, std::cos(slope), std::sin(slope)}}, 12.0).what,
            What::kNothing);
}

TEST(Cast, ALowRayHitsTheStepUpToATerrace) {
  const StaticScene scene = StaticScene::FromMap(Shipped("small_town"));
  // Empty tile r1c3 at 0 m; the terrace (row 0, y >= 4) is 0.05 m up.
  const Hit hit = Cast(scene, {}, Horizontal(3.5, 3.2, 0.02, kPi / 2), 12.0);
  EXPECT_EQ(hit.what, What::kTerrain);
  EXPECT_NEAR(hit.range_m, 0.8, kTol);
  EXPECT_EQ(Cast(scene, {}, Horizontal(3.5, 3.2, 0.06, kPi / 2), 12.0).what, What::kNothing);
  // Outside the map the ground is z = 0.
  const Hit outside = Cast(scene, {}, RayTo({-1.0, -1.0, 0.5}, {-3.0, -1.0, 0.0}), 12.0);
  EXPECT_EQ(outside.what, What::kTerrain);
  EXPECT_NEAR(outside.range_m, std::hypot(2.0, 0.5), kTol);
}

TEST(Cast, DynamicBoxesAtRangeAndBearingExcludingTheOwnOne) {
  const StaticScene empty(StaticGeometry{}, 0.1);  // flat ground only
  const Eigen::Vector3d o(1.0, 2.0, kLidarHeight);
  for (const double bearing : {0.0, 0.7, 2.0, -2.5}) {
    const Eigen::Vector3d u(std::cos(bearing), std::sin(bearing), 0.0);
    const std::vector<DynamicBox> boxes = {
        Box(1, o + 2.0 * u + Eigen::Vector3d(0, 0, kNigelHalf.z() - kLidarHeight), bearing,
            kNigelHalf),
        Box(2, o + Eigen::Vector3d(0, 0, kNigelHalf.z() - kLidarHeight), bearing, kNigelHalf)};
    // Own box (2) excluded: the other car's rear face.
    Hit hit = Cast(empty, boxes, {o, u}, 12.0, BoxId(2));
    EXPECT_EQ(hit.what, What::kBox);
    ASSERT_TRUE(hit.box.has_value());
    EXPECT_EQ(*hit.box, BoxId(1));
    EXPECT_NEAR(hit.range_m, 2.0 - kNigelHalf.x(), kTol);
    // Not excluded: the inside of its own front face.
    hit = Cast(empty, boxes, {o, u}, 12.0);
    EXPECT_EQ(*hit.box, BoxId(2));
    EXPECT_NEAR(hit.range_m, kNigelHalf.x(), kTol);
    // Sideways: neither.
    const Eigen::Vector3d side(-u.y(), u.x(), 0.0);
    EXPECT_EQ(Cast(empty, boxes, {o, side}, 12.0, BoxId(2)).what, What::kNothing);
    // Above the other car's roof (0.257 m): nothing.
    EXPECT_EQ(Cast(empty, boxes, {o + Eigen::Vector3d(0, 0, 0.1), u}, 12.0, BoxId(2)).what,
              What::kNothing);
  }
}

TEST(Cast, RotatedAndPitchedBoxes) {
  const StaticScene empty(StaticGeometry{}, 0.1);
  const Eigen::Vector3d half(0.1, 0.1, 0.1);
  // Yawed 45 degrees: the ray at y = 0.05 meets the face running back from the corner.
  std::vector<DynamicBox> boxes = {Box(5, {2.0, 0.0, 0.2}, kPi / 4, half)};
  Hit hit = Cast(empty, boxes, Horizontal(0.0, 0.05, 0.2, 0.0), 12.0);
  EXPECT_EQ(hit.what, What::kBox);
  EXPECT_NEAR(hit.range_m, 2.0 - 0.1 * std::sqrt(2.0) + 0.05, kTol);
  // Pitched 30 degrees about its y axis: the front face leans, met at hx / cos(30 deg).
  boxes = {Box(6, {2.0, 0.0, 0.2}, 0.0, half, kPi / 6)};
  hit = Cast(empty, boxes, Horizontal(0.0, 0.0, 0.2, 0.0), 12.0);
  EXPECT_NEAR(hit.range_m, 2.0 - 0.1 / std::cos(kPi / 6), kTol);
  // Rolled and yawed: against the six-face reference.
  boxes = {Box(7, {2.0, 0.3, 0.2}, 0.4, Eigen::Vector3d(0.2, 0.1, 0.05), 0.3, 0.5)};
  const Reference none;
  for (double y = 0.0; y < 0.6; y += 0.01) {
    const Ray ray = Horizontal(0.0, y, 0.21, 0.0);
    EXPECT_TRUE(
        SameAsReference(Cast(empty, boxes, ray, 12.0), ReferenceCast(none, boxes, ray, 12.0, {})))
        << "y " << y;
  }
}

TEST(Cast, ThinDividersOfTheParkingSchoolAreHit) {
  const StaticScene scene = StaticScene::FromMap(Shipped("parking_school"));
  // The divider at (3.6, 1.75), 0.7 m along x, 0.03 m thick (y in [1.735, 1.765]), 0.15 m high.
  Hit hit = Cast(scene, {}, Horizontal(3.6, 1.0, 0.1, kPi / 2), 12.0);
  EXPECT_EQ(hit.what, What::kStatic);
  EXPECT_NEAR(hit.range_m, 0.735, kTol);
  // Along its length, inside it: its far end.
  hit = Cast(scene, {}, Horizontal(3.3, 1.75, 0.1, 0.0), 12.0);
  EXPECT_NEAR(hit.range_m, 3.95 - 3.3, kTol);
  // At LIDAR height the ray passes over both dividers to the north wall (inner face y = 3.95).
  hit = Cast(scene, {}, Horizontal(3.6, 1.0, kLidarHeight, kPi / 2), 12.0);
  EXPECT_NEAR(hit.range_m, 2.95, kTol);
}

// ---------------------------------------------------------------------------------------------
// Randomised cross-check against the reference

// Ten boxes at random in the map, most on the ground, some tilted.
std::vector<DynamicBox> RandomBoxes(std::mt19937& rng, const maps::Map& map) {
  std::uniform_real_distribution<double> x(0.0, map.size_m().x()), y(0.0, map.size_m().y());
  std::uniform_real_distribution<double> yaw(-kPi, kPi), tilt(-0.3, 0.3);
  std::vector<DynamicBox> boxes;
  for (std::uint32_t i = 0; i < 10; ++i) {
    const double px = x(rng), py = y(rng);
    boxes.push_back(Box(i + 1, {px, py, maps::TerrainHeight(map, px, py) + kNigelHalf.z()},
                        yaw(rng), kNigelHalf, i % 3 == 0 ? tilt(rng) : 0.0,
                        i % 4 == 0 ? tilt(rng) : 0.0));
  }
  return boxes;
}

void CrossCheck(const std::string& name) {
  SCOPED_TRACE(name);
  const maps::Map map = Shipped(name);
  const StaticScene scene = StaticScene::FromMap(map);
  const Reference ref = MakeReference(map);
  std::mt19937 rng(static_cast<std::uint32_t>(name.size()));
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double w = map.size_m().x(), h = map.size_m().y();
  const auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * u01(rng); };
  const auto random_direction = [&](int kind) -> Eigen::Vector3d {
    const double heading = uniform(-kPi, kPi);
    double elevation = 0.0;
    if (kind == 1) elevation = uniform(-0.25, 0.25);           // a tilted LIDAR
    if (kind == 2) elevation = std::asin(uniform(-1.0, 1.0));  // anywhere
    return {std::cos(elevation) * std::cos(heading), std::cos(elevation) * std::sin(heading),
            std::sin(elevation)};
  };
  int counts[4] = {0, 0, 0, 0};
  int thin_hits = 0;
  const int n = 4000 * test::SoakFactor();
  std::vector<DynamicBox> boxes = RandomBoxes(rng, map);
  for (int i = 0; i < n; ++i) {
    if (i % 500 == 0) boxes = RandomBoxes(rng, map);
    const Eigen::Vector3d from(uniform(-0.5, w + 0.5), uniform(-0.5, h + 0.5),
                               uniform(-0.02, 0.45));
    Ray ray{from, random_direction(i % 3)};
    // Every other ray aims at a random point of an obstacle or a pole, at a height it has.
    bool aimed_at_thin = false;
    if (i % 2 == 1) {
      Eigen::Vector3d target = from;
      const auto& g = scene.geometry();
      const std::size_t k = static_cast<std::size_t>(
          u01(rng) * static_cast<double>(g.prisms.size() + g.cylinders.size()));
      if (k < g.prisms.size()) {
        const Prism& p = g.prisms[k];
        const Eigen::Vector2d a = p.footprint_M[0], b = p.footprint_M[1], c = p.footprint_M[2];
        const Eigen::Vector2d q = a + (b - a) * u01(rng) + (c - b) * u01(rng);
        target = {q.x(), q.y(), uniform(p.z_bottom_m, p.z_top_m)};
        aimed_at_thin = (c - b).norm() < 0.04 || (b - a).norm() < 0.04;
      } else if (!g.cylinders.empty()) {
        const Cylinder& c = g.cylinders[std::min(k - g.prisms.size(), g.cylinders.size() - 1)];
        target = {c.centre_M.x() + uniform(-0.01, 0.01), c.centre_M.y() + uniform(-0.01, 0.01),
                  uniform(c.z_bottom_m, c.z_top_m)};
      }
      if ((target - from).norm() > 1e-3) ray = RayTo(from, target);
    }
    const double max_range = i % 7 == 0 ? uniform(0.1, 3.0) : 12.0;
    const std::optional<BoxId> exclude = i % 5 == 0 ? std::optional<BoxId>(BoxId(1)) : std::nullopt;
    const Hit hit = Cast(scene, boxes, ray, max_range, exclude);
    const RefResult expected = ReferenceCast(ref, boxes, ray, max_range, exclude);
    ASSERT_TRUE(SameAsReference(hit, expected))
        << "ray " << i << " from " << ray.origin_M.transpose() << " along "
        << ray.direction_M.transpose() << " max " << max_range;
    const Hit brute = CastBruteForce(scene, boxes, ray, max_range, exclude);
    ASSERT_TRUE(SameAsReference(brute, expected)) << "brute force, ray " << i;
    ++counts[static_cast<int>(hit.what)];
    if (aimed_at_thin && hit.what == What::kStatic &&
        std::abs(hit.range_m - expected.statics) < kTol) {
      ++thin_hits;
    }
  }
  // The rays met every kind of surface.
  for (const int c : counts) EXPECT_GT(c, n / 50);
  if (name == "parking_school") {
    EXPECT_GT(thin_hits, n / 200);
  }
}

TEST(Cast, EqualsTheReferenceOnRandomRaysOverTheSmallTown) { CrossCheck("small_town"); }
TEST(Cast, EqualsTheReferenceOnRandomRaysOverTheParkingSchool) { CrossCheck("parking_school"); }
TEST(Cast, EqualsTheReferenceOnRandomRaysOverTheDrivingSchool) { CrossCheck("driving_school"); }

// ---------------------------------------------------------------------------------------------
// Allocation and threads

std::vector<Ray> FullScan(const Eigen::Vector3d& p_ML) {
  std::vector<Ray> rays;
  for (int i = 0; i < 360; ++i)
    rays.push_back(Horizontal(p_ML.x(), p_ML.y(), p_ML.z(), i * kPi / 180));
  return rays;
}

TEST(Cast, AScanAllocatesNothing) {
  const StaticScene scene = StaticScene::FromMap(Shipped("small_town"));
  std::mt19937 rng(3);
  const std::vector<DynamicBox> boxes = RandomBoxes(rng, Shipped("small_town"));
  const std::vector<Ray> rays = FullScan({2.5, 1.85, kLidarHeight});
  std::vector<Hit> hits(rays.size());
  const long before = g_allocations.load();
  CastScan(scene, boxes, rays, 12.0, BoxId(1), hits);
  for (const Ray& r : rays) (void)Cast(scene, boxes, r, 12.0);
  EXPECT_EQ(g_allocations.load() - before, 0);
  int returns = 0;
  for (const Hit& h : hits) returns += h.what != What::kNothing;
  EXPECT_GT(returns, 0);
}

TEST(Cast, ThreadsCastingAtOnceGetTheSameAnswers) {
  const maps::Map map = Shipped("parking_school");
  const StaticScene scene = StaticScene::FromMap(map);
  std::mt19937 rng(4);
  const std::vector<DynamicBox> boxes = RandomBoxes(rng, map);
  std::vector<Ray> rays;
  for (double x = 0.3; x < 3.8; x += 0.5) {
    for (const Ray& r : FullScan({x, 1.3, kLidarHeight})) rays.push_back(r);
  }
  std::vector<Hit> expected(rays.size()), a(rays.size()), b(rays.size());
  CastScan(scene, boxes, rays, 12.0, std::nullopt, expected);
  std::thread ta([&] { CastScan(scene, boxes, rays, 12.0, std::nullopt, a); });
  std::thread tb([&] { CastScan(scene, boxes, rays, 12.0, std::nullopt, b); });
  ta.join();
  tb.join();
  for (std::size_t i = 0; i < rays.size(); ++i) {
    EXPECT_EQ(a[i].range_m, expected[i].range_m);
    EXPECT_EQ(b[i].range_m, expected[i].range_m);
    EXPECT_EQ(b[i].what, expected[i].what);
  }
}

}  // namespace
}  // namespace autodrive::vehicle_sim
