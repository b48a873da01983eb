#include "vehicle_sim/renderer.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h10.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>
#include <random>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

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

/// The ground's picture and its mip pyramid, RGBX texels (R in the low byte). Level k's texel
/// (i, j) covers level 0's texels [2^k i, 2^k (i + 1)) x [2^k j, 2^k (j + 1)).
struct GroundPyramid {
  double texel_m = 0.002;
  double x0_m = 0.0;  ///< map x of level 0's left edge
  double y1_m = 0.0;  ///< map y of level 0's top edge
  struct Level {
    int w = 0, h = 0;
    std::vector<std::uint32_t> texels;
  };
  std::vector<Level> levels;
};

/// What is drawn on a face.
enum class Decal : std::uint8_t {
  kNone,
  kTag,           ///< the part's tag bitmap over the whole face (+z)
  kLamps,         ///< a signal head's three lamps (+x face)
  kVehicleFront,  ///< headlights and front indicators (+x face)
  kVehicleRear,   ///< tail lights and rear indicators (-x face)
  kSign,          ///< a sign's disc (+x face)
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
  int head = -1;            ///< kLamps: index of the head in the map
  Rgb decal_colour;         ///< kSign: the disc's colour
  std::uint8_t lights = 0;  ///< vehicles: bit 0 headlights, 1 left, 2 right indicator lit now
  std::array<double, 3> lamp_z{};  ///< kLamps: heights of red, yellow, green in B
  double lamp_radius = 0.0;
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

std::uint32_t Pack(Rgb c) {
  return static_cast<std::uint32_t>(c.r) | (static_cast<std::uint32_t>(c.g) << 8) |
         (static_cast<std::uint32_t>(c.b) << 16);
}

struct Family {
  apriltag_family_t* (*create)();
  void (*destroy)(apriltag_family_t*);
};

const std::map<std::string, Family, std::less<>>& Families() {
  static const std::map<std::string, Family, std::less<>> kFamilies{
      {"tag16h5", {tag16h5_create, tag16h5_destroy}},
      {"tag25h9", {tag25h9_create, tag25h9_destroy}},
      {"tag36h10", {tag36h10_create, tag36h10_destroy}},
      {"tag36h11", {tag36h11_create, tag36h11_destroy}},
      {"tagCircle21h7", {tagCircle21h7_create, tagCircle21h7_destroy}},
      {"tagCircle49h12", {tagCircle49h12_create, tagCircle49h12_destroy}},
      {"tagCustom48h12", {tagCustom48h12_create, tagCustom48h12_destroy}},
      {"tagStandard41h12", {tagStandard41h12_create, tagStandard41h12_destroy}},
      {"tagStandard52h13", {tagStandard52h13_create, tagStandard52h13_destroy}},
  };
  return kFamilies;
}

TagBitmap MakeTagBitmap(const TagSpec& spec) {
  const auto it = Families().find(spec.family);
  if (it == Families().end()) {
    std::string names;
    for (const auto& [name, f] : Families()) names += (names.empty() ? "" : ", ") + name;
    throw InputError("unknown AprilTag family \"" + spec.family + "\" (known: " + names + ")");
  }
  apriltag_family_t* family = it->second.create();
  const int ncodes = static_cast<int>(family->ncodes);
  if (spec.id < 0 || spec.id >= ncodes) {
    it->second.destroy(family);
    throw InputError("AprilTag family " + spec.family + " has ids 0.." +
                     std::to_string(ncodes - 1) + ", not " + std::to_string(spec.id));
  }
  image_u8_t* image = apriltag_to_image(family, spec.id);
  TagBitmap bitmap;
  bitmap.total = family->total_width;
  bitmap.at_border = family->width_at_border;
  bitmap.white.resize(static_cast<std::size_t>(bitmap.total * bitmap.total));
  for (int y = 0; y < bitmap.total; ++y) {
    for (int x = 0; x < bitmap.total; ++x) {
      bitmap.white[static_cast<std::size_t>(y * bitmap.total + x)] =
          image->buf[y * image->stride + x] > 127 ? 1 : 0;
    }
  }
  image_u8_destroy(image);
  it->second.destroy(family);
  return bitmap;
}

GroundPyramid MakeGround(const maps::Map& map, double texel_m) {
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
  cv::Mat level0(h, w, CV_8UC4, cv::Scalar(kFloor.r, kFloor.g, kFloor.b, 0));
  for (int y = 0; y < picture.height_px; ++y) {
    for (int x = 0; x < picture.width_px; ++x) {
      const std::size_t k =
          (static_cast<std::size_t>(y) * static_cast<std::size_t>(picture.width_px) +
           static_cast<std::size_t>(x)) *
          3;
      level0.at<cv::Vec4b>(y + kBorder, x + kBorder) =
          cv::Vec4b(picture.rgb[k], picture.rgb[k + 1], picture.rgb[k + 2], 0);
    }
  }
  cv::Mat level = level0;
  for (int k = 0; k < kLevels; ++k) {
    GroundPyramid::Level& l = g.levels.emplace_back();
    l.w = level.cols;
    l.h = level.rows;
    l.texels.resize(static_cast<std::size_t>(l.w) * static_cast<std::size_t>(l.h));
    std::memcpy(l.texels.data(), level.data, l.texels.size() * 4);
    if (l.w < 2 || l.h < 2) break;
    cv::Mat next;
    cv::resize(level, next, cv::Size(level.cols / 2, level.rows / 2), 0, 0, cv::INTER_AREA);
    level = next;
  }
  return g;
}

// Bilinear sample of an RGBX texture at continuous texel-centre coordinates (u, v): texel
// (i, j)'s centre is at (i, j). Coordinates outside the texture clamp to its edge, which is
// the lab's floor.
inline std::uint32_t Bilinear(const GroundPyramid::Level& l, float u, float v) {
  u = std::clamp(u, 0.0f, static_cast<float>(l.w - 1) - 1e-3f);
  v = std::clamp(v, 0.0f, static_cast<float>(l.h - 1) - 1e-3f);
  const int i = static_cast<int>(u);
  const int j = static_cast<int>(v);
  const auto fx = static_cast<std::uint32_t>((u - static_cast<float>(i)) * 256.0f);
  const auto fy = static_cast<std::uint32_t>((v - static_cast<float>(j)) * 256.0f);
  const std::uint32_t* p = l.texels.data() +
                           static_cast<std::size_t>(j) * static_cast<std::size_t>(l.w) +
                           static_cast<std::size_t>(i);
  const std::uint32_t c00 = p[0], c01 = p[1], c10 = p[l.w], c11 = p[l.w + 1];
  const std::uint32_t w11 = (fx * fy) >> 8;
  const std::uint32_t w01 = fx - w11;
  const std::uint32_t w10 = fy - w11;
  const std::uint32_t w00 = 256 - fx - fy + w11;
  const std::uint32_t rb = ((c00 & 0xff00ffu) * w00 + (c01 & 0xff00ffu) * w01 +
                            (c10 & 0xff00ffu) * w10 + (c11 & 0xff00ffu) * w11) >>
                           8;
  const std::uint32_t g = ((c00 & 0xff00u) * w00 + (c01 & 0xff00u) * w01 + (c10 & 0xff00u) * w10 +
                           (c11 & 0xff00u) * w11) >>
                          8;
  return (rb & 0xff00ffu) | (g & 0xff00u);
}

Rgb SignColour(const std::string& type) {
  if (type == "stop" || type == "no_entry") return {200, 20, 20};
  if (type == "parking" || type == "one_way" || type == "pedestrian_crossing") return {30, 80, 200};
  if (type == "yield") return {240, 240, 240};
  return {240, 240, 240};
}

}  // namespace

