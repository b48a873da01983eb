#include "vehicle_sim/raycast.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "common/error.h"
#include "common/geometry.h"

namespace autodrive::vehicle_sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Margin by which a cell is grown when deciding which faces touch it, so that rounding in the
// traversal never skips a face that passes exactly along a cell boundary (m).
constexpr double kCellMargin = 1e-9;
// The kind of a cell entry, in its top two bits.
constexpr std::uint32_t kEdge = 0;
constexpr std::uint32_t kPole = 1;
constexpr std::uint32_t kCap = 2;
constexpr int kKindShift = 30;
constexpr std::uint32_t kIndexMask = (1u << kKindShift) - 1;
constexpr std::size_t kMaxCells = std::size_t{1} << 26;

// The ray, unpacked once per cast.
struct RayData {
  double ox, oy, oz, dx, dy, dz;
  double dxy2;    // dx^2 + dy^2
  double inv_dz;  // 1 / dz, or 0 when dz == 0 (then caps are never hit)
};

RayData Unpack(const Ray& ray, double max_range_m) {
  const Eigen::Vector3d& o = ray.origin_M;
  const Eigen::Vector3d& d = ray.direction_M;
  AUTODRIVE_CHECK(o.allFinite() && d.allFinite(),
                  "ray origin " << o.transpose() << " direction " << d.transpose());
  AUTODRIVE_CHECK(std::abs(d.squaredNorm() - 1.0) <= 2e-6,
                  "ray direction must be a unit vector, got " << d.transpose());
  AUTODRIVE_CHECK(max_range_m > 0, "max_range_m must be positive, got " << max_range_m);
  RayData r{o.x(), o.y(), o.z(), d.x(), d.y(), d.z(), 0.0, 0.0};
  r.dxy2 = r.dx * r.dx + r.dy * r.dy;
  r.inv_dz = r.dz != 0.0 ? 1.0 / r.dz : 0.0;
  return r;
}

// The side face over edge `e`: the range where the ray's ground projection crosses the edge,
// when the ray is then between the face's heights. Rays parallel to the edge never hit it (its
// neighbours or the caps catch them).
inline bool TestEdge(const internal::GridEdge& e, const RayData& r, double& best) {
  const double den = r.dx * e.ey - r.dy * e.ex;
  if (den == 0.0) return false;
  const double wx = e.ax - r.ox;
  const double wy = e.ay - r.oy;
  const double inv = 1.0 / den;
  const double t = (wx * e.ey - wy * e.ex) * inv;
  if (!(t >= 0.0 && t < best)) return false;
  const double s = (wx * r.dy - wy * r.dx) * inv;
  if (s < 0.0 || s > 1.0) return false;
  const double z = r.oz + t * r.dz;
  if (z < e.z_bottom || z > e.z_top) return false;
  best = t;
  return true;
}

// A vertical cylinder: its side where the ray is between the heights, and its end discs.
inline bool TestPole(const internal::GridPole& p, const RayData& r, double& best) {
  const double fx = r.ox - p.cx;
  const double fy = r.oy - p.cy;
  bool hit = false;
  if (r.dxy2 > 0.0) {
    const double half_b = fx * r.dx + fy * r.dy;
    const double c = fx * fx + fy * fy - p.r2;
    const double disc = half_b * half_b - r.dxy2 * c;
    if (disc < 0.0) return false;  // the ray's projection misses the circle: no side, no disc
    const double sq = std::sqrt(disc);
    for (const double t : {(-half_b - sq) / r.dxy2, (-half_b + sq) / r.dxy2}) {
      if (t >= 0.0 && t < best) {
        const double z = r.oz + t * r.dz;
        if (z >= p.z_bottom && z <= p.z_top) {
          best = t;
          hit = true;
          break;
        }
      }
    }
  }
  if (r.inv_dz == 0.0) return hit;
  for (const double z : {p.z_top, p.z_bottom}) {
    const double t = (z - r.oz) * r.inv_dz;
    if (!(t >= 0.0 && t < best)) continue;
    const double x = fx + t * r.dx;
    const double y = fy + t * r.dy;
    if (x * x + y * y <= p.r2) {
      best = t;
      hit = true;
    }
  }
  return hit;
}

// A prism's top and bottom faces.
inline bool TestCap(const internal::GridCap& c, const Eigen::Vector2d* vertices, const RayData& r,
                    double& best) {
  if (r.inv_dz == 0.0) return false;
  bool hit = false;
  for (const double z : {c.z_top, c.z_bottom}) {
    const double t = (z - r.oz) * r.inv_dz;
    if (!(t >= 0.0 && t < best)) continue;
    if (InsidePolygon(vertices + c.first, c.count, r.ox + t * r.dx, r.oy + t * r.dy)) {
      best = t;
      hit = true;
    }
  }
  return hit;
}

