#include "vehicle_sim/renderer.h"

#include <apriltag/apriltag.h>
#include <immintrin.h>
#include <sys/mman.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>
#include <random>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "common/camera/tag_family.h"
#include "common/error.h"
#include "maps/map.h"
#include "maps/render.h"

namespace autodrive::vehicle_sim {

namespace internal {

/// A tag family's bitmap of one tag: `total` x `total` cells, row-major from the top-left,
/// 1 for white.
struct TagBitmap {
  int total = 0;
  int at_border = 0;
  std::vector<std::uint8_t> white;
};

/// The ground's picture and its mip pyramid in one RGB atlas image, so that one `cv::remap`
/// samples every pixel at its own level: level 0 at the atlas' left, levels 1, 2, ... stacked
/// down a column to its right. Level k's texel (i, j) covers level 0's texels
/// [2^k i, 2^k (i + 1)) x [2^k j, 2^k (j + 1)); every level has a border of the lab's floor at
/// least a texel wide, and a patch of the lab's walls sits below the last level.
struct GroundPyramid {
  double texel_m = 0.002;
  double x0_m = 0.0;  ///< map x of level 0's left edge
  double y1_m = 0.0;  ///< map y of level 0's top edge
  struct Level {
    int w = 0, h = 0;  ///< texels
    int x = 0, y = 0;  ///< where it is in the atlas
  };
  std::vector<Level> levels;
  cv::Mat atlas;  ///< CV_8UC3, R G B; its pixels in `atlas_memory`
  /// Aligned to 2 MiB and advised to the kernel as huge pages: a camera's rows walk the atlas
  /// in any direction, and with 4 KiB pages nearly every texel read would miss the TLB.
  std::unique_ptr<std::uint8_t, decltype(&std::free)> atlas_memory{nullptr, &std::free};
  Eigen::Vector2f walls{0, 0};  ///< atlas coordinates of a texel of the walls' colour
  cv::Mat atlas32;              ///< the atlas as R G B X words (CV_8UC4), for the AVX2 sampler
  bool avx2 = false;  ///< the AVX2 sampler may be used (the CPU has it and the options allow)
};

/// What is drawn on a face.
enum class Decal : std::uint8_t {
  kNone,
  kTag,           ///< the part's tag bitmap over the whole face (+z)
  kLamps,         ///< a signal head's three lamps (+x face)
  kVehicleFront,  ///< headlights and front indicators (+x face)
  kVehicleRear,   ///< tail lights and rear indicators (-x face)
  kSign,          ///< a sign's disc (+x face)
  kTrafficEnds,   ///< a background object's lamps: front (+x face) and rear (-x face)
};

/// A solid part: a box (half extents) or a vertical cylinder (radius, half height) in its own
/// frame B.
struct RenderPart {
  bool cylinder = false;
  Eigen::Matrix3d R_MB = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_MB = Eigen::Vector3d::Zero();
  Eigen::Vector3d half = Eigen::Vector3d::Zero();  ///< box: half extents; cylinder: r, r, hz
  Rgb colour;
  Decal decal = Decal::kNone;
  const TagBitmap* tag = nullptr;
  int head = -1;     ///< kLamps: index of the head in the map
  Rgb decal_colour;  ///< kSign: the disc's colour
  /// Vehicles: bit 0 headlights, 1 left, 2 right indicator lit now, 3 brake lights.
  std::uint8_t lights = 0;
  std::array<double, 3> lamp_z{};  ///< kLamps: heights of red, yellow, green in B
  double lamp_radius = 0.0;
  /// A tile of raised or sloping ground: the plane z' = a x' + b y' + c in B (axes along the
  /// map's), over the square |x'|, |y'| <= half.x(), textured with the ground's picture.
  bool terrain = false;
  float a = 0, b = 0, c = 0;
};

}  // namespace internal

using internal::Decal;
using internal::GroundPyramid;
using internal::RenderPart;
using internal::TagBitmap;

namespace {

constexpr Rgb kFloor{150, 146, 140};     // the lab's floor around the map
constexpr Rgb kLabWalls{208, 210, 214};  // above the horizon
constexpr Rgb kWallColour{128, 128, 128};
constexpr Rgb kBoxColour{255, 140, 0};
constexpr Rgb kUnmappedColour{170, 120, 70};
constexpr Rgb kPoleColour{90, 90, 95};
constexpr Rgb kHeadColour{25, 25, 25};
constexpr Rgb kWheelColour{20, 20, 20};
constexpr Rgb kLidarColour{40, 40, 45};
constexpr Rgb kPlateColour{255, 255, 255};
constexpr Rgb kTagBlack{0, 0, 0};
constexpr Rgb kTerrainSide{150, 160, 140};
constexpr Rgb kUnderbody{30, 30, 32};  // a background object's wheels and the shade under it

TagBitmap MakeTagBitmap(const TagSpec& spec) {
  const camera::TagFamily family(spec.family);
  family.CheckId(spec.id);
  image_u8_t* image = apriltag_to_image(family.get(), spec.id);
  TagBitmap bitmap;
  bitmap.total = family.total_width();
  bitmap.at_border = family.width_at_border();
  bitmap.white.resize(static_cast<std::size_t>(bitmap.total * bitmap.total));
  for (int y = 0; y < bitmap.total; ++y) {
    for (int x = 0; x < bitmap.total; ++x) {
      bitmap.white[static_cast<std::size_t>(y * bitmap.total + x)] =
          image->buf[y * image->stride + x] > 127 ? 1 : 0;
    }
  }
  image_u8_destroy(image);
  return bitmap;
}

GroundPyramid MakeGround(const maps::Map& map, double texel_m, bool allow_avx2) {
  AUTODRIVE_THROW_UNLESS(std::isfinite(texel_m) && texel_m > 0,
                         "ground_texel_m must be positive, got " << texel_m);
  // Drawn at twice the resolution without anti-aliasing and averaged down: the road's regions
  // of neighbouring tiles then meet with no seam, which anti-aliasing each would leave.
  maps::RenderOptions options;
  options.pixels_per_tile = 2 * map.tile_size_m / texel_m;
  options.margin_px = 0;
  options.ground_only = true;
  options.antialias = false;
  AUTODRIVE_THROW_UNLESS(options.pixels_per_tile >= 8 && options.pixels_per_tile <= 1000,
                         "ground_texel_m " << texel_m << " gives " << options.pixels_per_tile / 2
                                           << " px per tile of " << map.tile_size_m
                                           << " m; it must give 4 to 500");
  const maps::Picture fine = maps::RenderPicture(map, options);
  maps::Picture picture{fine.width_px / 2, fine.height_px / 2, {}};
  picture.rgb.resize(static_cast<std::size_t>(picture.width_px) *
                     static_cast<std::size_t>(picture.height_px) * 3);
  cv::resize(
      cv::Mat(fine.height_px, fine.width_px, CV_8UC3, const_cast<std::uint8_t*>(fine.rgb.data())),
      cv::Mat(picture.height_px, picture.width_px, CV_8UC3, picture.rgb.data()),
      cv::Size(picture.width_px, picture.height_px), 0, 0, cv::INTER_AREA);
  GroundPyramid g;
  g.texel_m = 2 * map.tile_size_m / options.pixels_per_tile;
  // A border of the lab's floor, and a size divisible by 2^(levels-1), so that every level
  // lines up with level 0.
  constexpr int kLevels = 8;
  constexpr int kAlign = 1 << (kLevels - 1);
  // The border is as wide as a texel of the top level, so that every level's edge texels
  // are the floor's colour and sampling clamps to it.
  constexpr int kBorder = kAlign;
  const int w = (picture.width_px + 2 * kBorder + kAlign - 1) / kAlign * kAlign;
  const int h = (picture.height_px + 2 * kBorder + kAlign - 1) / kAlign * kAlign;
  g.x0_m = -kBorder * g.texel_m;
  g.y1_m = map.rows * map.tile_size_m + kBorder * g.texel_m;
  cv::Mat level0(h, w, CV_8UC3, cv::Scalar(kFloor.r, kFloor.g, kFloor.b));
  cv::Mat(picture.height_px, picture.width_px, CV_8UC3,
          const_cast<std::uint8_t*>(picture.rgb.data()))
      .copyTo(level0(cv::Rect(kBorder, kBorder, picture.width_px, picture.height_px)));
  std::vector<cv::Mat> levels{level0};
  while (static_cast<int>(levels.size()) < kLevels && levels.back().cols >= 2 &&
         levels.back().rows >= 2) {
    cv::Mat next;
    cv::resize(levels.back(), next, cv::Size(levels.back().cols / 2, levels.back().rows / 2), 0, 0,
               cv::INTER_AREA);
    levels.push_back(next);
  }
  // Level 0, then the others down a column to its right, then the walls' patch.
  int y = 0;
  for (std::size_t k = 0; k < levels.size(); ++k) {
    GroundPyramid::Level l{levels[k].cols, levels[k].rows, k == 0 ? 0 : w, k == 0 ? 0 : y};
    if (k > 0) y += l.h;
    g.levels.push_back(l);
  }
  const int atlas_w = w + levels[1].cols;
  const int atlas_h = std::max(h, y) + 2;  // the bottom two rows: the walls' patch
  AUTODRIVE_THROW_UNLESS(atlas_w < 32000 && atlas_h < 32000,
                         "the ground's picture at " << texel_m << " m a texel is too big ("
                                                    << atlas_w << " x " << atlas_h
                                                    << " px); raise ground_texel_m");
  {
    constexpr std::size_t kHuge = std::size_t{2} << 20;
    const std::size_t bytes =
        static_cast<std::size_t>(atlas_w) * static_cast<std::size_t>(atlas_h) * 3;
    const std::size_t rounded = (bytes + kHuge - 1) / kHuge * kHuge;
    g.atlas_memory.reset(static_cast<std::uint8_t*>(std::aligned_alloc(kHuge, rounded)));
    AUTODRIVE_CHECK(g.atlas_memory != nullptr, "out of memory for the ground's picture");
    ::madvise(g.atlas_memory.get(), rounded, MADV_HUGEPAGE);  // advice only: may fail
    g.atlas = cv::Mat(atlas_h, atlas_w, CV_8UC3, g.atlas_memory.get());
  }
  g.atlas.setTo(cv::Scalar(kLabWalls.r, kLabWalls.g, kLabWalls.b));
  for (std::size_t k = 0; k < levels.size(); ++k) {
    const auto& l = g.levels[k];
    levels[k].copyTo(g.atlas(cv::Rect(l.x, l.y, l.w, l.h)));
  }
  g.walls = {static_cast<float>(atlas_w - 1), static_cast<float>(atlas_h - 1)};
  g.avx2 = allow_avx2 && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  if (g.avx2) cv::cvtColor(g.atlas, g.atlas32, cv::COLOR_RGB2RGBA);
  return g;
}

Rgb SignColour(const std::string& type) {
  if (type == "stop" || type == "no_entry") return {200, 20, 20};
  if (type == "parking" || type == "one_way" || type == "pedestrian_crossing") return {30, 80, 200};
  if (type == "yield") return {240, 240, 240};
  return {240, 240, 240};
}

}  // namespace

// ---- RenderWorld ----------------------------------------------------------------------------

struct RenderWorld::Impl {
  RenderWorldOptions options;
  GroundPyramid ground;
  std::vector<RenderPart> parts;    ///< static
  std::vector<RenderPart> terrain;  ///< raised and sloping tiles and the sides under them
  int heads = 0;
  mutable std::mutex tags_mutex;
  mutable std::map<std::pair<std::string, int>, std::unique_ptr<TagBitmap>> tags;