// ---- RenderWorld ----------------------------------------------------------------------------

bool FilmOptions::AnyEffect() const {
  return exposure != 1.0 || exposure_time_s > 0.0 || blur_sigma_px > 0.0 || noise_sigma > 0.0;
}

struct RenderWorld::Impl {
  RenderWorldOptions options;
  GroundPyramid ground;
  std::vector<RenderPart> parts;  ///< static
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
  impl_->ground = MakeGround(map, options.ground_texel_m);
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
  std::vector<float> rx, ry, rz;  ///< unit rays in C, per pixel
  float f_px = 1.0f;
  // Tiles of kTile x kTile pixels: the inward normals of the four planes through the camera's
  // centre and the tile's corner rays.
  int tw = 0, th = 0;
  std::vector<std::array<Eigen::Vector3f, 4>> tile_planes;

  // Buffers.
  std::vector<float> depth;
  std::vector<std::uint8_t> colour;  ///< rgb
  std::vector<RenderPart> dynamic_parts;
  std::vector<FramePart> frame_parts;
  std::vector<std::uint8_t> lamp_state;  ///< per head: bits red, yellow, green
  std::vector<std::uint16_t> accumulator;
  cv::Mat noise;  ///< a block of Gaussian noise, offset at random per frame
  // The ground as last drawn: reused while the camera does not move.
  Eigen::Isometry3d cached_pose;
  bool have_cache = false;
  std::vector<float> cached_depth;
  std::vector<std::uint8_t> cached_colour;

