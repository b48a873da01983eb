#pragma once
/// @file
/// A fast 3-D ray caster for the simulated sensors: the 2-D LIDAR (RPLIDAR A1: 360 beams,
/// 0.15-12 m, in a plane 0.1757 m above the ground on the car, tilted with the car on ramps)
/// and later the cameras.
///
/// Frame and units: everything is in the map frame M of `maps::Map` (origin at the south-west
/// corner of the layout's grid, x east, y north, z up), in metres. A ray is an origin and a unit
/// direction; a hit is reported as the distance along the ray (the range, metres).
///
/// What a ray hits, in a `StaticScene` built once per map plus the `DynamicBox`es of the frame:
/// - static prisms: vertical extrusions of a polygon footprint between two heights, with their
///   side faces and their top and bottom faces: the map's obstacles (walls and boxes, standing
///   on the lowest ground under their footprint) and any unmapped obstacle the caller adds;
/// - static vertical cylinders with their end discs: the poles of the traffic lights (signal
///   heads) and of the signs;
/// - the terrain: the piecewise planar height field of the map's tiles (flat tiles and ramps;
///   neighbouring tiles at different heights meet in vertical steps), and the plane z = 0
///   outside the map. A ray hits the terrain where it first reaches or goes below the ground;
///   a ray whose origin is at or below the ground hits it at range 0;
/// - dynamic oriented boxes (vehicles and background traffic), given anew for every cast; one
///   of them (the vehicle carrying the sensor) can be excluded.
/// Prisms, cylinders and boxes are closed surfaces: a ray is stopped by any of their faces,
/// including, for a ray that starts inside one, the face where it leaves.
///
/// Cost: the static prisms' faces and the cylinders are indexed in a uniform 2-D grid over the
/// map (cells of about 0.1 m, each listing the faces that touch it); a cast walks the cells
/// along the ray's ground projection (Amanatides-Woo) and stops at the first cell that holds a
/// hit nearer than its far boundary, so its cost grows with the distance travelled in cells and
/// the faces met there, not with the size of the scene. A ray that cannot reach the ground
/// (above the highest ground and not descending, as LIDAR beams on flat ground are) jumps over
/// squares of empty cells; other rays test the terrain analytically in each cell they walk (one
/// plane per tile). Dynamic boxes are tested one by one, each first rejected by its bounding
/// circle. A cast allocates nothing and changes nothing: `Cast` may be called on one scene from
/// many threads at once. On the small town with 10 vehicles one core casts about 4-5 million
/// LIDAR rays per second (`autodrive-bench-raycast`); building the scene takes well under a
/// millisecond.
///
///     const StaticScene scene = StaticScene::FromMap(map);
///     const Hit hit = Cast(scene, boxes, {p_ML, d_M}, 12.0, own_box_id);
///     if (hit.what != Hit::What::kNothing) range_m = hit.range_m;

#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/config.h"
#include "common/ids.h"
#include "maps/map.h"