// The oriented boxes, each first rejected by its bounding circle in the ground plane and by
// its bounding sphere's distance, then tested by slabs in its own frame.
void TestBoxes(std::span<const DynamicBox> boxes, const RayData& r, std::optional<BoxId> exclude,
               double& best, Hit& hit) {
  for (const DynamicBox& b : boxes) {
    if (exclude && b.id == *exclude) continue;
    const Eigen::Vector3d c = b.X_MB.translation();
    const double radius2 = b.half_extents_m.squaredNorm();
    const double cx = c.x() - r.ox;
    const double cy = c.y() - r.oy;
    const double cz = c.z() - r.oz;
    // Closest approach of the projected ray (t >= 0) to the centre.
    const double s = r.dxy2 > 0.0 ? std::max(0.0, (cx * r.dx + cy * r.dy) / r.dxy2) : 0.0;
    const double ex = cx - s * r.dx;
    const double ey = cy - s * r.dy;
    if (ex * ex + ey * ey > radius2) continue;
    const double reach = best + std::sqrt(radius2);
    if (cx * cx + cy * cy + cz * cz > reach * reach) continue;
    const Eigen::Matrix3d R = b.X_MB.linear();
    const Eigen::Vector3d w(-cx, -cy, -cz);
    const Eigen::Vector3d p = R.transpose() * w;
    const Eigen::Vector3d v = R.transpose() * Eigen::Vector3d(r.dx, r.dy, r.dz);
    double t_near = -kInf;
    double t_far = kInf;
    bool miss = false;
    for (int i = 0; i < 3; ++i) {
      const double half = b.half_extents_m[i];
      if (v[i] == 0.0) {
        if (std::abs(p[i]) > half) miss = true;
        continue;
      }
      double t1 = (-half - p[i]) / v[i];
      double t2 = (half - p[i]) / v[i];
      if (t1 > t2) std::swap(t1, t2);
      t_near = std::max(t_near, t1);
      t_far = std::min(t_far, t2);
    }
    if (miss || t_near > t_far) continue;
    const double t = t_near >= 0.0 ? t_near : t_far;
    if (t >= 0.0 && t < best) {
      best = t;
      hit.what = Hit::What::kBox;
      hit.box = b.id;
    }
  }
}

// The range over which the ray's ground projection is inside the closed rectangle, clipped to
// t >= 0; false when it never is.
bool ClipToRect(const RayData& r, double x0, double y0, double x1, double y1, double& t_enter,
                double& t_exit) {
  t_enter = 0.0;
  t_exit = kInf;
  const auto slab = [&](double o, double d, double lo, double hi) {
    if (d == 0.0) return o >= lo && o <= hi;
    double t1 = (lo - o) / d;
    double t2 = (hi - o) / d;
    if (t1 > t2) std::swap(t1, t2);
    t_enter = std::max(t_enter, t1);
    t_exit = std::min(t_exit, t2);
    return true;
  };
  return slab(r.ox, r.dx, x0, x1) && slab(r.oy, r.dy, y0, y1) && t_enter <= t_exit;
}

// The flat ground z = 0 over [t_from, t_to): where the ray first is at or below it.
inline bool TestFlatGround(const RayData& r, double t_from, double t_to, double& best) {
  const double limit = std::min(t_to, best);
  if (!(t_from < limit)) return false;
  if (r.oz + t_from * r.dz <= 0.0) {
    best = t_from;
    return true;
  }
  if (r.dz < 0.0) {
    const double t = -r.oz / r.dz;
    if (t < limit) {
      best = t;
      return true;
    }
  }
  return false;
}

// The plane over [t_from, t_to] (t_to included: the root may lie on the far boundary).
inline bool TestPlane(const TerrainModel::Plane& p, const RayData& r, double t_from, double t_to,
                      double& best) {
  const double f0 = r.oz - p.HeightAt(r.ox, r.oy);
  const double f1 = r.dz - (p.dz_dx * r.dx + p.dz_dy * r.dy);
  if (f0 + f1 * t_from <= 0.0) {
    if (!(t_from < best)) return false;
    best = t_from;
    return true;
  }
  if (f1 < 0.0) {
    const double t = -f0 / f1;
    if (t <= t_to && t < best) {
      best = t;
      return true;
    }
  }
  return false;
}

int FloorToInt(double v) { return static_cast<int>(std::floor(v)); }

// Cells [lo, hi] along one axis that a span [a, b] (grown by the margin) touches, clamped.
std::pair<int, int> CellSpan(double a, double b, double origin, double h, int n) {
  const int lo = std::max(0, FloorToInt((a - kCellMargin - origin) / h));
  const int hi = std::min(n - 1, FloorToInt((b + kCellMargin - origin) / h));
  return {lo, hi};
}

// True when segment a -> b touches the rectangle (whose box overlaps the segment's box): the
// rectangle's corners are not all strictly on one side of the segment's line.
bool SegmentTouchesRect(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double x0, double y0,
                        double x1, double y1) {
  const Eigen::Vector2d e = b - a;
  int positive = 0;
  int negative = 0;
  for (const Eigen::Vector2d& q : {Eigen::Vector2d(x0, y0), Eigen::Vector2d(x1, y0),
                                   Eigen::Vector2d(x1, y1), Eigen::Vector2d(x0, y1)}) {
    const double c = e.x() * (q.y() - a.y()) - e.y() * (q.x() - a.x());
    positive += c > 0.0;
    negative += c < 0.0;
  }
  return positive < 4 && negative < 4;
}