  Impl(std::shared_ptr<const RenderWorld> w_, const camera::Intrinsics& intrinsics,
       const FilmOptions& f)
      : world(std::move(w_)), model(intrinsics), film(f) {
    AUTODRIVE_THROW_UNLESS(world != nullptr, "CameraRenderer: no world");
    w = intrinsics.width_px;
    h = intrinsics.height_px;
    f_px = static_cast<float>(std::sqrt(intrinsics.fx_px * intrinsics.fy_px));
    const std::size_t n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
    rx.resize(n);
    ry.resize(n);
    rz.resize(n);
    for (int v = 0; v < h; ++v) {
      for (int u = 0; u < w; ++u) {
        const auto ray = model.Unproject({u, v});
        const std::size_t i = Index(u, v);
        // A pixel beyond the lens model's fold sees nothing: a ray straight back.
        const Eigen::Vector3d d = ray ? *ray : Eigen::Vector3d(0, 0, -1);
        rx[i] = static_cast<float>(d.x());
        ry[i] = static_cast<float>(d.y());
        rz[i] = static_cast<float>(d.z());
      }
    }
    tw = (w + kTile - 1) / kTile;
    th = (h + kTile - 1) / kTile;
    tile_planes.resize(static_cast<std::size_t>(tw * th));
    for (int ty = 0; ty < th; ++ty) {
      for (int tx = 0; tx < tw; ++tx) {
        // The tile's outer corners, half a pixel beyond its pixel centres and a pixel more of
        // margin; the corner rays in clockwise image order.
        const double u0 = tx * kTile - 1.5, v0 = ty * kTile - 1.5;
        const double u1 = std::min(w, (tx + 1) * kTile) + 0.5,
                     v1 = std::min(h, (ty + 1) * kTile) + 0.5;
        const std::array<Eigen::Vector2d, 4> corners{
            Eigen::Vector2d(u0, v0), Eigen::Vector2d(u1, v0), Eigen::Vector2d(u1, v1),
            Eigen::Vector2d(u0, v1)};
        std::array<Eigen::Vector3d, 4> rays;
        for (int k = 0; k < 4; ++k) {
          const auto r = model.Unproject(corners[static_cast<std::size_t>(k)]);
          // Beyond the fold: a wide ray in the corner's direction.
          rays[static_cast<std::size_t>(k)] =
              r ? *r
                : Eigen::Vector3d(corners[static_cast<std::size_t>(k)].x() - intrinsics.cx_px,
                                  corners[static_cast<std::size_t>(k)].y() - intrinsics.cy_px, 1e-3)
                      .normalized();
        }
        auto& planes = tile_planes[static_cast<std::size_t>(ty * tw + tx)];
        for (int k = 0; k < 4; ++k) {
          // Clockwise in the image (x right, y down) is counter-clockwise about +z: the cross
          // product of consecutive rays points into the tile's pyramid.
          planes[static_cast<std::size_t>(k)] =
              rays[static_cast<std::size_t>(k)]
                  .cross(rays[static_cast<std::size_t>((k + 1) % 4)])
                  .cast<float>();
        }
      }
    }
    depth.resize(n);
    colour.resize(n * 3);
    frame_parts.reserve(256);
    dynamic_parts.reserve(256);
    lamp_state.resize(static_cast<std::size_t>(world->impl_->heads));
    if (film.noise_sigma > 0) {
      noise.create(h + 64, (w + 64) * 3, CV_16S);
      cv::RNG rng(0x5eed);
      rng.fill(noise, cv::RNG::NORMAL, 0.0, film.noise_sigma);
    }
  }