namespace autodrive::vehicle_sim {

namespace internal {
struct BoxIdTag {
  static constexpr std::string_view kName = "BoxId";
};
/// A prism's side face in the grid: the vertical quad over the edge a -> a + e, between two
/// heights (m, map frame).
struct GridEdge {
  double ax, ay, ex, ey, z_bottom, z_top;
};
/// A cylinder in the grid: centre, squared radius (m^2), heights.
struct GridPole {
  double cx, cy, r2, z_bottom, z_top;
};
/// A prism's top and bottom faces in the grid: its footprint, vertices [first, first + count)
/// of the scene's cap vertices, at two heights.
struct GridCap {
  std::uint32_t first, count;
  double z_bottom, z_top;
};
}  // namespace internal

/// The id of a dynamic box: a simulated vehicle or a SUMO car, chosen by the caller.
using BoxId = Id<internal::BoxIdTag>;

/// A ray: origin `origin_M` (m) and unit direction `direction_M`, map frame. Points on the ray
/// are `origin_M + t * direction_M` for t >= 0, t being the range in metres.
struct Ray {
  Eigen::Vector3d origin_M = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction_M = Eigen::Vector3d::UnitX();  ///< unit length (within 1e-6)
};

/// What a ray met first.
struct Hit {
  enum class What {
    kNothing,  ///< nothing nearer than the maximum range
    kStatic,   ///< a static prism (wall, box, unmapped obstacle) or cylinder (pole)
    kTerrain,  ///< the ground
    kBox,      ///< a dynamic box; `box` says which
  };
  /// Distance from the ray's origin to the hit (m); +infinity for `kNothing`.
  double range_m = std::numeric_limits<double>::infinity();
  What what = What::kNothing;
  std::optional<BoxId> box;  ///< set for `kBox` only
};

/// A moving oriented box (a vehicle): frame B at the box's centre, axes along its edges.
struct DynamicBox {
  BoxId id;
  Eigen::Isometry3d X_MB = Eigen::Isometry3d::Identity();    ///< the box's pose in the map frame
  Eigen::Vector3d half_extents_m = Eigen::Vector3d::Zero();  ///< along B's x, y, z (m), >= 0
};

/// A static vertical prism: the polygon `footprint_M` (map frame, m; a simple polygon of at
/// least 3 vertices, either orientation, not closed by repeating the first vertex) extruded
/// from `z_bottom_m` up to `z_top_m`.
struct Prism {
  maps::Polyline footprint_M;
  double z_bottom_m = 0.0;
  double z_top_m = 0.0;
};

/// A static vertical cylinder (a pole): centre `centre_M` (map frame, m) and radius, from
/// `z_bottom_m` up to `z_top_m`.
struct Cylinder {
  Eigen::Vector2d centre_M = Eigen::Vector2d::Zero();
  double radius_m = 0.01;
  double z_bottom_m = 0.0;
  double z_top_m = 0.0;
};

/// The ground as one plane per map tile, z = 0 outside the map: the same heights as
/// `maps::TerrainHeight`, as planes so that a ray can be tested analytically. Copyable value.
class TerrainModel {
 public:
  /// A plane z = z0_m + dz_dx * x + dz_dy * y (map frame, m).
  struct Plane {
    double dz_dx = 0.0;
    double dz_dy = 0.0;
    double z0_m = 0.0;
    [[nodiscard]] double HeightAt(double x_m, double y_m) const {
      return z0_m + dz_dx * x_m + dz_dy * y_m;
    }
  };

  /// Flat ground, z = 0 everywhere.
  TerrainModel() = default;

  /// The terrain of `map` (its tile elevations and ramps).
  [[nodiscard]] static TerrainModel FromMap(const maps::Map& map);

  /// Tiles along x (columns) and y (rows, counted from the south).
  [[nodiscard]] int tiles_x() const { return tiles_x_; }
  [[nodiscard]] int tiles_y() const { return tiles_y_; }
  [[nodiscard]] double tile_size_m() const { return tile_size_m_; }
  /// The plane of the tile in column `ix` and row `iy` counted from the south (map row
  /// `rows - 1 - iy`), covering [ix T, (ix+1) T] x [iy T, (iy+1) T].
  [[nodiscard]] const Plane& plane(int ix, int iy) const;

  /// Height of the ground at (x, y) (m): the tile's plane inside the map (on a tile edge, the
  /// tile to the east or north, as `maps::TerrainHeight`), 0 outside.
  [[nodiscard]] double HeightAt(double x_m, double y_m) const;
  /// The lowest ground under the polygon `footprint_M` (m), over every tile it touches (at a
  /// step, the lower side counts).
  [[nodiscard]] double MinHeightUnder(const maps::Polyline& footprint_M) const;
  /// The highest ground anywhere (m), at least 0 (the ground outside the map).
  [[nodiscard]] double MaxHeight() const;