  const TagBitmap& Tag(const TagSpec& spec) const {
    const std::lock_guard lock(tags_mutex);
    auto& slot = tags[{spec.family, spec.id}];
    if (!slot) slot = std::make_unique<TagBitmap>(MakeTagBitmap(spec));
    return *slot;
  }
};

namespace {

// A box part from a rectangular prism's footprint (4 vertices).
RenderPart BoxFromPrism(const Prism& prism) {
  AUTODRIVE_THROW_UNLESS(prism.footprint_M.size() == 4,
                         "the cameras draw rectangular obstacles only; one has "
                             << prism.footprint_M.size() << " vertices");
  const auto& v = prism.footprint_M;
  const Eigen::Vector2d centre = (v[0] + v[1] + v[2] + v[3]) / 4.0;
  const Eigen::Vector2d e0 = v[1] - v[0];
  const Eigen::Vector2d e1 = v[3] - v[0];
  AUTODRIVE_THROW_UNLESS(std::abs(e0.normalized().dot(e1.normalized())) < 1e-3,
                         "the cameras draw rectangular obstacles only; one is not a rectangle");
  RenderPart part;
  const double yaw = std::atan2(e0.y(), e0.x());
  part.R_MB = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  part.p_MB = {centre.x(), centre.y(), (prism.z_bottom_m + prism.z_top_m) / 2};
  part.half = {e0.norm() / 2, e1.norm() / 2, (prism.z_top_m - prism.z_bottom_m) / 2};
  return part;
}

Eigen::Matrix3d Yaw(double yaw) {
  return Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

}  // namespace

RenderWorld::RenderWorld(const maps::Map& map, const StaticGeometry& geometry,
                         const RenderWorldOptions& options)
    : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  options.scene.Validate();
  impl_->ground = MakeGround(map, options.ground_texel_m, options.allow_avx2);
  auto& parts = impl_->parts;
  for (std::size_t i = 0; i < geometry.prisms.size(); ++i) {
    RenderPart part = BoxFromPrism(geometry.prisms[i]);
    if (i < map.obstacles.size()) {
      part.colour = map.obstacles[i].kind == "wall" ? kWallColour : kBoxColour;
    } else {
      part.colour = kUnmappedColour;
    }
    parts.push_back(part);
  }
  for (const Cylinder& c : geometry.cylinders) {
    RenderPart part;
    part.cylinder = true;
    part.p_MB = {c.centre_M.x(), c.centre_M.y(), (c.z_bottom_m + c.z_top_m) / 2};
    part.half = {c.radius_m, c.radius_m, (c.z_top_m - c.z_bottom_m) / 2};
    part.colour = kPoleColour;
    parts.push_back(part);
  }
  const TerrainModel& terrain = geometry.terrain;
  // The tiles that are not at z = 0: each its plane, and under a raised one a block of the
  // ground's side colour up to its lowest corner (the step a camera sees from beside it).
  const double T = terrain.tile_size_m();
  for (int iy = 0; iy < terrain.tiles_y(); ++iy) {
    for (int ix = 0; ix < terrain.tiles_x(); ++ix) {
      const TerrainModel::Plane& plane = terrain.plane(ix, iy);
      if (plane.dz_dx == 0 && plane.dz_dy == 0 && plane.z0_m == 0) continue;
      const double x0 = ix * T, y0 = iy * T;
      double lo = 1e30, hi = -1e30;
      for (const double x : {x0, x0 + T}) {
        for (const double y : {y0, y0 + T}) {
          lo = std::min(lo, plane.HeightAt(x, y));
          hi = std::max(hi, plane.HeightAt(x, y));
        }
      }
      RenderPart tile;
      tile.terrain = true;
      tile.p_MB = {x0 + T / 2, y0 + T / 2, (lo + hi) / 2};
      tile.half = {T / 2, T / 2, (hi - lo) / 2 + 1e-4};
      tile.a = static_cast<float>(plane.dz_dx);
      tile.b = static_cast<float>(plane.dz_dy);
      tile.c = static_cast<float>(plane.HeightAt(tile.p_MB.x(), tile.p_MB.y()) - tile.p_MB.z());
      impl_->terrain.push_back(tile);
      if (lo > 1e-3) {
        RenderPart block;
        block.p_MB = {x0 + T / 2, y0 + T / 2, (lo - 5e-4) / 2};
        block.half = {T / 2, T / 2, (lo - 5e-4) / 2};
        block.colour = kTerrainSide;
        impl_->terrain.push_back(block);
      }
    }
  }
  const double pole_r = options.scene.pole_radius_m;
  // Each head: a dark housing in front of its pole (towards the traffic it faces), with its
  // lamps on the face the traffic sees.
  for (std::size_t i = 0; i < map.signal_heads.size(); ++i) {
    const maps::SignalHead& head = map.signal_heads[i];
    const Eigen::Vector2d p = head.X_MH.translation();
    const double yaw = head.X_MH.rotation().angle();
    const double ground = terrain.HeightAt(p.x(), p.y());
    const auto [lo, hi] =
        std::minmax_element(head.lamp_heights_m.begin(), head.lamp_heights_m.end());
    const double spacing = std::max(0.01, (*hi - *lo) / 2);
    const double bottom = *lo - spacing * 0.75;
    const double top = *hi + spacing * 0.75;
    RenderPart part;
    part.R_MB = Yaw(yaw);
    const double depth = 0.02;
    const Eigen::Vector2d c =
        p + Eigen::Vector2d(std::cos(yaw), std::sin(yaw)) * (pole_r + depth / 2);
    part.p_MB = {c.x(), c.y(), ground + (bottom + top) / 2};
    part.half = {depth / 2, spacing * 0.8, (top - bottom) / 2};
    part.colour = kHeadColour;
    part.decal = Decal::kLamps;
    part.head = static_cast<int>(i);
    part.lamp_radius = spacing * 0.42;
    for (int k = 0; k < 3; ++k) {
      part.lamp_z[static_cast<std::size_t>(k)] =
          head.lamp_heights_m[static_cast<std::size_t>(k)] - (bottom + top) / 2;
    }
    parts.push_back(part);
  }
  impl_->heads = static_cast<int>(map.signal_heads.size());
  // Each sign: a plate on top of its pole, facing where the sign looks.
  for (const maps::Sign& sign : map.signs) {
    const Eigen::Vector2d p = sign.X_MS.translation();
    const double yaw = sign.X_MS.rotation().angle();
    const double ground = terrain.HeightAt(p.x(), p.y());
    const double size = 0.05;
    RenderPart part;
    part.R_MB = Yaw(yaw);
    const double depth = 0.004;
    const Eigen::Vector2d c =
        p + Eigen::Vector2d(std::cos(yaw), std::sin(yaw)) * (pole_r + depth / 2);
    part.p_MB = {c.x(), c.y(), ground + options.scene.sign_height_m - size / 2};
    part.half = {depth / 2, size / 2, size / 2};
    part.colour = {200, 200, 200};
    part.decal = Decal::kSign;
    part.decal_colour = SignColour(sign.type);
    parts.push_back(part);
  }
  // Ground tags: a white plate 0.5 mm thick with the tag on top.
  for (const GroundTag& g : options.ground_tags) {
    const TagBitmap& bitmap = impl_->Tag(g.tag);
    const double plate = g.tag.size_m * bitmap.total / bitmap.at_border;
    RenderPart part;
    part.R_MB = Yaw(g.yaw_rad);
    const double thickness = 0.0005;
    part.p_MB = {g.x_m, g.y_m, terrain.HeightAt(g.x_m, g.y_m) + thickness / 2};
    part.half = {plate / 2, plate / 2, thickness / 2};
    part.colour = kPlateColour;
    part.decal = Decal::kTag;
    part.tag = &bitmap;
    parts.push_back(part);
  }
}

RenderWorld::~RenderWorld() = default;

const RenderWorldOptions& RenderWorld::options() const { return impl_->options; }

const internal::TagBitmap& RenderWorld::Tag(const TagSpec& tag) const { return impl_->Tag(tag); }

std::array<Eigen::Vector3d, 4> TagCorners(double size_m) {
  const double h = size_m / 2;
  return {Eigen::Vector3d(-h, -h, 0), Eigen::Vector3d(h, -h, 0), Eigen::Vector3d(h, h, 0),
          Eigen::Vector3d(-h, h, 0)};
}

Eigen::Isometry3d VehicleTagPose(const RenderVehicle& vehicle) {
  const VehicleParams& p = *vehicle.params;
  Eigen::Isometry3d X_VT = Eigen::Isometry3d::Identity();
  X_VT.translation() =
      Eigen::Vector3d(p.body_centre_ahead_of_rear_axle_m, 0.0, vehicle.look.tag_height_m);
  X_VT.linear() = Yaw(-kPi / 2);  // tag's y (its top) along the vehicle's x
  return vehicle.X_MV * X_VT;
}

// ---- CameraRenderer -------------------------------------------------------------------------

namespace {

// A part as one frame's camera sees it: the camera's rays map into the part's frame by Q,
// the camera's centre is at o.
struct FramePart {
  const RenderPart* part = nullptr;
  Eigen::Matrix3f Q;
  Eigen::Vector3f o;
  std::array<float, 6> shade{};        ///< faces +x, -x, +y, -y, +z, -z
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  ///< pixel rectangle [x0, x1) x [y0, y1)
  bool tiles = false;                  ///< straddles the camera's plane: use the tile mask
};

constexpr int kTile = 16;
constexpr int kStrip = 16;  ///< rows of the ground drawn at a time (their remap stays in cache)

}  // namespace

struct CameraRenderer::Impl {
  std::shared_ptr<const RenderWorld> world;
  camera::CameraModel model;
  FilmOptions film;
  int w = 0, h = 0;
  [[nodiscard]] std::size_t W() const { return static_cast<std::size_t>(w); }
  [[nodiscard]] std::size_t Index(int u, int v) const {
    return static_cast<std::size_t>(v) * W() + static_cast<std::size_t>(u);
  }
  // Each pixel's ray in C is (x, y, 1), x and y its undistorted normalised coordinates: for a
  // camera without distortion x = (u - cx) / fx and y = (v - cy) / fy, computed as needed;
  // with distortion, from a table (NaN beyond the lens model's fold). Ranges along rays are in
  // units of this ray, the same for the ground and every part.
  bool distorted = false;
  float fx = 1, fy = 1, cx = 0, cy = 0;
  std::vector<float> table_x, table_y;
  std::vector<float> column_x;  ///< without distortion: x of each column
  float inv_fy = 1.0f;
  std::vector<float> row_y;  ///< a row's y, repeated
  std::vector<int> row_ax, row_ay;
  [[nodiscard]] Eigen::Vector3f Ray(int u, int v) const {
    if (!distorted) {
      return {column_x[static_cast<std::size_t>(u)], (static_cast<float>(v) - cy) * inv_fy, 1.0f};
    }
    const std::size_t i = Index(u, v);
    return {table_x[i], table_y[i], 1.0f};
  }
  float f_px = 1.0f;
  // Tiles of kTile x kTile pixels: the inward normals of the four planes through the camera's
  // centre and the tile's corner rays.
  int tw = 0, th = 0;
  std::vector<std::array<Eigen::Vector3f, 4>> tile_planes;
  std::array<Eigen::Vector3f, 4> image_planes;       ///< the same for the whole image
  std::array<Eigen::Vector3d, 4> image_planes_unit;  ///< `image_planes` of unit length