  void DrawGround(const Eigen::Isometry3d& X_MC);
  void BuildParts(const Eigen::Isometry3d& X_MC, const FrameState& frame,
                  std::optional<int> exclude);
  void Place(FramePart& fp, const Eigen::Isometry3d& X_MC);
  void DrawPart(const FramePart& fp, const FrameState& frame);
  void DrawPixel(const FramePart& fp, int u, int v, const FrameState& frame);
  void RenderOnce(const Eigen::Isometry3d& X_MC, const FrameState& frame,
                  std::optional<int> exclude);
};

void CameraRenderer::Impl::DrawGround(const Eigen::Isometry3d& X_MC) {
  const std::size_t n = depth.size();
  if (have_cache && X_MC.isApprox(cached_pose, 0.0)) {
    std::memcpy(depth.data(), cached_depth.data(), n * sizeof(float));
    std::memcpy(colour.data(), cached_colour.data(), n * 3);
    return;
  }
  const GroundPyramid& g = world->impl_->ground;
  const Eigen::Matrix3f R = X_MC.linear().cast<float>();
  const Eigen::Vector3f c = X_MC.translation().cast<float>();
  const float height = c.z();
  const std::uint32_t walls = Pack(kLabWalls);
  const float inv_texel = static_cast<float>(1.0 / g.texel_m);
  // The footprint's edge in level-0 texels is sqrt(A) with A = h^2 / (f^2 texel^2 |d_z|^3).
  const float a_num = height * height * inv_texel * inv_texel / (f_px * f_px);
  const int top_level = static_cast<int>(g.levels.size()) - 1;
  std::array<float, 32> level_scale{};
  for (int k = 0; k <= top_level; ++k)
    level_scale[static_cast<std::size_t>(k)] = std::ldexp(1.0f, -k);
  std::uint8_t* out = colour.data();
  for (std::size_t i = 0; i < n; ++i) {
    const float x = rx[i], y = ry[i], z = rz[i];
    const float dz = R(2, 0) * x + R(2, 1) * y + R(2, 2) * z;
    std::uint32_t texel = walls;
    float t = std::numeric_limits<float>::infinity();
    if (height > 0 && dz < -1e-6f) {
      t = height / -dz;
      const float dx = R(0, 0) * x + R(0, 1) * y + R(0, 2) * z;
      const float dy = R(1, 0) * x + R(1, 1) * y + R(1, 2) * z;
      const float gx = c.x() + t * dx;
      const float gy = c.y() + t * dy;
      const float area = a_num / (-dz * dz * dz);
      // Level round(log2(sqrt(area))) from the float's exponent.
      const int e = static_cast<int>((std::bit_cast<std::uint32_t>(area) >> 23) & 0xff) - 127;
      const int level = std::clamp((e + 1) / 2, 0, top_level);
      const float s = level_scale[static_cast<std::size_t>(level)];
      const float u = (gx - static_cast<float>(g.x0_m)) * inv_texel * s - 0.5f;
      const float v = (static_cast<float>(g.y1_m) - gy) * inv_texel * s - 0.5f;
      texel = Bilinear(g.levels[static_cast<std::size_t>(level)], u, v);
    }
    depth[i] = t;
    out[3 * i] = static_cast<std::uint8_t>(texel);
    out[3 * i + 1] = static_cast<std::uint8_t>(texel >> 8);
    out[3 * i + 2] = static_cast<std::uint8_t>(texel >> 16);
  }
  cached_pose = X_MC;
  have_cache = true;
  cached_depth = depth;
  cached_colour = colour;
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

void CameraRenderer::Impl::BuildParts(const Eigen::Isometry3d& X_MC, const FrameState& frame,
                                      std::optional<int> exclude) {
  dynamic_parts.clear();
  for (const RenderVehicle& car : frame.vehicles) {
    if (exclude && car.index == *exclude) continue;
    AUTODRIVE_CHECK(car.params != nullptr, "RenderVehicle without params");
    const VehicleParams& p = *car.params;
    const Eigen::Isometry3d& X = car.X_MV;
    const double cx = p.body_centre_ahead_of_rear_axle_m;
    const double top = std::min(p.body_height_m, car.look.tag_height_m);
    const double deck = p.body_clearance_m + (top - p.body_clearance_m) * 0.55;
    // Body (the chassis and its deck).
    const std::size_t body = dynamic_parts.size();
    AddBox(dynamic_parts, X, {cx, 0, (p.body_clearance_m + deck) / 2},
           {p.body_length_m / 2, p.body_width_m / 2 - p.wheel_width_m,
            (deck - p.body_clearance_m) / 2},
           car.look.colour, Decal::kVehicleFront);
    // The front face carries the headlights; a second, thin box at the back the tail lights.
    const bool blink = std::fmod(frame.time_s, 1.0 / 1.5) < 0.5 / 1.5;
    std::uint8_t lights = car.headlights ? 1 : 0;
    if (car.left_indicator && blink) lights |= 2;
    if (car.right_indicator && blink) lights |= 4;
    dynamic_parts[body].lights = lights;
    AddBox(dynamic_parts, X, {cx - p.body_length_m / 2 - 0.001, 0, (p.body_clearance_m + deck) / 2},
           {0.001, p.body_width_m / 2 - p.wheel_width_m, (deck - p.body_clearance_m) / 2},
           car.look.colour, Decal::kVehicleRear);
    dynamic_parts.back().lights = lights;
    // The LIDAR and its mast up to the plate.
    const double plate_bottom = car.look.tag_height_m - 0.003;
    if (plate_bottom > deck) {
      AddBox(dynamic_parts, X, {cx, 0, (deck + plate_bottom) / 2},
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
  std::fill(lamp_state.begin(), lamp_state.end(), 0);
  for (const HeadLamps& l : frame.lamps) {
    const auto i = static_cast<std::size_t>(l.head.value() - 1);
    if (i < lamp_state.size()) {
      lamp_state[i] =
          static_cast<std::uint8_t>((l.red ? 1 : 0) | (l.yellow ? 2 : 0) | (l.green ? 4 : 0));
    }
  }
  frame_parts.clear();
  // Light: shades of each face relative to the ground's (which the map's picture shows as is).
  const Eigen::Vector3d light(std::cos(film.light_elevation_rad) * std::cos(film.light_azimuth_rad),
                              std::cos(film.light_elevation_rad) * std::sin(film.light_azimuth_rad),
                              std::sin(film.light_elevation_rad));
  const double ground_shade = film.ambient + film.light_intensity * std::max(0.0, light.z());
  const auto add = [&](const RenderPart& part) {
    FramePart& fp = frame_parts.emplace_back();
    fp.part = &part;
    for (int k = 0; k < 6; ++k) {
      const Eigen::Vector3d n = part.R_MB.col(k / 2) * (k % 2 == 0 ? 1.0 : -1.0);
      fp.shade[static_cast<std::size_t>(k)] =
          static_cast<float>((film.ambient + film.light_intensity * std::max(0.0, n.dot(light))) /
                             std::max(1e-6, ground_shade));
    }
    Place(fp, X_MC);
    if (fp.x1 <= fp.x0 || fp.y1 <= fp.y0) frame_parts.pop_back();
  };
  for (const RenderPart& part : world->impl_->parts) add(part);
  for (const RenderPart& part : dynamic_parts) add(part);
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
  const auto visible_in_tile = [&](int t) {
    const auto& planes = tile_planes[static_cast<std::size_t>(t)];
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
  int tx0 = 0, ty0 = 0, tx1 = tw, ty1 = th;
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
    }
  }
  int bx0 = tw, by0 = th, bx1 = 0, by1 = 0;
  for (int ty = ty0; ty < ty1; ++ty) {
    for (int tx = tx0; tx < tx1; ++tx) {
      if (!visible_in_tile(ty * tw + tx)) continue;
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

void CameraRenderer::Impl::DrawPixel(const FramePart& fp, int u, int v, const FrameState&) {
  const std::size_t i = Index(u, v);
  const RenderPart& part = *fp.part;
  const Eigen::Vector3f r(rx[i], ry[i], rz[i]);
  const Eigen::Vector3f d = fp.Q * r;
  const PartHit hit = Intersect(part, fp.o, d, depth[i]);
  if (!(hit.t < depth[i])) return;
  depth[i] = hit.t;
  std::uint8_t* px = colour.data() + 3 * i;
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
  switch (part.decal) {
    case Decal::kNone:
      break;
    case Decal::kTag:
      if (hit.face == 4) {
        // Supersampled 4 x 4 over the pixel: the sub-pixel rays interpolated between the
        // pixel's ray and its neighbours', each met with the face's plane.
        const TagBitmap& tag = *part.tag;
        const float half = static_cast<float>(part.half.x());
        const float cell = 2 * half / static_cast<float>(tag.total);
        const std::size_t iu = u + 1 < w ? i + 1 : i - 1;
        const std::size_t iv = v + 1 < h ? i + W() : i - W();
        const float su = u + 1 < w ? 1.0f : -1.0f, sv = v + 1 < h ? 1.0f : -1.0f;
        const Eigen::Vector3f du = (Eigen::Vector3f(rx[iu], ry[iu], rz[iu]) - r) * su;
        const Eigen::Vector3f dv = (Eigen::Vector3f(rx[iv], ry[iv], rz[iv]) - r) * sv;
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
    case Decal::kVehicleRear: {
      const bool front = part.decal == Decal::kVehicleFront;
      if (hit.face != (front ? 0 : 1)) break;
      const float hy = static_cast<float>(part.half.y()), hz = static_cast<float>(part.half.z());
      const float y = hit.p.y(), z = hit.p.z();
      const float lamp = std::min(hy, hz) * 0.35f;
      // Indicators at the outer corners, lights inboard of them.
      for (int side = -1; side <= 1; side += 2) {
        const float cy = static_cast<float>(side) * (hy - lamp * 1.2f);
        if (std::abs(y - cy) < lamp && std::abs(z - hz * 0.3f) < lamp * 0.8f) {
          const bool on = (part.lights >> (side > 0 ? 1 : 2)) & 1;
          c = on ? Rgb{255, 170, 0} : Rgb{120, 80, 20};
          if (on) shade = 1.0f;
        }
        const float ly = static_cast<float>(side) * (hy - lamp * 3.6f);
        if (std::abs(y - ly) < lamp && std::abs(z - hz * 0.3f) < lamp * 0.8f) {
          const bool on = part.lights & 1;
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

void CameraRenderer::Impl::DrawPart(const FramePart& fp, const FrameState& frame) {
  for (int v = fp.y0; v < fp.y1; ++v) {
    for (int u = fp.x0; u < fp.x1; ++u) DrawPixel(fp, u, v, frame);
  }
}

void CameraRenderer::Impl::RenderOnce(const Eigen::Isometry3d& X_MC, const FrameState& frame,
                                      std::optional<int> exclude) {
  DrawGround(X_MC);
  BuildParts(X_MC, frame, exclude);
  for (const FramePart& fp : frame_parts) DrawPart(fp, frame);
}

CameraRenderer::CameraRenderer(std::shared_ptr<const RenderWorld> world,
                               const camera::Intrinsics& intrinsics, const FilmOptions& film)
    : impl_(std::make_unique<Impl>(std::move(world), intrinsics, film)) {}

CameraRenderer::~CameraRenderer() = default;

const camera::CameraModel& CameraRenderer::model() const { return impl_->model; }
const FilmOptions& CameraRenderer::film() const { return impl_->film; }

void CameraRenderer::Render(const Eigen::Isometry3d& X_MC, const FrameState& frame, Image& out,
                            std::optional<int> exclude, const Eigen::Vector3d& v_M_mps,
                            const Eigen::Vector3d& w_M_radps, std::uint64_t noise_seed) {
  Impl& m = *impl_;
  const FilmOptions& film = m.film;
  out.width_px = m.w;
  out.height_px = m.h;
  const std::size_t bytes = m.colour.size();
  out.rgb.resize(bytes);
  if (film.exposure_time_s > 0) {
    // Motion blur: sub-frames at instants spread over the exposure, the vehicles and the camera
    // moved rigidly by their velocities.
    m.accumulator.assign(bytes, 0);
    const int n = film.motion_blur_samples;
    std::vector<RenderVehicle> moved(frame.vehicles.begin(), frame.vehicles.end());
    for (int s = 0; s < n; ++s) {
      const double dt = film.exposure_time_s * ((s + 0.5) / n - 0.5);
      const auto shift = [dt](const Eigen::Isometry3d& X, const Eigen::Vector3d& v,
                              const Eigen::Vector3d& w_) {
        Eigen::Isometry3d Y = X;
        Y.translation() += v * dt;
        if (w_.norm() > 0)
          Y.linear() = Eigen::AngleAxisd(w_.norm() * dt, w_.normalized()) * X.linear();
        return Y;
      };
      for (std::size_t k = 0; k < moved.size(); ++k) {
        moved[k].X_MV =
            shift(frame.vehicles[k].X_MV, frame.vehicles[k].v_M_mps, frame.vehicles[k].w_M_radps);
      }
      FrameState sub = frame;
      sub.vehicles = moved;
      sub.time_s = frame.time_s + dt;
      m.RenderOnce(shift(X_MC, v_M_mps, w_M_radps), sub, exclude);
      for (std::size_t k = 0; k < bytes; ++k) m.accumulator[k] += m.colour[k];
    }
    for (std::size_t k = 0; k < bytes; ++k) {
      m.colour[k] = static_cast<std::uint8_t>((m.accumulator[k] + n / 2) / n);
    }
  } else {
    m.RenderOnce(X_MC, frame, exclude);
  }
  cv::Mat image(m.h, m.w, CV_8UC3, m.colour.data());
  cv::Mat dst(m.h, m.w, CV_8UC3, out.rgb.data());
  if (film.exposure != 1.0) {
    image.convertTo(dst, CV_8UC3, film.exposure);
  } else {
    image.copyTo(dst);
  }
  if (film.blur_sigma_px > 0) cv::GaussianBlur(dst, dst, cv::Size(0, 0), film.blur_sigma_px);
  if (film.noise_sigma > 0) {
    std::mt19937_64 rng(noise_seed);
    const int ox = static_cast<int>(rng() % 64), oy = static_cast<int>(rng() % 64);
    const cv::Mat block = m.noise(cv::Rect(ox * 3, oy, m.w * 3, m.h));
    cv::Mat wide;
    dst.reshape(1).convertTo(wide, CV_16S);
    wide += block;
    wide.convertTo(dst.reshape(1), CV_8U);
  }
}

}  // namespace autodrive::vehicle_sim