// Sutherland-Hodgman: the part of `poly` on the side of the line where keep(p) >= 0.
template <typename Distance>
maps::Polyline ClipHalfPlane(const maps::Polyline& poly, Distance distance) {
  maps::Polyline out;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector2d& a = poly[i];
    const Eigen::Vector2d& b = poly[(i + 1) % poly.size()];
    const double da = distance(a);
    const double db = distance(b);
    if (da >= 0) out.push_back(a);
    if ((da >= 0) != (db >= 0)) out.push_back(a + (b - a) * (da / (da - db)));
  }
  return out;
}

void CheckFinite(double v, const char* what, std::size_t i) {
  AUTODRIVE_THROW_UNLESS(std::isfinite(v),
                         what << " " << i << ": coordinate " << v << " is not finite");
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// TerrainModel

TerrainModel TerrainModel::FromMap(const maps::Map& map) {
  TerrainModel t;
  t.tiles_x_ = map.cols;
  t.tiles_y_ = map.rows;
  t.tile_size_m_ = map.tile_size_m;
  const auto& terrain = map.terrain;
  const auto n = static_cast<std::size_t>(map.rows) * static_cast<std::size_t>(map.cols);
  AUTODRIVE_THROW_UNLESS(terrain.tile_elevation_m.size() == n && terrain.tile_rise_m.size() == n &&
                             terrain.tile_rotation_deg.size() == n,
                         "map " << map.name << ": terrain of " << terrain.tile_elevation_m.size()
                                << " tiles for a grid of " << map.rows << " x " << map.cols);
  t.planes_.resize(n);
  const double T = map.tile_size_m;
  for (int row = 0; row < map.rows; ++row) {
    for (int col = 0; col < map.cols; ++col) {
      const auto i = static_cast<std::size_t>(row * map.cols + col);
      const double base = terrain.tile_elevation_m[i];
      const double rise = terrain.tile_rise_m[i];
      Plane p{0.0, 0.0, base};
      if (rise != 0.0) {
        // maps::TerrainHeight: base + rise * (along / T + 1/2), `along` the offset from the
        // tile's centre along the ramp's local +x (rotated counter-clockwise). Exact cosines
        // for the quarter turns layouts use.
        const int deg = terrain.tile_rotation_deg[i];
        double c = std::cos(deg * kPi / 180.0);
        double s = std::sin(deg * kPi / 180.0);
        if (deg % 90 == 0) {
          constexpr double kCos[] = {1, 0, -1, 0};
          constexpr double kSin[] = {0, 1, 0, -1};
          const auto k = static_cast<std::size_t>(((deg / 90) % 4 + 4) % 4);
          c = kCos[k];
          s = kSin[k];
        }
        const Eigen::Vector2d centre = map.TileCentre({row, col});
        p.dz_dx = rise * c / T;
        p.dz_dy = rise * s / T;
        p.z0_m = base + rise / 2 - p.dz_dx * centre.x() - p.dz_dy * centre.y();
      }
      const int iy = map.rows - 1 - row;
      t.planes_[static_cast<std::size_t>(iy * map.cols + col)] = p;
    }
  }
  return t;
}

const TerrainModel::Plane& TerrainModel::plane(int ix, int iy) const {
  AUTODRIVE_CHECK(ix >= 0 && ix < tiles_x_ && iy >= 0 && iy < tiles_y_,
                  "tile (" << ix << ", " << iy << ") of " << tiles_x_ << " x " << tiles_y_);
  return planes_[static_cast<std::size_t>(iy * tiles_x_ + ix)];
}

double TerrainModel::HeightAt(double x_m, double y_m) const {
  const double w = tiles_x_ * tile_size_m_;
  const double h = tiles_y_ * tile_size_m_;
  if (planes_.empty() || !(x_m >= 0 && y_m >= 0 && x_m <= w && y_m <= h)) return 0.0;
  const int ix = std::min(tiles_x_ - 1, static_cast<int>(x_m / tile_size_m_));
  const int iy = std::min(tiles_y_ - 1, static_cast<int>(y_m / tile_size_m_));
  return plane(ix, iy).HeightAt(x_m, y_m);
}

double TerrainModel::MinHeightUnder(const maps::Polyline& footprint_M) const {
  AUTODRIVE_THROW_UNLESS(!footprint_M.empty(), "MinHeightUnder: empty footprint");
  const double T = tile_size_m_;
  const double w = tiles_x_ * T;
  const double h = tiles_y_ * T;
  double lowest = kInf;
  Eigen::AlignedBox2d box;
  for (const auto& p : footprint_M) {
    box.extend(p);
    // The polygon reaches outside the map, where the ground is at 0.
    if (!(p.x() >= 0 && p.y() >= 0 && p.x() <= w && p.y() <= h)) lowest = 0.0;
  }
  if (planes_.empty()) return 0.0;
  const int ix0 = std::max(0, FloorToInt(box.min().x() / T));
  const int ix1 = std::min(tiles_x_ - 1, FloorToInt(box.max().x() / T));
  const int iy0 = std::max(0, FloorToInt(box.min().y() / T));
  const int iy1 = std::min(tiles_y_ - 1, FloorToInt(box.max().y() / T));
  for (int iy = iy0; iy <= iy1; ++iy) {
    for (int ix = ix0; ix <= ix1; ++ix) {
      const double xl = ix * T, xr = (ix + 1) * T, yb = iy * T, yt = (iy + 1) * T;
      maps::Polyline part = footprint_M;
      part = ClipHalfPlane(part, [&](const Eigen::Vector2d& p) { return p.x() - xl; });
      part = ClipHalfPlane(part, [&](const Eigen::Vector2d& p) { return xr - p.x(); });
      part = ClipHalfPlane(part, [&](const Eigen::Vector2d& p) { return p.y() - yb; });
      part = ClipHalfPlane(part, [&](const Eigen::Vector2d& p) { return yt - p.y(); });
      for (const auto& p : part) lowest = std::min(lowest, plane(ix, iy).HeightAt(p.x(), p.y()));
    }
  }
  return std::isfinite(lowest) ? lowest : 0.0;
}

double TerrainModel::MaxHeight() const {
  double highest = 0.0;
  const double T = tile_size_m_;
  for (int iy = 0; iy < tiles_y_; ++iy) {
    for (int ix = 0; ix < tiles_x_; ++ix) {
      for (const double x : {ix * T, (ix + 1) * T}) {
        for (const double y : {iy * T, (iy + 1) * T}) {
          highest = std::max(highest, plane(ix, iy).HeightAt(x, y));
        }
      }
    }
  }
  return highest;
}

// ---------------------------------------------------------------------------------------------
// Building the scene

Prism PrismOnGround(const TerrainModel& terrain, maps::Polyline footprint_M, double height_m) {
  const double bottom = terrain.MinHeightUnder(footprint_M);
  return {std::move(footprint_M), bottom, bottom + height_m};
}

StaticGeometry GeometryFromMap(const maps::Map& map, const StaticSceneOptions& options) {
  options.Validate();
  StaticGeometry g;
  g.terrain = TerrainModel::FromMap(map);
  for (const auto& o : map.obstacles) {
    g.prisms.push_back(PrismOnGround(g.terrain, o.footprint, o.height_m));
  }
  const auto pole = [&](const Eigen::Vector2d& p, double height_m) {
    const double ground = g.terrain.HeightAt(p.x(), p.y());
    g.cylinders.push_back({p, options.pole_radius_m, ground, ground + height_m});
  };
  for (const auto& h : map.signal_heads) pole(h.X_MH.translation(), options.signal_head_height_m);
  for (const auto& s : map.signs) pole(s.X_MS.translation(), options.sign_height_m);
  return g;
}

StaticScene::StaticScene(StaticGeometry geometry, double cell_size_m)
    : geometry_(std::move(geometry)) {
  Index(cell_size_m);
}

StaticScene StaticScene::FromMap(const maps::Map& map, const StaticSceneOptions& options) {
  return StaticScene(GeometryFromMap(map, options), options.cell_size_m);
}

namespace {

// What the grid must cover: the map's tiles and everything in the geometry, which is checked
// on the way (finite coordinates, z_top >= z_bottom, radii >= 0, footprints of 3 vertices or
// more).
Eigen::AlignedBox2d CheckedBounds(const StaticGeometry& geometry) {
  const TerrainModel& terrain = geometry.terrain;
  Eigen::AlignedBox2d bounds;
  if (terrain.tiles_x() > 0 && terrain.tiles_y() > 0) {
    const double T = terrain.tile_size_m();
    bounds.extend(Eigen::Vector2d(0, 0));
    bounds.extend(Eigen::Vector2d(terrain.tiles_x() * T, terrain.tiles_y() * T));
  }
  for (std::size_t i = 0; i < geometry.prisms.size(); ++i) {
    const Prism& p = geometry.prisms[i];
    AUTODRIVE_THROW_UNLESS(p.footprint_M.size() >= 3, "prism " << i
                                                               << ": a footprint needs at "
                                                                  "least 3 vertices, got "
                                                               << p.footprint_M.size());
    AUTODRIVE_THROW_UNLESS(
        std::isfinite(p.z_bottom_m) && std::isfinite(p.z_top_m) && p.z_top_m >= p.z_bottom_m,
        "prism " << i << ": z_top_m " << p.z_top_m << " must be finite and >= z_bottom_m "
                 << p.z_bottom_m);
    for (const auto& v : p.footprint_M) {
      CheckFinite(v.x(), "prism", i);
      CheckFinite(v.y(), "prism", i);
      bounds.extend(v);
    }
  }
  for (std::size_t i = 0; i < geometry.cylinders.size(); ++i) {
    const Cylinder& c = geometry.cylinders[i];
    CheckFinite(c.centre_M.x(), "cylinder", i);
    CheckFinite(c.centre_M.y(), "cylinder", i);
    AUTODRIVE_THROW_UNLESS(std::isfinite(c.radius_m) && c.radius_m >= 0,
                           "cylinder " << i << ": radius_m must be >= 0, got " << c.radius_m);
    AUTODRIVE_THROW_UNLESS(
        std::isfinite(c.z_bottom_m) && std::isfinite(c.z_top_m) && c.z_top_m >= c.z_bottom_m,
        "cylinder " << i << ": z_top_m " << c.z_top_m << " must be finite and >= z_bottom_m "
                    << c.z_bottom_m);
    bounds.extend(c.centre_M - Eigen::Vector2d::Constant(c.radius_m));
    bounds.extend(c.centre_M + Eigen::Vector2d::Constant(c.radius_m));
  }
  return bounds;
}

// Per cell of an nx x ny grid, the Chebyshev distance (at most 255) to the nearest of the cells
// that have entries, by two chamfer passes.
std::vector<std::uint8_t> ChamferClearance(
    const std::vector<std::pair<std::uint32_t, std::uint32_t>>& entries, int nx, int ny) {
  const auto cell_index = [nx](int ix, int iy) {
    return static_cast<std::size_t>(iy) * static_cast<std::size_t>(nx) +
           static_cast<std::size_t>(ix);
  };
  const auto num_cells = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
  std::vector<int> clear(num_cells, 255);
  for (const auto& entry : entries) clear[entry.first] = 0;
  const auto relax = [&](int ix, int iy, int jx, int jy) {
    if (jx < 0 || jy < 0 || jx >= nx || jy >= ny) return;
    int& c = clear[cell_index(ix, iy)];
    c = std::min(c, clear[cell_index(jx, jy)] + 1);
  };
  for (int iy = 0; iy < ny; ++iy) {
    for (int ix = 0; ix < nx; ++ix) {
      relax(ix, iy, ix - 1, iy);
      relax(ix, iy, ix - 1, iy - 1);
      relax(ix, iy, ix, iy - 1);
      relax(ix, iy, ix + 1, iy - 1);
    }
  }
  for (int iy = ny - 1; iy >= 0; --iy) {
    for (int ix = nx - 1; ix >= 0; --ix) {
      relax(ix, iy, ix + 1, iy);
      relax(ix, iy, ix + 1, iy + 1);
      relax(ix, iy, ix, iy + 1);
      relax(ix, iy, ix - 1, iy + 1);
    }
  }
  std::vector<std::uint8_t> clearance(num_cells);
  for (std::size_t i = 0; i < num_cells; ++i) {
    clearance[i] = static_cast<std::uint8_t>(std::min(clear[i], 255));
  }
  return clearance;
}

}  // namespace

void StaticScene::Index(double requested_cell_m) {
  AUTODRIVE_THROW_UNLESS(
      requested_cell_m >= 0.01 && requested_cell_m <= 10.0,
      "StaticScene: cell size must be in [0.01, 10] m, got " << requested_cell_m);
  const TerrainModel& terrain = geometry_.terrain;
  const double T = terrain.tile_size_m();
  const bool has_tiles = terrain.tiles_x() > 0 && terrain.tiles_y() > 0;
  // Cells divide tiles evenly, so that each cell lies in one tile.
  cell_m_ = requested_cell_m;
  if (has_tiles) cell_m_ = T / std::max(1.0, std::round(T / requested_cell_m));
  const double h = cell_m_;
  const Eigen::AlignedBox2d bounds = CheckedBounds(geometry_);

  planes_.clear();
  for (int iy = 0; iy < terrain.tiles_y(); ++iy) {
    for (int ix = 0; ix < terrain.tiles_x(); ++ix) planes_.push_back(terrain.plane(ix, iy));
  }
  const auto flat = static_cast<std::uint32_t>(planes_.size());
  planes_.push_back({0.0, 0.0, 0.0});
  max_ground_m_ = terrain.MaxHeight();

  edges_.clear();
  poles_.clear();
  caps_.clear();
  cap_vertices_.clear();
  cell_start_.clear();
  cell_items_.clear();
  cell_plane_.clear();
  cell_clearance_.clear();
  nx_ = ny_ = 0;
  x0_ = y0_ = 0.0;
  if (bounds.isEmpty()) return;

  // Whole cells, aligned with the tiles (cell boundaries at integer multiples of h).
  x0_ = std::floor(bounds.min().x() / h + 1e-9) * h;
  y0_ = std::floor(bounds.min().y() / h + 1e-9) * h;
  const double cells_x = std::max(1.0, std::ceil((bounds.max().x() - x0_) / h - 1e-9));
  const double cells_y = std::max(1.0, std::ceil((bounds.max().y() - y0_) / h - 1e-9));
  AUTODRIVE_THROW_UNLESS(cells_x * cells_y <= static_cast<double>(kMaxCells),
                         "StaticScene: a grid of " << cells_x << " x " << cells_y << " cells of "
                                                   << h << " m is too large (limit " << kMaxCells
                                                   << " cells)");
  nx_ = static_cast<int>(cells_x);
  ny_ = static_cast<int>(cells_y);
  const auto num_cells = static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_);

  // The terrain plane of each cell, from its centre.
  cell_plane_.assign(num_cells, flat);
  if (has_tiles) {
    for (int iy = 0; iy < ny_; ++iy) {
      for (int ix = 0; ix < nx_; ++ix) {
        const int tx = FloorToInt((x0_ + (ix + 0.5) * h) / T);
        const int ty = FloorToInt((y0_ + (iy + 0.5) * h) / T);
        if (tx >= 0 && ty >= 0 && tx < terrain.tiles_x() && ty < terrain.tiles_y()) {
          cell_plane_[CellIndex(ix, iy)] = static_cast<std::uint32_t>(ty * terrain.tiles_x() + tx);
        }
      }
    }
  }

  // (cell, entry) pairs, then sorted into cells.
  CellEntries entries;
  for (const Prism& prism : geometry_.prisms) IndexPrism(prism, entries);
  for (const Cylinder& c : geometry_.cylinders) IndexCylinder(c, entries);
  cell_clearance_ = ChamferClearance(entries, nx_, ny_);

  std::sort(entries.begin(), entries.end());  // by cell, then entry: faces before poles and caps
  cell_start_.assign(num_cells + 1, 0);
  for (const auto& [cell, item] : entries) ++cell_start_[cell + 1];
  for (std::size_t i = 0; i < num_cells; ++i) cell_start_[i + 1] += cell_start_[i];
  cell_items_.reserve(entries.size());
  for (const auto& [cell, item] : entries) cell_items_.push_back(item);
}