  // Buffers.
  std::vector<float> depth;  ///< range of the nearest part, valid inside the parts' rectangles
  /// The range of the raised and sloping ground, infinity where there is none (drawn with the
  /// ground, and kept with it while a camera does not move); parts start from it.
  std::vector<float> ground_depth;
  std::vector<std::array<int, 4>> terrain_rects;  ///< where ground_depth is not infinite
  std::vector<std::uint8_t> colour;               ///< rgb
  std::vector<RenderPart> dynamic_parts;
  std::vector<FramePart> frame_parts;
  std::vector<std::uint8_t> lamp_state;  ///< per head: bits red, yellow, green
  std::vector<std::uint16_t> accumulator;
  std::vector<RenderVehicle> moved;
  std::vector<RenderTraffic> moved_traffic;
  RenderStats stats;
  cv::Mat noise;  ///< a block of Gaussian noise (CV_8S), offset at random per frame
  // The ground of a camera that does not move is drawn once: when a frame's pose is the last
  // frame's, the ground is kept and reused while the pose stays.
  Eigen::Matrix4d last_pose = Eigen::Matrix4d::Zero();
  bool cache_valid = false;
  std::vector<std::uint8_t> cached_colour;
  cv::Mat map_xy, map_frac;        ///< a strip of the ground's remap, CV_16SC2 and CV_16UC1
  std::uint8_t* target = nullptr;  ///< where this pass draws: rgb, w x h

  Impl(std::shared_ptr<const RenderWorld> w_, const camera::Intrinsics& intrinsics,
       const FilmOptions& f)
      : world(std::move(w_)), model(intrinsics), film(f) {
    AUTODRIVE_THROW_UNLESS(world != nullptr, "CameraRenderer: no world");
    w = intrinsics.width_px;
    h = intrinsics.height_px;
    f_px = static_cast<float>(std::sqrt(intrinsics.fx_px * intrinsics.fy_px));
    const std::size_t n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
    fx = static_cast<float>(intrinsics.fx_px);
    fy = static_cast<float>(intrinsics.fy_px);
    cx = static_cast<float>(intrinsics.cx_px);
    cy = static_cast<float>(intrinsics.cy_px);
    distorted = std::any_of(intrinsics.distortion.begin(), intrinsics.distortion.end(),
                            [](double k) { return k != 0.0; });
    if (distorted) {
      table_x.resize(n);
      table_y.resize(n);
      for (int v = 0; v < h; ++v) {
        for (int u = 0; u < w; ++u) {
          const auto xy = model.UndistortToNormalized({u, v});
          const std::size_t i = Index(u, v);
          table_x[i] = xy ? static_cast<float>(xy->x()) : std::numeric_limits<float>::quiet_NaN();
          table_y[i] = xy ? static_cast<float>(xy->y()) : std::numeric_limits<float>::quiet_NaN();
        }
      }
    }
    tw = (w + kTile - 1) / kTile;
    th = (h + kTile - 1) / kTile;
    tile_planes.resize(static_cast<std::size_t>(tw * th));
    for (int ty = 0; ty < th; ++ty) {
      for (int tx = 0; tx < tw; ++tx) {
        // The tile's outer corners, half a pixel beyond its pixel centres and a pixel more of
        // margin.
        tile_planes[static_cast<std::size_t>(ty * tw + tx)] =
            PyramidPlanes(tx * kTile - 1.5, ty * kTile - 1.5, std::min(w, (tx + 1) * kTile) + 0.5,
                          std::min(h, (ty + 1) * kTile) + 0.5);
      }
    }
    image_planes = PyramidPlanes(-1.5, -1.5, w + 0.5, h + 0.5);
    for (std::size_t k = 0; k < 4; ++k) {
      image_planes_unit[k] = image_planes[k].cast<double>().normalized();
    }
    depth.resize(n);
    ground_depth.assign(n, std::numeric_limits<float>::infinity());
    colour.resize(n * 3);
    column_x.resize(W());
    for (int k = 0; k < w; ++k) {
      column_x[static_cast<std::size_t>(k)] = (static_cast<float>(k) - cx) / fx;
    }
    inv_fy = 1.0f / fy;
    row_y.resize(W());
    row_ax.resize(W());
    row_ay.resize(W());
    map_xy.create(kStrip, w, CV_16SC2);
    map_frac.create(kStrip, w, CV_16UC1);
    frame_parts.reserve(256);
    dynamic_parts.reserve(256);
    lamp_state.resize(static_cast<std::size_t>(world->impl_->heads));
    if (film.noise_sigma > 0) {
      // Clipped at +-127 levels: beyond 3.9 sigma for the largest sigma allowed (32).
      cv::Mat normal(h + 64, (w + 64) * 3, CV_32F);
      cv::RNG rng(0x5eed);
      rng.fill(normal, cv::RNG::NORMAL, 0.0, film.noise_sigma);
      normal.convertTo(noise, CV_8S);
    }
  }