 private:
  int tiles_x_ = 0;
  int tiles_y_ = 0;
  double tile_size_m_ = 1.0;
  std::vector<Plane> planes_;  ///< row-major from the south-west tile, tiles_x_ per row
};

/// Parameters of the static scene that the map does not give.
struct StaticSceneOptions {
  /// Edge of a grid cell (m). The cell actually used divides the map's tile size evenly: the
  /// tile size over round(tile size / this), so that every cell lies in one tile.
  double cell_size_m = 0.1;
  /// Radius of the poles of signal heads and signs (m).
  double pole_radius_m = 0.01;
  /// Height of a signal head's pole above the ground (m).
  double signal_head_height_m = 0.21;
  /// Height of a sign's pole above the ground (m).
  double sign_height_m = 0.15;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("cell_size_m", cell_size_m, config::Range{0.01, 10.0});
    a.Optional("pole_radius_m", pole_radius_m, config::Range{0.001, 1.0});
    a.Optional("signal_head_height_m", signal_head_height_m, config::Range{0.0, 10.0});
    a.Optional("sign_height_m", sign_height_m, config::Range{0.0, 10.0});
  }
  /// Throws `InputError` naming the field and value when one is out of the ranges above.
  void Validate() const;
  bool operator==(const StaticSceneOptions&) const = default;
};

/// What a static scene holds, before it is indexed: plain data that the caller may edit (add
/// unmapped obstacles, move walls) before building a `StaticScene` from it.
struct StaticGeometry {
  std::vector<Prism> prisms;
  std::vector<Cylinder> cylinders;
  TerrainModel terrain;
};

/// The static geometry of `map`: every obstacle as a prism standing on the lowest ground under
/// its footprint (`TerrainModel::MinHeightUnder`; `maps::WriteMeshObj` takes the ground at its
/// first corner instead, the same on flat tiles) up to that plus its height; every signal head
/// and sign as a pole of `options`' radius and height standing on the ground at its position;
/// and the map's terrain. Throws `InputError` for bad options.
[[nodiscard]] StaticGeometry GeometryFromMap(const maps::Map& map,
                                             const StaticSceneOptions& options = {});

/// A prism of height `height_m` standing on the lowest ground under `footprint_M`.
[[nodiscard]] Prism PrismOnGround(const TerrainModel& terrain, maps::Polyline footprint_M,
                                  double height_m);

/// The static world a ray can hit, indexed for fast casting: immutable once built (to change it,
/// edit a `StaticGeometry` and build a new scene; a build of a lab map takes about a
/// millisecond). A copyable and movable value; const methods and `Cast` are thread-safe.
class StaticScene {
 public:
  /// Indexes `geometry` in a grid of cells of `cell_size_m` (adjusted to divide the terrain's
  /// tile size, see `StaticSceneOptions::cell_size_m`) covering the map and every prism and
  /// cylinder. Throws `InputError` for a prism with fewer than 3 vertices, a non-finite
  /// coordinate, z_top < z_bottom, a negative radius, a cell size out of [0.01, 10] m, or a grid
  /// of more than 2^26 cells.
  StaticScene(StaticGeometry geometry, double cell_size_m);

  /// The scene of `map`: `StaticScene(GeometryFromMap(map, options), options.cell_size_m)`.
  [[nodiscard]] static StaticScene FromMap(const maps::Map& map,
                                           const StaticSceneOptions& options = {});

  /// What was indexed.
  [[nodiscard]] const StaticGeometry& geometry() const { return geometry_; }
  /// The cell size used (m).
  [[nodiscard]] double cell_size_m() const { return cell_m_; }
  /// Cells along x and y.
  [[nodiscard]] int cells_x() const { return nx_; }
  [[nodiscard]] int cells_y() const { return ny_; }
  /// The grid's south-west corner (m, map frame).
  [[nodiscard]] Eigen::Vector2d grid_origin_M() const { return {x0_, y0_}; }
  /// Entries over all cells (a face or pole listed in k cells counts k times).
  [[nodiscard]] std::size_t num_cell_entries() const { return cell_items_.size(); }

 private:
  friend Hit Cast(const StaticScene& scene, std::span<const DynamicBox> boxes, const Ray& ray,
                  double max_range_m, std::optional<BoxId> exclude);
  friend Hit CastBruteForce(const StaticScene& scene, std::span<const DynamicBox> boxes,
                            const Ray& ray, double max_range_m, std::optional<BoxId> exclude);