std::size_t StaticScene::CellIndex(int ix, int iy) const {
  return static_cast<std::size_t>(iy) * static_cast<std::size_t>(nx_) +
         static_cast<std::size_t>(ix);
}

void StaticScene::AddEntry(int ix, int iy, std::uint32_t kind, std::size_t index,
                           CellEntries& entries) const {
  AUTODRIVE_THROW_UNLESS(index <= kIndexMask, "StaticScene: too many faces (" << index << ")");
  entries.emplace_back(static_cast<std::uint32_t>(CellIndex(ix, iy)),
                       (kind << kKindShift) | static_cast<std::uint32_t>(index));
}

bool StaticScene::SegmentTouchesCell(const Eigen::Vector2d& a, const Eigen::Vector2d& b, int ix,
                                     int iy) const {
  const double h = cell_m_;
  return SegmentTouchesRect(a, b, x0_ + ix * h - kCellMargin, y0_ + iy * h - kCellMargin,
                            x0_ + (ix + 1) * h + kCellMargin, y0_ + (iy + 1) * h + kCellMargin);
}

// A prism's side faces into every cell they cross; its caps into every cell the footprint
// touches (crossed by an edge or with its centre inside).
void StaticScene::IndexPrism(const Prism& prism, CellEntries& entries) {
  const double h = cell_m_;
  const maps::Polyline& v = prism.footprint_M;
  const std::size_t n = v.size();
  Eigen::AlignedBox2d box;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& a = v[i];
    const Eigen::Vector2d& b = v[(i + 1) % n];
    box.extend(a);
    const std::size_t index = edges_.size();
    edges_.push_back({a.x(), a.y(), b.x() - a.x(), b.y() - a.y(), prism.z_bottom_m, prism.z_top_m});
    const auto [ix0, ix1] = CellSpan(std::min(a.x(), b.x()), std::max(a.x(), b.x()), x0_, h, nx_);
    const auto [iy0, iy1] = CellSpan(std::min(a.y(), b.y()), std::max(a.y(), b.y()), y0_, h, ny_);
    for (int iy = iy0; iy <= iy1; ++iy) {
      for (int ix = ix0; ix <= ix1; ++ix) {
        if (SegmentTouchesCell(a, b, ix, iy)) AddEntry(ix, iy, kEdge, index, entries);
      }
    }
  }
  const std::size_t cap = caps_.size();
  caps_.push_back({static_cast<std::uint32_t>(cap_vertices_.size()), static_cast<std::uint32_t>(n),
                   prism.z_bottom_m, prism.z_top_m});
  for (const auto& p : v) cap_vertices_.push_back(p);
  const auto [ix0, ix1] = CellSpan(box.min().x(), box.max().x(), x0_, h, nx_);
  const auto [iy0, iy1] = CellSpan(box.min().y(), box.max().y(), y0_, h, ny_);
  for (int iy = iy0; iy <= iy1; ++iy) {
    for (int ix = ix0; ix <= ix1; ++ix) {
      bool touches = InsidePolygon(v.data(), static_cast<std::uint32_t>(n), x0_ + (ix + 0.5) * h,
                                   y0_ + (iy + 0.5) * h);
      for (std::size_t i = 0; i < n && !touches; ++i) {
        touches = SegmentTouchesCell(v[i], v[(i + 1) % n], ix, iy);
      }
      if (touches) AddEntry(ix, iy, kCap, cap, entries);
    }
  }
}