  // The inward normals of the four planes through the camera's centre and the rays of the
  // corners of the image rectangle [u0, u1] x [v0, v1].
  [[nodiscard]] std::array<Eigen::Vector3f, 4> PyramidPlanes(double u0, double v0, double u1,
                                                             double v1) const {
    const std::array<Eigen::Vector2d, 4> corners{Eigen::Vector2d(u0, v0), Eigen::Vector2d(u1, v0),
                                                 Eigen::Vector2d(u1, v1), Eigen::Vector2d(u0, v1)};
    std::array<Eigen::Vector3d, 4> rays;
    for (std::size_t k = 0; k < 4; ++k) {
      const auto r = model.Unproject(corners[k]);
      // Beyond the fold: a wide ray in the corner's direction.
      const camera::Intrinsics& in = model.intrinsics();
      rays[k] = r ? *r
                  : Eigen::Vector3d(corners[k].x() - in.cx_px, corners[k].y() - in.cy_px, 1e-3)
                        .normalized();
    }
    std::array<Eigen::Vector3f, 4> planes;
    for (std::size_t k = 0; k < 4; ++k) {
      // Clockwise in the image (x right, y down) is counter-clockwise about +z: the cross
      // product of consecutive rays points into the pyramid.
      planes[k] = rays[k].cross(rays[(k + 1) % 4]).cast<float>();
    }
    return planes;
  }
  void DrawGround(const Eigen::Isometry3d& X_MC);
  void BuildParts(const Eigen::Isometry3d& X_MC, const FrameState& frame,
                  std::optional<int> exclude);
  [[nodiscard]] bool SphereInView(const Eigen::Vector3d& centre_C, double radius) const;
  void AddTraffic(const RenderTraffic& object, bool blink, bool far);
  void Place(FramePart& fp, const Eigen::Isometry3d& X_MC);
  void DrawPart(const FramePart& fp, float* depth_buffer);
  void DrawPixel(const FramePart& fp, int u, int v, const Eigen::Vector3f& r,
                 const Eigen::Vector3f& d, float* depth_buffer);
  void DrawTerrain(const Eigen::Isometry3d& X_MC);
  void Shade(FramePart& fp) const;
  [[nodiscard]] Rgb SampleGround(float x, float y, float area_texels) const;
  void RenderOnce(const Eigen::Isometry3d& X_MC, const FrameState& frame,
                  std::optional<int> exclude);
};

namespace {

// What the ground's sampler needs for one frame: the camera's rotation rows and position, the
// level thresholds and the atlas (see DrawGround).
struct GroundFrame {
  float r00, r01, r02, r10, r11, r12, r20, r21, r22;
  float ccx, ccy, height, min_dz, a_num;
  std::array<float, 8> thresholds;
  float x0, y1, inv_texel, W0, H0;
  std::uint32_t walls;
  const std::uint32_t* atlas;
  int stride;  // texels per atlas row
};

// One pixel of the ground (the same arithmetic as the AVX2 sampler, for the rows' tails).
inline std::uint32_t GroundPixel(const GroundFrame& f, float x, float y) {
  const float dz = f.r20 * x + f.r21 * y + f.r22;
  if (!(dz < f.min_dz)) return f.walls;
  const float inv = -1.0f / dz;
  const float t = f.height * inv;
  const float gx = f.ccx + t * (f.r00 * x + f.r01 * y + f.r02);
  const float gy = f.ccy + t * (f.r10 * x + f.r11 * y + f.r12);
  const float area = f.a_num * inv * inv * inv;
  int level = 0;
  for (int k = 1; k < 8; ++k) level += area >= f.thresholds[static_cast<std::size_t>(k)] ? 1 : 0;
  const float scale = std::bit_cast<float>((127 - level) << 23);
  const float ox = level > 0 ? f.W0 - 0.5f : -0.5f;
  const float oy = level > 0 ? f.H0 - 2.0f * f.H0 * scale - 0.5f : -0.5f;
  const float uu = std::min(std::max((gx - f.x0) * f.inv_texel * scale, 0.5f), f.W0 * scale - 0.5f);
  const float vv = std::min(std::max((f.y1 - gy) * f.inv_texel * scale, 0.5f), f.H0 * scale - 0.5f);
  const float ax = ox + uu, ay = oy + vv;
  const int i = static_cast<int>(ax), j = static_cast<int>(ay);
  const auto wu = static_cast<std::uint32_t>((ax - static_cast<float>(i)) * 256.0f);
  const auto wv = static_cast<std::uint32_t>((ay - static_cast<float>(j)) * 256.0f);
  const std::uint32_t* p = f.atlas + static_cast<std::ptrdiff_t>(j) * f.stride + i;
  const std::uint32_t c00 = p[0], c01 = p[1], c10 = p[f.stride], c11 = p[f.stride + 1];
  const std::uint32_t w11 = (wu * wv) >> 8, w01 = wu - w11, w10 = wv - w11;
  const std::uint32_t w00 = 256 - wu - wv + w11;
  const std::uint32_t rb = ((c00 & 0xff00ffu) * w00 + (c01 & 0xff00ffu) * w01 +
                            (c10 & 0xff00ffu) * w10 + (c11 & 0xff00ffu) * w11) >>
                           8;
  const std::uint32_t g = ((c00 & 0xff00u) * w00 + (c01 & 0xff00u) * w01 + (c10 & 0xff00u) * w10 +
                           (c11 & 0xff00u) * w11) >>
                          8;
  return (rb & 0xff00ffu) | (g & 0xff00u);
}

// The bilinear blend of four texels' channels under `mask` (R and B, or G, each in 16 bits of
// the 32-bit lanes), weights in 1/256.
__attribute__((target("avx2,fma"))) inline __m256i Blend4(__m256i c00, __m256i c01, __m256i c10,
                                                          __m256i c11, __m256i w00, __m256i w01,
                                                          __m256i w10, __m256i w11, __m256i mask) {
  __m256i sum = _mm256_mullo_epi32(_mm256_and_si256(c00, mask), w00);
  sum = _mm256_add_epi32(sum, _mm256_mullo_epi32(_mm256_and_si256(c01, mask), w01));
  sum = _mm256_add_epi32(sum, _mm256_mullo_epi32(_mm256_and_si256(c10, mask), w10));
  sum = _mm256_add_epi32(sum, _mm256_mullo_epi32(_mm256_and_si256(c11, mask), w11));
  return _mm256_and_si256(_mm256_srli_epi32(sum, 8), mask);
}

// The 32-bit lanes 0 and 2 (or 1 and 3) of each 64-bit pair of p and q: p0 p2 q0 q2 | p4 p6 q4 q6.
__attribute__((target("avx2,fma"))) inline __m256i EvenLanes(__m256i p, __m256i q) {
  return _mm256_castps_si256(
      _mm256_shuffle_ps(_mm256_castsi256_ps(p), _mm256_castsi256_ps(q), _MM_SHUFFLE(2, 0, 2, 0)));
}
__attribute__((target("avx2,fma"))) inline __m256i OddLanes(__m256i p, __m256i q) {
  return _mm256_castps_si256(
      _mm256_shuffle_ps(_mm256_castsi256_ps(p), _mm256_castsi256_ps(q), _MM_SHUFFLE(3, 1, 3, 1)));
}

// A row of the ground, 8 pixels at a time with AVX2 (the bilinear texels loaded in pairs), the tail
// one by one. `xs`, `ys`: the row's undistorted coordinates (ys null: all `y`).
__attribute__((target("avx2,fma"))) void GroundRowAvx2(const GroundFrame& f, const float* xs,
                                                       const float* ys, float y, int width,
                                                       std::uint8_t* out) {
  const __m256 r00 = _mm256_set1_ps(f.r00), r01 = _mm256_set1_ps(f.r01),
               r02 = _mm256_set1_ps(f.r02);
  const __m256 r10 = _mm256_set1_ps(f.r10), r11 = _mm256_set1_ps(f.r11),
               r12 = _mm256_set1_ps(f.r12);
  const __m256 r20 = _mm256_set1_ps(f.r20), r21 = _mm256_set1_ps(f.r21),
               r22 = _mm256_set1_ps(f.r22);
  const __m256 ccx = _mm256_set1_ps(f.ccx), ccy = _mm256_set1_ps(f.ccy);
  const __m256 height = _mm256_set1_ps(f.height), min_dz = _mm256_set1_ps(f.min_dz);
  const __m256 a_num = _mm256_set1_ps(f.a_num), minus1 = _mm256_set1_ps(-1.0f);
  const __m256 x0 = _mm256_set1_ps(f.x0), y1 = _mm256_set1_ps(f.y1);
  const __m256 inv_texel = _mm256_set1_ps(f.inv_texel);
  const __m256 W0 = _mm256_set1_ps(f.W0), H0 = _mm256_set1_ps(f.H0);
  const __m256 half = _mm256_set1_ps(0.5f), k256 = _mm256_set1_ps(256.0f);
  const __m256 w0_edge = _mm256_set1_ps(f.W0 - 0.5f), minus_half = _mm256_set1_ps(-0.5f);
  const __m256i zero = _mm256_setzero_si256(), bias = _mm256_set1_epi32(127);
  const __m256i stride = _mm256_set1_epi32(f.stride);
  const __m256i rb_mask = _mm256_set1_epi32(0xff00ff), g_mask = _mm256_set1_epi32(0xff00);
  const __m256i k256i = _mm256_set1_epi32(256);
  const __m256i walls = _mm256_set1_epi32(static_cast<int>(f.walls));
  __m256 thresholds[8];
  for (std::size_t k = 1; k < 8; ++k) thresholds[k] = _mm256_set1_ps(f.thresholds[k]);
  const auto* atlas = reinterpret_cast<const int*>(f.atlas);
  // RGBX RGBX RGBX RGBX -> RGBRGBRGBRGB in each 128-bit half.
  const __m128i pack = _mm_setr_epi8(0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1);
  const __m256i order = _mm256_setr_epi32(0, 1, 4, 5, 2, 3, 6, 7);  // its own inverse
  int u = 0;
  for (; u + 8 <= width; u += 8) {
    const __m256 x = _mm256_loadu_ps(xs + u);
    const __m256 yv = ys != nullptr ? _mm256_loadu_ps(ys + u) : _mm256_set1_ps(y);
    const __m256 dz = _mm256_fmadd_ps(r20, x, _mm256_fmadd_ps(r21, yv, r22));
    const __m256 hit = _mm256_cmp_ps(dz, min_dz, _CMP_LT_OQ);
    if (_mm256_movemask_ps(hit) == 0) {
      // Eight rays over the horizon (the sky of an on-board camera): the walls, no texels.
      const __m128i w = _mm_shuffle_epi8(_mm256_castsi256_si128(walls), pack);
      std::memcpy(out + 3 * u, &w, 12);
      std::memcpy(out + 3 * u + 12, &w, 12);
      continue;
    }
    const __m256 inv = _mm256_div_ps(minus1, _mm256_blendv_ps(minus1, dz, hit));
    const __m256 t = _mm256_mul_ps(height, inv);
    const __m256 gx =
        _mm256_fmadd_ps(t, _mm256_fmadd_ps(r00, x, _mm256_fmadd_ps(r01, yv, r02)), ccx);
    const __m256 gy =
        _mm256_fmadd_ps(t, _mm256_fmadd_ps(r10, x, _mm256_fmadd_ps(r11, yv, r12)), ccy);
    const __m256 area = _mm256_mul_ps(_mm256_mul_ps(a_num, inv), _mm256_mul_ps(inv, inv));
    __m256i level = zero;
    for (std::size_t k = 1; k < 8; ++k) {
      level = _mm256_sub_epi32(level,
                               _mm256_castps_si256(_mm256_cmp_ps(area, thresholds[k], _CMP_GE_OQ)));
    }
    const __m256 scale = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_sub_epi32(bias, level), 23));
    const __m256 above0 = _mm256_castsi256_ps(_mm256_cmpgt_epi32(level, zero));
    const __m256 ox = _mm256_blendv_ps(minus_half, w0_edge, above0);
    const __m256 oy = _mm256_blendv_ps(
        minus_half, _mm256_sub_ps(_mm256_fnmadd_ps(_mm256_add_ps(H0, H0), scale, H0), half),
        above0);
    const __m256 uu = _mm256_min_ps(
        _mm256_max_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(gx, x0), inv_texel), scale), half),
        _mm256_fmsub_ps(W0, scale, half));
    const __m256 vv = _mm256_min_ps(
        _mm256_max_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(y1, gy), inv_texel), scale), half),
        _mm256_fmsub_ps(H0, scale, half));
    const __m256 ax = _mm256_add_ps(ox, uu), ay = _mm256_add_ps(oy, vv);
    const __m256i i = _mm256_cvttps_epi32(ax), j = _mm256_cvttps_epi32(ay);
    __m256i wu = _mm256_cvttps_epi32(_mm256_mul_ps(_mm256_sub_ps(ax, _mm256_cvtepi32_ps(i)), k256));
    __m256i wv = _mm256_cvttps_epi32(_mm256_mul_ps(_mm256_sub_ps(ay, _mm256_cvtepi32_ps(j)), k256));
    const __m256i idx = _mm256_add_epi32(_mm256_mullo_epi32(j, stride), i);
    // A texel and its right-hand neighbour in one 64-bit load, scalar: as fast as AVX2's
    // gathers here (AMD Zen 5) and far faster where microcode slows gathers down (Intel's
    // Downfall mitigation). Pairs of pixels 0-3 come in a, 4-7 in b; the even and odd
    // lanes of (a, b) are the left and right texels of pixels 0 1 4 5 | 2 3 6 7, the order the
    // weights are put in and the colours are put back from.
    alignas(32) std::int32_t ix[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(ix), idx);
    const std::int64_t s = f.stride;
    const auto at = [&](int k) {
      std::int64_t q;
      std::memcpy(&q, atlas + ix[k], 8);
      return q;
    };
    const auto below = [&](int k) {
      std::int64_t q;
      std::memcpy(&q, atlas + ix[k] + s, 8);
      return q;
    };
    const __m256i a0 = _mm256_setr_epi64x(at(0), at(1), at(2), at(3));
    const __m256i b0 = _mm256_setr_epi64x(at(4), at(5), at(6), at(7));
    const __m256i a1 = _mm256_setr_epi64x(below(0), below(1), below(2), below(3));
    const __m256i b1 = _mm256_setr_epi64x(below(4), below(5), below(6), below(7));
    const __m256i c00 = EvenLanes(a0, b0), c01 = OddLanes(a0, b0);
    const __m256i c10 = EvenLanes(a1, b1), c11 = OddLanes(a1, b1);
    wu = _mm256_permutevar8x32_epi32(wu, order);
    wv = _mm256_permutevar8x32_epi32(wv, order);
    const __m256i w11 = _mm256_srli_epi32(_mm256_mullo_epi32(wu, wv), 8);
    const __m256i w01 = _mm256_sub_epi32(wu, w11), w10 = _mm256_sub_epi32(wv, w11);
    const __m256i w00 = _mm256_add_epi32(_mm256_sub_epi32(_mm256_sub_epi32(k256i, wu), wv), w11);
    __m256i rgbx = _mm256_or_si256(Blend4(c00, c01, c10, c11, w00, w01, w10, w11, rb_mask),
                                   Blend4(c00, c01, c10, c11, w00, w01, w10, w11, g_mask));
    rgbx = _mm256_permutevar8x32_epi32(rgbx, order);
    rgbx = _mm256_blendv_epi8(walls, rgbx, _mm256_castps_si256(hit));
    const __m128i lo = _mm_shuffle_epi8(_mm256_castsi256_si128(rgbx), pack);
    const __m128i hi = _mm_shuffle_epi8(_mm256_extracti128_si256(rgbx, 1), pack);
    std::memcpy(out + 3 * u, &lo, 12);
    std::memcpy(out + 3 * u + 12, &hi, 12);
  }
  for (; u < width; ++u) {
    const std::uint32_t c = GroundPixel(f, xs[u], ys != nullptr ? ys[u] : y);
    out[3 * u] = static_cast<std::uint8_t>(c);
    out[3 * u + 1] = static_cast<std::uint8_t>(c >> 8);
    out[3 * u + 2] = static_cast<std::uint8_t>(c >> 16);
  }
}

}  // namespace