  /// (cell, entry) pairs, the entry's kind in its top 2 bits.
  using CellEntries = std::vector<std::pair<std::uint32_t, std::uint32_t>>;

  void Index(double requested_cell_m);
  void IndexPrism(const Prism& prism, CellEntries& entries);
  void IndexCylinder(const Cylinder& c, CellEntries& entries);
  [[nodiscard]] std::size_t CellIndex(int ix, int iy) const;
  void AddEntry(int ix, int iy, std::uint32_t kind, std::size_t index, CellEntries& entries) const;
  /// Whether segment a -> b touches cell (ix, iy), grown by a rounding margin.
  [[nodiscard]] bool SegmentTouchesCell(const Eigen::Vector2d& a, const Eigen::Vector2d& b, int ix,
                                        int iy) const;

  StaticGeometry geometry_;
  std::vector<internal::GridEdge> edges_;
  std::vector<internal::GridPole> poles_;
  std::vector<internal::GridCap> caps_;
  std::vector<Eigen::Vector2d> cap_vertices_;
  std::vector<TerrainModel::Plane> planes_;  ///< the terrain's tiles, then z = 0
  double max_ground_m_ = 0.0;
  // The grid: cell (ix, iy) covers [x0 + ix h, x0 + (ix+1) h] x [y0 + iy h, ...], row-major.
  double x0_ = 0.0, y0_ = 0.0, cell_m_ = 0.1;
  int nx_ = 0, ny_ = 0;
  std::vector<std::uint32_t> cell_start_;  ///< nx * ny + 1 offsets into cell_items_
  std::vector<std::uint32_t> cell_items_;  ///< kind in the top 2 bits, index below
  std::vector<std::uint32_t> cell_plane_;  ///< index into planes_ per cell
  /// Per cell, the Chebyshev distance in cells to the nearest cell with entries (0 for such a
  /// cell, at most 255): the cells nearer than that are empty, so a ray that cannot reach the
  /// ground jumps over them.
  std::vector<std::uint8_t> cell_clearance_;
};

/// The first thing `ray` meets within `max_range_m` (m, > 0; hits at a range of exactly
/// `max_range_m` or more are not reported): a static prism or pole of `scene`, the terrain, or
/// one of `boxes` other than the one whose id is `exclude`. When two surfaces are hit at the
/// same range (to rounding), either may be reported; a ray that runs exactly along a side face
/// (parallel to it in the ground plane) is not stopped by it. Allocation-free and thread-safe.
/// Aborts (a programmer error) when the direction is not of unit length within 1e-6, the origin is
/// not finite or `max_range_m` is not positive.
[[nodiscard]] Hit Cast(const StaticScene& scene, std::span<const DynamicBox> boxes, const Ray& ray,
                       double max_range_m, std::optional<BoxId> exclude = std::nullopt);

/// `Cast` for each of `rays`, into `hits` (same size, checked).
void CastScan(const StaticScene& scene, std::span<const DynamicBox> boxes,
              std::span<const Ray> rays, double max_range_m, std::optional<BoxId> exclude,
              std::span<Hit> hits);

/// Even-odd test of (x, y) against the polygon v[0..n) (n >= 1): inside or not, for a point
/// on no edge.
inline bool InsidePolygon(const Eigen::Vector2d* v, std::uint32_t n, double x, double y) {
  bool inside = false;
  for (std::uint32_t i = 0, j = n - 1; i < n; j = i++) {
    const Eigen::Vector2d& a = v[i];
    const Eigen::Vector2d& b = v[j];
    if ((a.y() > y) != (b.y() > y) && x < (b.x() - a.x()) * (y - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

/// The same answer as `Cast` (to rounding) without the grid: every face, pole, tile and box is
/// tested. For tests and benchmarks; its cost grows with the size of the scene.
[[nodiscard]] Hit CastBruteForce(const StaticScene& scene, std::span<const DynamicBox> boxes,
                                 const Ray& ray, double max_range_m,
                                 std::optional<BoxId> exclude = std::nullopt);

}  // namespace autodrive::vehicle_sim