// A pole into every cell its bounding square touches.
void StaticScene::IndexCylinder(const Cylinder& c, CellEntries& entries) {
  const double h = cell_m_;
  const std::size_t index = poles_.size();
  poles_.push_back(
      {c.centre_M.x(), c.centre_M.y(), c.radius_m * c.radius_m, c.z_bottom_m, c.z_top_m});
  const auto [ix0, ix1] =
      CellSpan(c.centre_M.x() - c.radius_m, c.centre_M.x() + c.radius_m, x0_, h, nx_);
  const auto [iy0, iy1] =
      CellSpan(c.centre_M.y() - c.radius_m, c.centre_M.y() + c.radius_m, y0_, h, ny_);
  for (int iy = iy0; iy <= iy1; ++iy) {
    for (int ix = ix0; ix <= ix1; ++ix) AddEntry(ix, iy, kPole, index, entries);
  }
}

// ---------------------------------------------------------------------------------------------
// Casting

Hit Cast(const StaticScene& scene, std::span<const DynamicBox> boxes, const Ray& ray,
         double max_range_m, std::optional<BoxId> exclude) {
  const RayData r = Unpack(ray, max_range_m);
  Hit hit;
  double best = max_range_m;
  TestBoxes(boxes, r, exclude, best, hit);
  // Each test lowers `best` only for a strictly nearer hit, so the last to lower it wins.
  const auto mark = [&hit](bool nearer, Hit::What what) {
    if (nearer) hit.what = what;
  };
  // No ground can be reached by a ray that starts above the highest ground and does not descend.
  const bool ground_possible = !(r.dz >= 0.0 && r.oz > scene.max_ground_m_);
  const double h = scene.cell_m_;
  double t_enter = kInf;
  double t_exit = kInf;
  const bool in_grid =
      scene.nx_ > 0 && ClipToRect(r, scene.x0_, scene.y0_, scene.x0_ + scene.nx_ * h,
                                  scene.y0_ + scene.ny_ * h, t_enter, t_exit);
  if (!in_grid) t_enter = t_exit = kInf;
  // Flat ground before the grid.
  if (ground_possible) mark(TestFlatGround(r, 0.0, t_enter, best), Hit::What::kTerrain);

  if (in_grid && t_enter < best) {
    const double inv_h = 1.0 / h;
    int ix = std::clamp(FloorToInt((r.ox + t_enter * r.dx - scene.x0_) * inv_h), 0, scene.nx_ - 1);
    int iy = std::clamp(FloorToInt((r.oy + t_enter * r.dy - scene.y0_) * inv_h), 0, scene.ny_ - 1);
    const int step_x = r.dx > 0.0 ? 1 : -1;
    const int step_y = r.dy > 0.0 ? 1 : -1;
    const int far_x = r.dx > 0.0 ? 1 : 0;
    const int far_y = r.dy > 0.0 ? 1 : 0;
    const double inv_dx = r.dx != 0.0 ? 1.0 / r.dx : 0.0;
    const double inv_dy = r.dy != 0.0 ? 1.0 / r.dy : 0.0;
    const std::uint32_t* items = scene.cell_items_.data();
    const std::uint32_t* starts = scene.cell_start_.data();
    const Eigen::Vector2d* cap_vertices = scene.cap_vertices_.data();
    double t_in = t_enter;
    while (true) {
      if (!ground_possible) {
        // The cells within `clear - 1` of this one are empty: leave their square at once.
        const int clear = scene.cell_clearance_[static_cast<std::size_t>(iy) *
                                                    static_cast<std::size_t>(scene.nx_) +
                                                static_cast<std::size_t>(ix)];
        if (clear > 1) {
          const int k = clear - 1;
          const double tx = r.dx != 0.0
                                ? (scene.x0_ + (ix + (r.dx > 0.0 ? k + 1 : -k)) * h - r.ox) * inv_dx
                                : kInf;
          const double ty = r.dy != 0.0
                                ? (scene.y0_ + (iy + (r.dy > 0.0 ? k + 1 : -k)) * h - r.oy) * inv_dy
                                : kInf;
          const double t_jump = std::min({tx, ty, t_exit});
          if (best <= t_jump || t_jump >= t_exit) break;
          // Into the cell beyond the square, along the side the ray leaves by.
          if (tx < ty) {
            const int jy = FloorToInt((r.oy + t_jump * r.dy - scene.y0_) * inv_h);
            ix += step_x * (k + 1);
            iy = std::clamp(jy, iy - k, iy + k);
          } else {
            const int jx = FloorToInt((r.ox + t_jump * r.dx - scene.x0_) * inv_h);
            iy += step_y * (k + 1);
            ix = std::clamp(jx, ix - k, ix + k);
          }
          if (ix < 0 || ix >= scene.nx_ || iy < 0 || iy >= scene.ny_) break;
          t_in = t_jump;
          continue;
        }
      }
      const double t_next_x = r.dx != 0.0 ? (scene.x0_ + (ix + far_x) * h - r.ox) * inv_dx : kInf;
      const double t_next_y = r.dy != 0.0 ? (scene.y0_ + (iy + far_y) * h - r.oy) * inv_dy : kInf;
      const double t_out = std::min({t_next_x, t_next_y, t_exit});
      const auto cell = static_cast<std::size_t>(iy) * static_cast<std::size_t>(scene.nx_) +
                        static_cast<std::size_t>(ix);
      if (ground_possible) {
        mark(TestPlane(scene.planes_[scene.cell_plane_[cell]], r, std::max(t_in, 0.0), t_out, best),
             Hit::What::kTerrain);
      }
      bool nearer = false;
      for (std::uint32_t k = starts[cell]; k < starts[cell + 1]; ++k) {
        const std::uint32_t item = items[k];
        const std::uint32_t index = item & kIndexMask;
        switch (item >> kKindShift) {
          case kEdge:
            nearer |= TestEdge(scene.edges_[index], r, best);
            break;
          case kPole:
            nearer |= TestPole(scene.poles_[index], r, best);
            break;
          default:
            nearer |= TestCap(scene.caps_[index], cap_vertices, r, best);
            break;
        }
      }
      mark(nearer, Hit::What::kStatic);
      // Every hit nearer than this cell's far boundary lies in a cell already walked.
      if (best <= t_out || t_out >= t_exit) break;
      if (t_next_x < t_next_y) {
        ix += step_x;
        if (ix < 0 || ix >= scene.nx_) break;
      } else {
        iy += step_y;
        if (iy < 0 || iy >= scene.ny_) break;
      }
      t_in = t_out;
    }
  }
  // Flat ground after the grid.
  if (ground_possible && in_grid) mark(TestFlatGround(r, t_exit, kInf, best), Hit::What::kTerrain);
  if (hit.what == Hit::What::kNothing) return hit;
  hit.range_m = best;
  if (hit.what != Hit::What::kBox) hit.box.reset();
  return hit;
}