void CameraRenderer::Impl::DrawGround(const Eigen::Isometry3d& X_MC) {
  const std::size_t n = W() * static_cast<std::size_t>(h);
  const bool same_pose = X_MC.matrix() == last_pose;
  last_pose = X_MC.matrix();
  if (same_pose && cache_valid) {
    std::memcpy(target, cached_colour.data(), n * 3);
    return;
  }
  // Each pixel's point on the ground as a position in the atlas at the level of its footprint,
  // in OpenCV's fixed-point map format (1/32 texel), then one bilinear remap; a strip of rows at
  // a time, so that the map never leaves the cache (this is bound by memory bandwidth).
  const GroundPyramid& g = world->impl_->ground;
  const Eigen::Matrix3f R = X_MC.linear().cast<float>();
  const Eigen::Vector3f c = X_MC.translation().cast<float>();
  const float height = c.z();
  const float inv_texel = static_cast<float>(1.0 / g.texel_m);
  // The footprint's area in level-0 texels (for a ray (x, y, 1) of solid angle 1 / (fx fy |r|^3)
  // per pixel, meeting the ground at range t = h / -d_z along it) is
  // A = h^2 / (fx fy texel^2 (-d_z)^3): level k from A >= 4^k / 2 (the nearest power of two).
  const float a_num = height * height * inv_texel * inv_texel / (fx * fy);
  const int top_level = std::min(7, static_cast<int>(g.levels.size()) - 1);
  std::array<float, 8> thresholds;
  thresholds.fill(std::numeric_limits<float>::infinity());
  for (int k = 1; k <= top_level; ++k) {
    thresholds[static_cast<std::size_t>(k)] = std::ldexp(0.5f, 2 * k);
  }
  const float x0 = static_cast<float>(g.x0_m), y1 = static_cast<float>(g.y1_m);
  // Level k's place in the atlas from s = 2^-k alone (no table, so that the loop vectorises):
  // level 0 at (0, 0) of W x H texels; level k >= 1 at (W, H - 2 H s), W s x H s.
  const float W0 = static_cast<float>(g.levels[0].w), H0 = static_cast<float>(g.levels[0].h);
  constexpr float kTab = static_cast<float>(static_cast<int>(cv::INTER_TAB_SIZE));
  const float walls_x = g.walls.x() * kTab + 0.5f, walls_y = g.walls.y() * kTab + 0.5f;
  constexpr int kMask = cv::INTER_TAB_SIZE - 1;
  const float r00 = R(0, 0), r01 = R(0, 1), r02 = R(0, 2);
  const float r10 = R(1, 0), r11 = R(1, 1), r12 = R(1, 2);
  const float r20 = R(2, 0), r21 = R(2, 1), r22 = R(2, 2);
  const float ccx = c.x(), ccy = c.y();
  const int width = w;
  const float min_dz = height > 0 ? -1e-6f : -std::numeric_limits<float>::infinity();
  const float t1 = thresholds[1], t2 = thresholds[2], t3 = thresholds[3], t4 = thresholds[4];
  const float t5 = thresholds[5], t6 = thresholds[6], t7 = thresholds[7];
  if (g.avx2) {
    const GroundFrame frame{r00,
                            r01,
                            r02,
                            r10,
                            r11,
                            r12,
                            r20,
                            r21,
                            r22,
                            ccx,
                            ccy,
                            height,
                            min_dz,
                            a_num,
                            thresholds,
                            x0,
                            y1,
                            inv_texel,
                            W0,
                            H0,
                            static_cast<std::uint32_t>(kLabWalls.r) |
                                (static_cast<std::uint32_t>(kLabWalls.g) << 8) |
                                (static_cast<std::uint32_t>(kLabWalls.b) << 16),
                            reinterpret_cast<const std::uint32_t*>(g.atlas32.data),
                            g.atlas32.cols};
    for (int v = 0; v < h; ++v) {
      GroundRowAvx2(frame, distorted ? table_x.data() + Index(0, v) : column_x.data(),
                    distorted ? table_y.data() + Index(0, v) : nullptr,
                    (static_cast<float>(v) - cy) / fy, w, target + Index(0, v) * 3);
    }
    DrawTerrain(X_MC);
    cache_valid = same_pose;
    if (cache_valid) cached_colour.assign(target, target + n * 3);
    return;
  }
  for (int v0 = 0; v0 < h; v0 += kStrip) {
    const int rows = std::min(kStrip, h - v0);
    auto* m1 = reinterpret_cast<std::int16_t*>(map_xy.data);
    auto* m2 = reinterpret_cast<std::uint16_t*>(map_frac.data);
    for (int v = v0; v < v0 + rows; ++v) {
      const float yn_row = (static_cast<float>(v) - cy) / fy;
      const float* xs = distorted ? table_x.data() + Index(0, v) : column_x.data();
      if (!distorted) std::fill(row_y.begin(), row_y.end(), yn_row);
      const float* ys = distorted ? table_y.data() + Index(0, v) : row_y.data();
      std::int16_t* o1 = m1 + 2 * static_cast<std::size_t>(v - v0) * W();
      std::uint16_t* o2 = m2 + static_cast<std::size_t>(v - v0) * W();
      int* pax = row_ax.data();
      int* pay = row_ay.data();
      // Branch-free, so that the compiler vectorises it: rays that miss the ground (or NaN
      // rays beyond a lens' fold) select the walls' texel. (`width`, a local: the int stores
      // could otherwise change the member `w`.)
      for (int u = 0; u < width; ++u) {
        const float x = xs[u];
        const float y = ys[u];
        const float dz = r20 * x + r21 * y + r22;
        const bool hit = dz < min_dz;
        const float inv = -1.0f / (hit ? dz : -1.0f);
        const float t = height * inv;
        const float gx = ccx + t * (r00 * x + r01 * y + r02);
        const float gy = ccy + t * (r10 * x + r11 * y + r12);
        const float area = a_num * inv * inv * inv;
        const int level = (area >= t1) + (area >= t2) + (area >= t3) + (area >= t4) + (area >= t5) +
                          (area >= t6) + (area >= t7);
        const float scale = std::bit_cast<float>((127 - level) << 23);  // 2^-level
        const float lw = W0 * scale, lh = H0 * scale;
        const float ox = level > 0 ? W0 - 0.5f : -0.5f;
        const float oy = level > 0 ? H0 - 2.0f * H0 * scale - 0.5f : -0.5f;
        const float uu = std::min(std::max((gx - x0) * inv_texel * scale, 0.5f), lw - 0.5f);
        const float vv = std::min(std::max((y1 - gy) * inv_texel * scale, 0.5f), lh - 0.5f);
        pax[u] = static_cast<int>(hit ? (ox + uu) * kTab + 0.5f : walls_x);
        pay[u] = static_cast<int>(hit ? (oy + vv) * kTab + 0.5f : walls_y);
      }
      for (int u = 0; u < width; ++u) {
        const int ax = pax[u], ay = pay[u];
        o1[2 * u] = static_cast<std::int16_t>(ax >> cv::INTER_BITS);
        o1[2 * u + 1] = static_cast<std::int16_t>(ay >> cv::INTER_BITS);
        o2[u] = static_cast<std::uint16_t>((ay & kMask) * cv::INTER_TAB_SIZE + (ax & kMask));
      }
    }
    cv::Mat out(rows, w, CV_8UC3, target + Index(0, v0) * 3);
    cv::remap(g.atlas, out, map_xy.rowRange(0, rows), map_frac.rowRange(0, rows), cv::INTER_LINEAR,
              cv::BORDER_REPLICATE);
  }
  DrawTerrain(X_MC);
  cache_valid = same_pose;
  if (cache_valid) cached_colour.assign(target, target + n * 3);
}

namespace {

void AddBox(std::vector<RenderPart>& parts, const Eigen::Isometry3d& X_MV,
            const Eigen::Vector3d& centre_V, const Eigen::Vector3d& half, Rgb colour,
            Decal decal = Decal::kNone) {
  RenderPart& p = parts.emplace_back();
  p.R_MB = X_MV.linear();
  p.p_MB = X_MV * centre_V;
  p.half = half;
  p.colour = colour;
  p.decal = decal;
}

}  // namespace

// Whether a sphere (centre in the camera frame) may be seen: in front of the camera and not
// wholly outside one of the image's planes. As permissive as `Place`'s test of a part's
// corners, so no part of an object it keeps would have been dropped by that test alone.
bool CameraRenderer::Impl::SphereInView(const Eigen::Vector3d& centre_C, double radius) const {
  if (centre_C.z() + radius <= 1e-3) return false;
  for (const Eigen::Vector3d& n : image_planes_unit) {
    if (n.dot(centre_C) < -radius) return false;
  }
  return true;
}

// A background object's parts: a dark underbody (its wheels), a body with its lamps at both
// ends, and for a car a shorter cabin in the roof's colour; they fill the box that the LIDARs
// and the physics take for it. `far` (a few pixels across): one block in the roof's colour.
void CameraRenderer::Impl::AddTraffic(const RenderTraffic& o, bool blink, bool far) {
  const double L = o.size_m.x(), W = o.size_m.y(), H = o.size_m.z();
  const Eigen::Isometry3d& X = o.X_MO;
  if (o.shape == TrafficShape::kBlock || far) {
    AddBox(dynamic_parts, X, {0, 0, H / 2}, {L / 2, W / 2, H / 2}, far ? o.roof : o.body);
    return;
  }
  std::uint8_t lights = o.brake ? 8 : 0;
  if (o.left_indicator && blink) lights |= 2;
  if (o.right_indicator && blink) lights |= 4;
  const double clearance = 0.15 * H;
  const double top = o.shape == TrafficShape::kCar ? 0.6 * H : H;
  AddBox(dynamic_parts, X, {0, 0, clearance / 2}, {0.42 * L, 0.46 * W, clearance / 2}, kUnderbody);
  AddBox(dynamic_parts, X, {0, 0, (clearance + top) / 2}, {L / 2, W / 2, (top - clearance) / 2},
         o.body, Decal::kTrafficEnds);
  dynamic_parts.back().lights = lights;
  if (o.shape == TrafficShape::kCar) {
    AddBox(dynamic_parts, X, {-0.05 * L, 0, (top + H) / 2}, {0.27 * L, 0.43 * W, (H - top) / 2},
           o.roof);
  }
}

void CameraRenderer::Impl::BuildParts(const Eigen::Isometry3d& X_MC, const FrameState& frame,
                                      std::optional<int> exclude) {
  dynamic_parts.clear();
  const bool blink = std::fmod(frame.time_s, 1.0 / 1.5) < 0.5 / 1.5;
  for (const RenderVehicle& car : frame.vehicles) {
    if (exclude && car.index == *exclude) continue;
    AUTODRIVE_CHECK(car.params != nullptr, "RenderVehicle without params");
    const VehicleParams& p = *car.params;
    const Eigen::Isometry3d& X = car.X_MV;
    const double bx = p.body_centre_ahead_of_rear_axle_m;
    const double top = std::min(p.body_height_m, car.look.tag_height_m);
    const double deck = p.body_clearance_m + (top - p.body_clearance_m) * 0.55;
    // Body (the chassis and its deck).
    const std::size_t body = dynamic_parts.size();
    AddBox(dynamic_parts, X, {bx, 0, (p.body_clearance_m + deck) / 2},
           {p.body_length_m / 2, p.body_width_m / 2 - p.wheel_width_m,
            (deck - p.body_clearance_m) / 2},
           car.look.colour, Decal::kVehicleFront);
    // The front face carries the headlights; a second, thin box at the back the tail lights.
    std::uint8_t lights = car.headlights ? 1 : 0;
    if (car.left_indicator && blink) lights |= 2;
    if (car.right_indicator && blink) lights |= 4;
    dynamic_parts[body].lights = lights;
    AddBox(dynamic_parts, X, {bx - p.body_length_m / 2 - 0.001, 0, (p.body_clearance_m + deck) / 2},
           {0.001, p.body_width_m / 2 - p.wheel_width_m, (deck - p.body_clearance_m) / 2},
           car.look.colour, Decal::kVehicleRear);
    dynamic_parts.back().lights = lights;
    // The LIDAR and its mast up to the plate.
    const double plate_bottom = car.look.tag_height_m - 0.003;
    if (plate_bottom > deck) {
      AddBox(dynamic_parts, X, {bx, 0, (deck + plate_bottom) / 2},
             {0.035, 0.035, (plate_bottom - deck) / 2}, kLidarColour);
    }
    // Wheels.
    for (int k = 0; k < 4; ++k) {
      const double wx = k < 2 ? p.wheelbase_m : 0.0;
      const double wy = (k % 2 == 0 ? 1 : -1) * (p.track_width_m / 2);
      AddBox(dynamic_parts, X, {wx, wy, p.wheel_radius_m},
             {p.wheel_radius_m, p.wheel_width_m / 2, p.wheel_radius_m}, kWheelColour);
    }
    // The roof tag on its plate.
    if (car.look.tag) {
      const TagBitmap& bitmap = world->Tag(*car.look.tag);
      const double plate = car.look.tag->size_m * bitmap.total / bitmap.at_border;
      const Eigen::Isometry3d X_MT = VehicleTagPose(car);
      RenderPart& part = dynamic_parts.emplace_back();
      part.R_MB = X_MT.linear();
      part.p_MB = X_MT * Eigen::Vector3d(0, 0, -0.0015);
      part.half = {plate / 2, plate / 2, 0.0015};
      part.colour = kPlateColour;
      part.decal = Decal::kTag;
      part.tag = &bitmap;
    }
  }
  // Background traffic: each object's bounding sphere against the view first, so that a
  // city's thousands of objects out of view cost a few products each and build no parts; one
  // whose sphere is under kFarPx pixels in radius is a single block.
  if (!frame.traffic.empty()) {
    constexpr double kFarPx = 6.0;
    const Eigen::Matrix3d R_CM = X_MC.linear().transpose();
    const Eigen::Vector3d p_MC = X_MC.translation();
    for (const RenderTraffic& o : frame.traffic) {
      const Eigen::Vector3d centre_M = o.X_MO * Eigen::Vector3d(0, 0, o.size_m.z() / 2);
      const Eigen::Vector3d centre_C = R_CM * (centre_M - p_MC);
      const double radius = o.size_m.norm() / 2;
      if (!SphereInView(centre_C, radius)) continue;
      AddTraffic(o, blink, f_px * radius < kFarPx * centre_C.z());
      ++stats.traffic_in_view;
    }
  }
  std::fill(lamp_state.begin(), lamp_state.end(), 0);
  for (const HeadLamps& l : frame.lamps) {
    const auto i = static_cast<std::size_t>(l.head.value() - 1);
    if (i < lamp_state.size()) {
      lamp_state[i] =
          static_cast<std::uint8_t>((l.red ? 1 : 0) | (l.yellow ? 2 : 0) | (l.green ? 4 : 0));
    }
  }
  frame_parts.clear();
  const auto add = [&](const RenderPart& part) {
    FramePart& fp = frame_parts.emplace_back();
    fp.part = &part;
    Shade(fp);
    Place(fp, X_MC);
    if (fp.x1 <= fp.x0 || fp.y1 <= fp.y0) frame_parts.pop_back();
  };
  for (const RenderPart& part : world->impl_->parts) add(part);
  for (const RenderPart& part : dynamic_parts) add(part);
}

// Light: the shade of each face relative to the ground's (which the map's picture shows as is).
void CameraRenderer::Impl::Shade(FramePart& fp) const {
  const Eigen::Vector3d light(std::cos(film.light_elevation_rad) * std::cos(film.light_azimuth_rad),
                              std::cos(film.light_elevation_rad) * std::sin(film.light_azimuth_rad),
                              std::sin(film.light_elevation_rad));
  const double ground_shade = film.ambient + film.light_intensity * std::max(0.0, light.z());
  for (int k = 0; k < 6; ++k) {
    const Eigen::Vector3d n = fp.part->R_MB.col(k / 2) * (k % 2 == 0 ? 1.0 : -1.0);
    fp.shade[static_cast<std::size_t>(k)] =
        static_cast<float>((film.ambient + film.light_intensity * std::max(0.0, n.dot(light))) /
                           std::max(1e-6, ground_shade));
  }
}

void CameraRenderer::Impl::Place(FramePart& fp, const Eigen::Isometry3d& X_MC) {
  const RenderPart& part = *fp.part;
  const Eigen::Matrix3d R_BM = part.R_MB.transpose();
  fp.Q = (R_BM * X_MC.linear()).cast<float>();
  fp.o = (R_BM * (X_MC.translation() - part.p_MB)).cast<float>();
  // The part's corners in the camera frame.
  const Eigen::Isometry3d X_CM = X_MC.inverse();
  std::array<Eigen::Vector3d, 8> corners;
  bool all_behind = true, any_behind = false;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d local(part.half.x() * ((k & 1) ? 1 : -1),
                                part.half.y() * ((k & 2) ? 1 : -1),
                                part.half.z() * ((k & 4) ? 1 : -1));
    corners[static_cast<std::size_t>(k)] = X_CM * (part.R_MB * local + part.p_MB);
    const bool behind = corners[static_cast<std::size_t>(k)].z() <= 1e-3;
    all_behind = all_behind && behind;
    any_behind = any_behind || behind;
  }
  fp.x0 = fp.y0 = fp.x1 = fp.y1 = 0;
  if (all_behind) return;
  // Against each tile's pyramid: the part is outside when all its corners are outside one of
  // the pyramid's planes. Cheap enough to run for every part; precise for parts near the edges
  // or partly behind the camera, where projecting corners fails.
  const auto visible_in = [&](const std::array<Eigen::Vector3f, 4>& planes) {
    for (const Eigen::Vector3f& n : planes) {
      bool all_out = true;
      for (const Eigen::Vector3d& c : corners) {
        if (n.x() * c.x() + n.y() * c.y() + n.z() * c.z() >= 0) {
          all_out = false;
          break;
        }
      }
      if (all_out) return false;
    }
    return true;
  };
  if (!visible_in(image_planes)) return;  // outside the view
  int tx0 = 0, ty0 = 0, tx1 = tw, ty1 = th;
  // Without distortion a part in front of the camera lies inside its corners' projections.
  std::optional<std::array<int, 4>> exact;
  if (!any_behind) {
    // A first bound from the projected corners, widened by a tile for the lens' bending.
    double u0 = 1e30, v0 = 1e30, u1 = -1e30, v1 = -1e30;
    bool ok = true;
    for (const Eigen::Vector3d& c : corners) {
      const auto px = model.Project(c);
      if (!px) {
        ok = false;
        break;
      }
      u0 = std::min(u0, px->x());
      v0 = std::min(v0, px->y());
      u1 = std::max(u1, px->x());
      v1 = std::max(v1, px->y());
    }
    if (ok) {
      tx0 = std::clamp(static_cast<int>(std::floor(u0 / kTile)) - 1, 0, tw);
      ty0 = std::clamp(static_cast<int>(std::floor(v0 / kTile)) - 1, 0, th);
      tx1 = std::clamp(static_cast<int>(std::floor(u1 / kTile)) + 2, 0, tw);
      ty1 = std::clamp(static_cast<int>(std::floor(v1 / kTile)) + 2, 0, th);
      if (!distorted) {
        exact = std::array<int, 4>{
            static_cast<int>(std::floor(u0)) - 1, static_cast<int>(std::floor(v0)) - 1,
            static_cast<int>(std::ceil(u1)) + 2, static_cast<int>(std::ceil(v1)) + 2};
      }
    }
  }
  int bx0 = tw, by0 = th, bx1 = 0, by1 = 0;
  for (int ty = ty0; ty < ty1; ++ty) {
    for (int tx = tx0; tx < tx1; ++tx) {
      if (!visible_in(tile_planes[static_cast<std::size_t>(ty * tw + tx)])) continue;
      bx0 = std::min(bx0, tx);
      by0 = std::min(by0, ty);
      bx1 = std::max(bx1, tx + 1);
      by1 = std::max(by1, ty + 1);
    }
  }
  if (bx1 <= bx0) return;
  fp.x0 = bx0 * kTile;
  fp.y0 = by0 * kTile;
  fp.x1 = std::min(w, bx1 * kTile);
  fp.y1 = std::min(h, by1 * kTile);
  if (exact) {
    fp.x0 = std::max(fp.x0, (*exact)[0]);
    fp.y0 = std::max(fp.y0, (*exact)[1]);
    fp.x1 = std::min(fp.x1, (*exact)[2]);
    fp.y1 = std::min(fp.y1, (*exact)[3]);
  }
}