void CastScan(const StaticScene& scene, std::span<const DynamicBox> boxes,
              std::span<const Ray> rays, double max_range_m, std::optional<BoxId> exclude,
              std::span<Hit> hits) {
  AUTODRIVE_CHECK(rays.size() == hits.size(),
                  rays.size() << " rays but room for " << hits.size() << " hits");
  for (std::size_t i = 0; i < rays.size(); ++i) {
    hits[i] = Cast(scene, boxes, rays[i], max_range_m, exclude);
  }
}

Hit CastBruteForce(const StaticScene& scene, std::span<const DynamicBox> boxes, const Ray& ray,
                   double max_range_m, std::optional<BoxId> exclude) {
  const RayData r = Unpack(ray, max_range_m);
  Hit hit;
  double best = max_range_m;
  TestBoxes(boxes, r, exclude, best, hit);
  const auto mark = [&hit](bool nearer, Hit::What what) {
    if (nearer) hit.what = what;
  };
  for (const auto& e : scene.edges_) mark(TestEdge(e, r, best), Hit::What::kStatic);
  for (const auto& p : scene.poles_) mark(TestPole(p, r, best), Hit::What::kStatic);
  for (const auto& c : scene.caps_) {
    mark(TestCap(c, scene.cap_vertices_.data(), r, best), Hit::What::kStatic);
  }
  const TerrainModel& terrain = scene.geometry_.terrain;
  const double T = terrain.tile_size_m();
  for (int iy = 0; iy < terrain.tiles_y(); ++iy) {
    for (int ix = 0; ix < terrain.tiles_x(); ++ix) {
      double t0 = 0;
      double t1 = 0;
      if (ClipToRect(r, ix * T, iy * T, (ix + 1) * T, (iy + 1) * T, t0, t1)) {
        mark(TestPlane(terrain.plane(ix, iy), r, t0, t1, best), Hit::What::kTerrain);
      }
    }
  }
  // Flat ground outside the map, before and after the ray crosses it.
  double t0 = kInf;
  double t1 = kInf;
  if (terrain.tiles_x() == 0 || terrain.tiles_y() == 0 ||
      !ClipToRect(r, 0, 0, terrain.tiles_x() * T, terrain.tiles_y() * T, t0, t1)) {
    t0 = t1 = kInf;
  }
  mark(TestFlatGround(r, 0.0, t0, best), Hit::What::kTerrain);
  mark(TestFlatGround(r, t1, kInf, best), Hit::What::kTerrain);
  if (hit.what == Hit::What::kNothing) return hit;
  hit.range_m = best;
  if (hit.what != Hit::What::kBox) hit.box.reset();
  return hit;
}

}  // namespace autodrive::vehicle_sim