namespace {

// The ray (Q r from o) against the part: the range and the face hit (0..5: +x, -x, +y, -y, +z,
// -z), or a range of infinity.
struct PartHit {
  float t = std::numeric_limits<float>::infinity();
  int face = -1;
  Eigen::Vector3f p;  ///< the hit, in the part's frame
};

inline PartHit Intersect(const RenderPart& part, const Eigen::Vector3f& o, const Eigen::Vector3f& d,
                         float t_max) {
  PartHit hit;
  const Eigen::Vector3f half = part.half.cast<float>();
  float t_near = 0.0f, t_far = t_max;
  int face = -1;
  if (part.terrain) {
    const float den = d.z() - part.a * d.x() - part.b * d.y();
    if (std::abs(den) < 1e-12f) return hit;
    const float t = (part.a * o.x() + part.b * o.y() + part.c - o.z()) / den;
    if (!(t > 0 && t < t_max)) return hit;
    const Eigen::Vector3f p = o + t * d;
    if (std::abs(p.x()) > half.x() || std::abs(p.y()) > half.y()) return hit;
    hit.t = t;
    hit.face = 4;
    hit.p = p;
    return hit;
  }
  if (!part.cylinder) {
    for (int k = 0; k < 3; ++k) {
      if (std::abs(d[k]) < 1e-12f) {
        if (std::abs(o[k]) > half[k]) return hit;
        continue;
      }
      const float inv = 1.0f / d[k];
      float t0 = (-half[k] - o[k]) * inv;
      float t1 = (half[k] - o[k]) * inv;
      int f = 2 * k + 1;  // entering through the -k face
      if (t0 > t1) {
        std::swap(t0, t1);
        f = 2 * k;
      }
      if (t0 > t_near) {
        t_near = t0;
        face = f;
      }
      t_far = std::min(t_far, t1);
      if (t_near > t_far) return hit;
    }
  } else {
    // The side: (o + t d)_xy on the circle of radius r.
    const float a = d.x() * d.x() + d.y() * d.y();
    const float r = half.x();
    float s0 = -std::numeric_limits<float>::infinity(), s1 = std::numeric_limits<float>::infinity();
    if (a > 1e-12f) {
      const float b = o.x() * d.x() + o.y() * d.y();
      const float c = o.x() * o.x() + o.y() * o.y() - r * r;
      const float disc = b * b - a * c;
      if (disc < 0) return hit;
      const float sq = std::sqrt(disc);
      s0 = (-b - sq) / a;
      s1 = (-b + sq) / a;
    } else if (o.x() * o.x() + o.y() * o.y() > r * r) {
      return hit;
    }
    float z0 = -std::numeric_limits<float>::infinity(), z1 = std::numeric_limits<float>::infinity();
    int zf = -1;
    if (std::abs(d.z()) > 1e-12f) {
      z0 = (-half.z() - o.z()) / d.z();
      z1 = (half.z() - o.z()) / d.z();
      zf = 5;
      if (z0 > z1) {
        std::swap(z0, z1);
        zf = 4;
      }
    } else if (std::abs(o.z()) > half.z()) {
      return hit;
    }
    if (s0 >= z0) {
      t_near = s0;
      face = 0;  // the side (shaded by its normal below)
    } else {
      t_near = z0;
      face = zf;
    }
    t_far = std::min({t_far, s1, z1});
    if (t_near > t_far || t_near <= 0) return hit;
  }
  if (face < 0 || t_near <= 0) return hit;
  hit.t = t_near;
  hit.face = face;
  hit.p = o + t_near * d;
  return hit;
}

inline void Put(std::uint8_t* px, Rgb c, float shade) {
  px[0] = static_cast<std::uint8_t>(std::min(255.0f, c.r * shade));
  px[1] = static_cast<std::uint8_t>(std::min(255.0f, c.g * shade));
  px[2] = static_cast<std::uint8_t>(std::min(255.0f, c.b * shade));
}

inline bool InDisc(float y, float z, float cy, float cz, float r) {
  return (y - cy) * (y - cy) + (z - cz) * (z - cz) <= r * r;
}

}  // namespace

void CameraRenderer::Impl::DrawPixel(const FramePart& fp, int u, int v, const Eigen::Vector3f& r,
                                     const Eigen::Vector3f& d, float* depth_buffer) {
  const std::size_t i = Index(u, v);
  const RenderPart& part = *fp.part;
  const PartHit hit = Intersect(part, fp.o, d, depth_buffer[i]);
  if (!(hit.t < depth_buffer[i])) return;
  depth_buffer[i] = hit.t;
  std::uint8_t* px = target + 3 * i;
  float shade = fp.shade[static_cast<std::size_t>(hit.face)];
  if (part.cylinder && hit.face == 0) {
    // The side's normal: radial, in the part's frame (vertical axis, so the map's light
    // direction in the part's frame equals the map's up to a yaw; the shade of +x/-x/+y/-y
    // faces interpolates well enough).
    const float nx = hit.p.x() / static_cast<float>(part.half.x());
    const float ny = hit.p.y() / static_cast<float>(part.half.y());
    shade = std::max(nx, 0.0f) * fp.shade[0] + std::max(-nx, 0.0f) * fp.shade[1] +
            std::max(ny, 0.0f) * fp.shade[2] + std::max(-ny, 0.0f) * fp.shade[3];
  }
  Rgb c = part.colour;
  if (part.terrain) {
    // The ground's picture at the hit, at the level of the pixel's footprint: area
    // t^2 / (fx fy |r| cos) for the ray r = (x, y, 1) meeting the plane at cosine cos.
    const GroundPyramid& g = world->impl_->ground;
    const float cos_incidence = std::abs(d.z() - part.a * d.x() - part.b * d.y()) /
                                (d.norm() * std::sqrt(1.0f + part.a * part.a + part.b * part.b));
    const float texel = static_cast<float>(g.texel_m);
    const float area =
        hit.t * hit.t / (fx * fy * r.norm() * std::max(cos_incidence, 1e-3f) * texel * texel);
    c = SampleGround(static_cast<float>(part.p_MB.x()) + hit.p.x(),
                     static_cast<float>(part.p_MB.y()) + hit.p.y(), area);
    shade = 1.0f;
  }
  switch (part.decal) {
    case Decal::kNone:
      break;
    case Decal::kTag:
      if (hit.face == 4) {
        // Supersampled 4 x 4 over the pixel: the sub-pixel rays (exact without distortion,
        // else interpolated between the pixel's ray and its neighbours'), each met with the
        // face's plane.
        const TagBitmap& tag = *part.tag;
        const float half = static_cast<float>(part.half.x());
        const float cell = 2 * half / static_cast<float>(tag.total);
        Eigen::Vector3f du(1.0f / fx, 0, 0), dv(0, 1.0f / fy, 0);
        if (distorted) {
          const int un = u + 1 < w ? u + 1 : u - 1, vn = v + 1 < h ? v + 1 : v - 1;
          du = (Ray(un, v) - r) * static_cast<float>(un - u);
          dv = (Ray(u, vn) - r) * static_cast<float>(vn - v);
          if (std::isnan(du.x()) || std::isnan(dv.x())) du = dv = Eigen::Vector3f::Zero();
        }
        const float top = static_cast<float>(part.half.z());
        int white = 0;
        constexpr int kS = 4;
        for (int a = 0; a < kS; ++a) {
          for (int b = 0; b < kS; ++b) {
            const float fu = (static_cast<float>(b) + 0.5f) / kS - 0.5f;
            const float fv = (static_cast<float>(a) + 0.5f) / kS - 0.5f;
            const Eigen::Vector3f ds = fp.Q * (r + fu * du + fv * dv);
            const float t = std::abs(ds.z()) > 1e-12f ? (top - fp.o.z()) / ds.z() : -1.0f;
            const float x = fp.o.x() + t * ds.x(), y = fp.o.y() + t * ds.y();
            const int col = static_cast<int>(std::floor((x + half) / cell));
            const int row = static_cast<int>(std::floor((half - y) / cell));
            if (t <= 0 || col < 0 || row < 0 || col >= tag.total || row >= tag.total ||
                tag.white[static_cast<std::size_t>(row * tag.total + col)]) {
              ++white;
            }
          }
        }
        const float k = static_cast<float>(white) / (kS * kS);
        c = {static_cast<std::uint8_t>(kTagBlack.r + k * (kPlateColour.r - kTagBlack.r)),
             static_cast<std::uint8_t>(kTagBlack.g + k * (kPlateColour.g - kTagBlack.g)),
             static_cast<std::uint8_t>(kTagBlack.b + k * (kPlateColour.b - kTagBlack.b))};
      }
      break;
    case Decal::kLamps:
      if (hit.face == 0) {
        const std::uint8_t lit = lamp_state[static_cast<std::size_t>(part.head)];
        static constexpr std::array<Rgb, 3> kOn{Rgb{255, 40, 30}, Rgb{255, 190, 20},
                                                Rgb{40, 255, 90}};
        static constexpr std::array<Rgb, 3> kOff{Rgb{70, 12, 10}, Rgb{70, 52, 8}, Rgb{10, 60, 22}};
        for (int k = 0; k < 3; ++k) {
          if (InDisc(hit.p.y(), hit.p.z(), 0.0f,
                     static_cast<float>(part.lamp_z[static_cast<std::size_t>(k)]),
                     static_cast<float>(part.lamp_radius))) {
            const bool on = (lit >> k) & 1;
            c = on ? kOn[static_cast<std::size_t>(k)] : kOff[static_cast<std::size_t>(k)];
            if (on) shade = 1.0f;  // emits
          }
        }
      }
      break;
    case Decal::kVehicleFront:
    case Decal::kVehicleRear:
    case Decal::kTrafficEnds: {
      const bool front =
          part.decal == Decal::kTrafficEnds ? hit.face == 0 : part.decal == Decal::kVehicleFront;
      if (hit.face != (front ? 0 : 1)) break;
      const float hy = static_cast<float>(part.half.y()), hz = static_cast<float>(part.half.z());
      const float y = hit.p.y(), z = hit.p.z();
      const float lamp = std::min(hy, hz) * 0.35f;
      // Indicators at the outer corners, lights inboard of them.
      for (int side = -1; side <= 1; side += 2) {
        const float iy = static_cast<float>(side) * (hy - lamp * 1.2f);
        if (std::abs(y - iy) < lamp && std::abs(z - hz * 0.3f) < lamp * 0.8f) {
          const bool on = (part.lights >> (side > 0 ? 1 : 2)) & 1;
          c = on ? Rgb{255, 170, 0} : Rgb{120, 80, 20};
          if (on) shade = 1.0f;
        }
        const float ly = static_cast<float>(side) * (hy - lamp * 3.6f);
        if (std::abs(y - ly) < lamp && std::abs(z - hz * 0.3f) < lamp * 0.8f) {
          // At the back: the tail lights, lit with the headlights or as brake lights.
          const bool on = (part.lights & (front ? 1 : 9)) != 0;
          if (front) {
            c = on ? Rgb{255, 255, 230} : Rgb{190, 190, 180};
          } else {
            c = on ? Rgb{255, 40, 40} : Rgb{120, 15, 15};
          }
          if (on) shade = 1.0f;
        }
      }
      break;
    }
    case Decal::kSign:
      if (hit.face == 0) {
        const float radius = static_cast<float>(std::min(part.half.y(), part.half.z()));
        if (InDisc(hit.p.y(), hit.p.z(), 0, 0, radius * 0.95f)) c = part.decal_colour;
      }
      break;
  }
  Put(px, c, shade);
}

void CameraRenderer::Impl::DrawPart(const FramePart& fp, float* depth_buffer) {
  // Rays that miss the part's bounding sphere (centre 0, radius |half| in the part's frame) are
  // rejected with a few products and no division: o + t d meets it for some t > 0 only if
  // c = |o|^2 - R^2 <= 0 (the camera inside) or b = o.d < 0 and b^2 >= |d|^2 c.
  const float c = fp.o.squaredNorm() - fp.part->half.cast<float>().squaredNorm();
  const auto misses = [&](const Eigen::Vector3f& d) {
    if (c <= 0) return false;
    const float b = fp.o.dot(d);
    return b >= 0 || b * b < d.squaredNorm() * c;
  };
  if (!distorted) {
    // d = Q (x_u, y_v, 1): per row e = Q (0, y_v, 1), per pixel d = e + x_u Q_0.
    const Eigen::Vector3f q0 = fp.Q.col(0);
    for (int v = fp.y0; v < fp.y1; ++v) {
      const float y = (static_cast<float>(v) - cy) * inv_fy;
      const Eigen::Vector3f e = fp.Q.col(1) * y + fp.Q.col(2);
      for (int u = fp.x0; u < fp.x1; ++u) {
        const float x = column_x[static_cast<std::size_t>(u)];
        const Eigen::Vector3f d = e + x * q0;
        if (misses(d)) continue;
        DrawPixel(fp, u, v, Eigen::Vector3f(x, y, 1.0f), d, depth_buffer);
      }
    }
    return;
  }
  for (int v = fp.y0; v < fp.y1; ++v) {
    for (int u = fp.x0; u < fp.x1; ++u) {
      const Eigen::Vector3f r = Ray(u, v);
      if (std::isnan(r.x())) continue;  // beyond the lens' fold
      const Eigen::Vector3f d = fp.Q * r;
      if (misses(d)) continue;
      DrawPixel(fp, u, v, r, d, depth_buffer);
    }
  }
}

void CameraRenderer::Impl::DrawTerrain(const Eigen::Isometry3d& X_MC) {
  const auto& terrain = world->impl_->terrain;
  for (const auto& [x0, y0, x1, y1] : terrain_rects) {
    for (int v = y0; v < y1; ++v) {
      std::fill_n(ground_depth.begin() + static_cast<std::ptrdiff_t>(Index(x0, v)), x1 - x0,
                  std::numeric_limits<float>::infinity());
    }
  }
  terrain_rects.clear();
  for (const RenderPart& part : terrain) {
    FramePart fp;
    fp.part = &part;
    Shade(fp);
    Place(fp, X_MC);
    if (fp.x1 <= fp.x0 || fp.y1 <= fp.y0) continue;
    DrawPart(fp, ground_depth.data());
    terrain_rects.push_back({fp.x0, fp.y0, fp.x1, fp.y1});
  }
}

Rgb CameraRenderer::Impl::SampleGround(float x, float y, float area_texels) const {
  const GroundPyramid& g = world->impl_->ground;
  int level = 0;
  while (level + 1 < static_cast<int>(g.levels.size()) &&
         area_texels >= std::ldexp(0.5f, 2 * (level + 1))) {
    ++level;
  }
  const auto& l = g.levels[static_cast<std::size_t>(level)];
  const float inv = static_cast<float>(std::ldexp(1.0 / g.texel_m, -level));
  const float u = std::clamp((x - static_cast<float>(g.x0_m)) * inv - 0.5f, 0.0f,
                             static_cast<float>(l.w) - 1.001f);
  const float v = std::clamp((static_cast<float>(g.y1_m) - y) * inv - 0.5f, 0.0f,
                             static_cast<float>(l.h) - 1.001f);
  const int i = static_cast<int>(u), j = static_cast<int>(v);
  const float wu = u - static_cast<float>(i), wv = v - static_cast<float>(j);
  const auto* p00 = g.atlas.ptr<std::uint8_t>(l.y + j) + 3 * (l.x + i);
  const auto* p10 = g.atlas.ptr<std::uint8_t>(l.y + j + 1) + 3 * (l.x + i);
  std::array<std::uint8_t, 3> c{};
  for (std::size_t k = 0; k < 3; ++k) {
    const float top = p00[k] + wu * static_cast<float>(p00[k + 3] - p00[k]);
    const float bottom = p10[k] + wu * static_cast<float>(p10[k + 3] - p10[k]);
    c[k] = static_cast<std::uint8_t>(top + wv * (bottom - top) + 0.5f);
  }
  return {c[0], c[1], c[2]};
}

void CameraRenderer::Impl::RenderOnce(const Eigen::Isometry3d& X_MC, const FrameState& frame,
                                      std::optional<int> exclude) {
  const auto t0 = std::chrono::steady_clock::now();
  DrawGround(X_MC);
  const auto t1 = std::chrono::steady_clock::now();
  BuildParts(X_MC, frame, exclude);
  // The flat ground lies under every part (the camera above it), so only parts and the raised
  // ground compete for a pixel: the depth buffer is needed inside the parts' rectangles only.
  for (const FramePart& fp : frame_parts) {
    for (int v = fp.y0; v < fp.y1; ++v) {
      const auto at = static_cast<std::ptrdiff_t>(Index(fp.x0, v));
      std::copy_n(ground_depth.begin() + at, fp.x1 - fp.x0, depth.begin() + at);
    }
  }
  for (const FramePart& fp : frame_parts) {
    DrawPart(fp, depth.data());
    stats.pixels_tested += static_cast<std::int64_t>(fp.x1 - fp.x0) * (fp.y1 - fp.y0);
  }
  stats.parts_drawn += static_cast<int>(frame_parts.size());
  const auto t2 = std::chrono::steady_clock::now();
  stats.ground_ms += std::chrono::duration<double, std::milli>(t1 - t0).count();
  stats.objects_ms += std::chrono::duration<double, std::milli>(t2 - t1).count();
}

CameraRenderer::CameraRenderer(std::shared_ptr<const RenderWorld> world,
                               const camera::Intrinsics& intrinsics, const FilmOptions& film)
    : impl_(std::make_unique<Impl>(std::move(world), intrinsics, film)) {}

CameraRenderer::~CameraRenderer() = default;

const camera::CameraModel& CameraRenderer::model() const { return impl_->model; }
const FilmOptions& CameraRenderer::film() const { return impl_->film; }
const RenderStats& CameraRenderer::stats() const { return impl_->stats; }

void CameraRenderer::Render(const Eigen::Isometry3d& X_MC, const FrameState& frame, Image& out,
                            std::optional<int> exclude, const Eigen::Vector3d& v_M_mps,
                            const Eigen::Vector3d& w_M_radps, std::uint64_t noise_seed) {
  Impl& m = *impl_;
  const FilmOptions& film = m.film;
  m.stats = {};
  out.width_px = m.w;
  out.height_px = m.h;
  const std::size_t bytes = m.colour.size();
  out.rgb.resize(bytes);
  if (film.exposure_time_s > 0) {
    // Motion blur: sub-frames at instants spread over the exposure, the vehicles and the camera
    // moved rigidly by their velocities.
    m.accumulator.assign(bytes, 0);
    const int n = film.motion_blur_samples;
    m.moved.assign(frame.vehicles.begin(), frame.vehicles.end());
    m.moved_traffic.assign(frame.traffic.begin(), frame.traffic.end());
    for (int s = 0; s < n; ++s) {
      const double dt = film.exposure_time_s * ((s + 0.5) / n - 0.5);
      const auto shift = [dt](const Eigen::Isometry3d& X, const Eigen::Vector3d& v,
                              const Eigen::Vector3d& w_) {
        Eigen::Isometry3d Y = X;
        Y.translation() += v * dt;
        if (w_.norm() > 0) {
          Y.linear() = Eigen::AngleAxisd(w_.norm() * dt, w_.normalized()) * X.linear();
        }
        return Y;
      };
      for (std::size_t k = 0; k < m.moved.size(); ++k) {
        m.moved[k].X_MV =
            shift(frame.vehicles[k].X_MV, frame.vehicles[k].v_M_mps, frame.vehicles[k].w_M_radps);
      }
      for (std::size_t k = 0; k < m.moved_traffic.size(); ++k) {
        const RenderTraffic& o = frame.traffic[k];
        m.moved_traffic[k].X_MO = o.X_MO;
        m.moved_traffic[k].X_MO.translation() += o.X_MO.linear().col(0) * (o.speed_mps * dt);
      }
      FrameState sub = frame;
      sub.vehicles = m.moved;
      sub.traffic = m.moved_traffic;
      sub.time_s = frame.time_s + dt;
      m.target = m.colour.data();
      m.RenderOnce(shift(X_MC, v_M_mps, w_M_radps), sub, exclude);
      for (std::size_t k = 0; k < bytes; ++k) m.accumulator[k] += m.colour[k];
    }
    const auto half = static_cast<std::uint16_t>(n / 2);
    const auto count = static_cast<std::uint16_t>(n);
    for (std::size_t k = 0; k < bytes; ++k) {
      out.rgb[k] = static_cast<std::uint8_t>((m.accumulator[k] + half) / count);
    }
  } else {
    m.target = out.rgb.data();
    m.RenderOnce(X_MC, frame, exclude);
  }
  const auto film0 = std::chrono::steady_clock::now();
  cv::Mat image(m.h, m.w, CV_8UC3, out.rgb.data());
  if (film.blur_sigma_px > 0) {
    // A kernel of +-2 sigma (95% of the Gaussian's weight): OpenCV's default of +-3 sigma costs
    // a third more for weights under 1%.
    const int radius = std::max(1, static_cast<int>(std::ceil(2.0 * film.blur_sigma_px)));
    cv::GaussianBlur(image, image, cv::Size(2 * radius + 1, 2 * radius + 1), film.blur_sigma_px);
  }
  if (film.exposure != 1.0) image.convertTo(image, CV_8UC3, film.exposure);
  if (film.noise_sigma > 0) {
    // A window of the camera's block of noise at an offset drawn from the frame's seed.
    std::mt19937_64 rng(noise_seed);
    const auto ox = static_cast<std::size_t>(rng() % 64), oy = static_cast<std::size_t>(rng() % 64);
    const std::size_t row = m.W() * 3;
    for (std::size_t v = 0; v < static_cast<std::size_t>(m.h); ++v) {
      const std::int8_t* noise = m.noise.ptr<std::int8_t>(static_cast<int>(v + oy)) + ox * 3;
      std::uint8_t* px = out.rgb.data() + v * row;
      for (std::size_t k = 0; k < row; ++k) {
        const int value = px[k] + noise[k];
        px[k] = static_cast<std::uint8_t>(value < 0 ? 0 : value > 255 ? 255 : value);
      }
    }
  }
  m.stats.film_ms +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - film0).count();
}

}  // namespace autodrive::vehicle_sim
