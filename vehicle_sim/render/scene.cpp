#include "vehicle_sim/render/scene.h"

#include <apriltag/apriltag.h>
#include <sys/mman.h>

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "common/camera/tag_family.h"
#include "common/error.h"
#include "maps/map.h"
#include "maps/render.h"

namespace autodrive::vehicle_sim::internal {

namespace {

constexpr Rgb kWallColour{128, 128, 128};
constexpr Rgb kBoxColour{255, 140, 0};
constexpr Rgb kPoleColour{90, 90, 95};
constexpr Rgb kHeadColour{25, 25, 25};
constexpr Rgb kWheelColour{20, 20, 20};
constexpr Rgb kLidarColour{40, 40, 45};
constexpr Rgb kTerrainSide{150, 160, 140};
constexpr Rgb kUnderbody{30, 30, 32};  // a background object's wheels and the shade under it

// The atlas' memory: 2 MiB-aligned and advised as huge pages (see GroundPyramid).
void AllocateAtlas(GroundPyramid& g, int atlas_w, int atlas_h) {
  constexpr std::size_t kHuge = std::size_t{2} << 20;
  const std::size_t bytes =
      static_cast<std::size_t>(atlas_w) * static_cast<std::size_t>(atlas_h) * 3;
  const std::size_t rounded = (bytes + kHuge - 1) / kHuge * kHuge;
  g.atlas_memory.reset(static_cast<std::uint8_t*>(std::aligned_alloc(kHuge, rounded)));
  AUTODRIVE_CHECK(g.atlas_memory != nullptr, "out of memory for the ground's picture");
  ::madvise(g.atlas_memory.get(), rounded, MADV_HUGEPAGE);  // advice only: may fail
  g.atlas = cv::Mat(atlas_h, atlas_w, CV_8UC3, g.atlas_memory.get());
}

// The map's ground picture at `texel_m`: drawn at twice the resolution without anti-aliasing
// and averaged down, so that the road's regions of neighbouring tiles meet with no seam, which
// anti-aliasing each would leave. Sets `texel_m` to the texel it has.
maps::Picture GroundPicture(const maps::Map& map, double& texel_m) {
  AUTODRIVE_THROW_UNLESS(std::isfinite(texel_m) && texel_m > 0,
                         "ground_texel_m must be positive, got " << texel_m);
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
  texel_m = 2 * map.tile_size_m / options.pixels_per_tile;
  return picture;
}

Rgb SignColour(const std::string& type) {
  if (type == "stop" || type == "no_entry") return {200, 20, 20};
  if (type == "parking" || type == "one_way" || type == "pedestrian_crossing") return {30, 80, 200};
  if (type == "yield") return {240, 240, 240};
  return {240, 240, 240};
}

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

bool Avx2SamplerAvailable() {
#if AUTODRIVE_RENDER_AVX2
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
  return false;
#endif
}

GroundPyramid MakeGround(const maps::Map& map, double texel_m, bool allow_avx2) {
  const double asked_texel_m = texel_m;
  const maps::Picture picture = GroundPicture(map, texel_m);
  GroundPyramid g;
  g.texel_m = texel_m;
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
                         "the ground's picture at " << asked_texel_m << " m a texel is too big ("
                                                    << atlas_w << " x " << atlas_h
                                                    << " px); raise ground_texel_m");
  AllocateAtlas(g, atlas_w, atlas_h);
  g.atlas.setTo(cv::Scalar(kLabWalls.r, kLabWalls.g, kLabWalls.b));
  for (std::size_t k = 0; k < levels.size(); ++k) {
    const auto& l = g.levels[k];
    levels[k].copyTo(g.atlas(cv::Rect(l.x, l.y, l.w, l.h)));
  }
  g.walls = {static_cast<float>(atlas_w - 1), static_cast<float>(atlas_h - 1)};
  g.avx2 = allow_avx2 && Avx2SamplerAvailable();
  if (g.avx2) cv::cvtColor(g.atlas, g.atlas32, cv::COLOR_RGB2RGBA);
  return g;
}

// ---- StaticScene ----------------------------------------------------------------------------

StaticScene::StaticScene(const maps::Map& map, const StaticGeometry& geometry,
                         const RenderWorldOptions& options)
    : options_(options) {
  options.scene.Validate();
  ground_ = MakeGround(map, options.ground_texel_m, options.allow_avx2);
  AddObstacles(map, geometry);
  AddTerrain(geometry.terrain);
  AddHeads(map, geometry.terrain);
  AddSigns(map, geometry.terrain);
  AddGroundTags(geometry.terrain);
}

const TagBitmap& StaticScene::Tag(const TagSpec& spec) const {
  const std::lock_guard lock(tags_mutex_);
  auto& slot = tags_[{spec.family, spec.id}];
  if (!slot) slot = std::make_unique<TagBitmap>(MakeTagBitmap(spec));
  return *slot;
}

// The world's prisms (the map's obstacles first, then unmapped ones) and cylinders (the poles).
void StaticScene::AddObstacles(const maps::Map& map, const StaticGeometry& geometry) {
  for (std::size_t i = 0; i < geometry.prisms.size(); ++i) {
    RenderPart part = BoxFromPrism(geometry.prisms[i]);
    if (i < map.obstacles.size()) {
      part.colour = map.obstacles[i].kind == "wall" ? kWallColour : kBoxColour;
    } else {
      part.colour = kUnmappedObstacleColour;
    }
    parts_.push_back(part);
  }
  for (const Cylinder& c : geometry.cylinders) {
    RenderPart part;
    part.cylinder = true;
    part.p_MB = {c.centre_M.x(), c.centre_M.y(), (c.z_bottom_m + c.z_top_m) / 2};
    part.half = {c.radius_m, c.radius_m, (c.z_top_m - c.z_bottom_m) / 2};
    part.colour = kPoleColour;
    parts_.push_back(part);
  }
}

// The tiles that are not at z = 0: each its plane, and under a raised one a block of the
// ground's side colour up to its lowest corner (the step a camera sees from beside it).
void StaticScene::AddTerrain(const TerrainModel& terrain) {
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
      terrain_.push_back(tile);
      if (lo > 1e-3) {
        RenderPart block;
        block.p_MB = {x0 + T / 2, y0 + T / 2, (lo - 5e-4) / 2};
        block.half = {T / 2, T / 2, (lo - 5e-4) / 2};
        block.colour = kTerrainSide;
        terrain_.push_back(block);
      }
    }
  }
}

// Each head: a dark housing in front of its pole (towards the traffic it faces), with its
// lamps on the face the traffic sees.
void StaticScene::AddHeads(const maps::Map& map, const TerrainModel& terrain) {
  const double pole_r = options_.scene.pole_radius_m;
  for (std::size_t i = 0; i < map.signal_heads.size(); ++i) {
    const maps::SignalHead& head = map.signal_heads[i];  // ascending ids
    head_ids_.push_back(head.id);
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
    parts_.push_back(part);
  }
}

// Each sign: a plate on top of its pole, facing where the sign looks.
void StaticScene::AddSigns(const maps::Map& map, const TerrainModel& terrain) {
  const double pole_r = options_.scene.pole_radius_m;
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
    part.p_MB = {c.x(), c.y(), ground + options_.scene.sign_height_m - size / 2};
    part.half = {depth / 2, size / 2, size / 2};
    part.colour = {200, 200, 200};
    part.decal = Decal::kSign;
    part.decal_colour = SignColour(sign.type);
    parts_.push_back(part);
  }
}

// Ground tags: a white plate 0.5 mm thick with the tag on top.
void StaticScene::AddGroundTags(const TerrainModel& terrain) {
  for (const GroundTag& g : options_.ground_tags) {
    const TagBitmap& bitmap = Tag(g.tag);
    const double plate = g.tag.size_m * bitmap.total / bitmap.at_border;
    RenderPart part;
    part.R_MB = Yaw(g.yaw_rad);
    const double thickness = 0.0005;
    part.p_MB = {g.x_m, g.y_m, terrain.HeightAt(g.x_m, g.y_m) + thickness / 2};
    part.half = {plate / 2, plate / 2, thickness / 2};
    part.colour = kPlateColour;
    part.decal = Decal::kTag;
    part.tag = &bitmap;
    parts_.push_back(part);
  }
}

// ---- FrameScene -----------------------------------------------------------------------------

bool IndicatorsLit(std::chrono::duration<double> t) {
  return std::fmod(t.count(), 1.0 / 1.5) < 0.5 / 1.5;
}

FrameScene::FrameScene(std::vector<SignalHeadId> head_ids)
    : head_ids_(std::move(head_ids)), lamp_state_(head_ids_.size()) {
  parts_.reserve(256);
}

void FrameScene::Clear() {
  parts_.clear();
  std::fill(lamp_state_.begin(), lamp_state_.end(), 0);
}

void FrameScene::AddVehicle(const RenderVehicle& car, bool blink, const StaticScene& scene) {
  AUTODRIVE_CHECK(car.params != nullptr, "RenderVehicle without params");
  const VehicleParams& p = *car.params;
  const Eigen::Isometry3d& X = car.X_MV;
  const double bx = p.body_centre_ahead_of_rear_axle_m;
  const double top = std::min(p.body_height_m, car.look.tag_height_m);
  const double deck = p.body_clearance_m + (top - p.body_clearance_m) * 0.55;
  // Body (the chassis and its deck).
  const std::size_t body = parts_.size();
  AddBox(
      parts_, X, {bx, 0, (p.body_clearance_m + deck) / 2},
      {p.body_length_m / 2, p.body_width_m / 2 - p.wheel_width_m, (deck - p.body_clearance_m) / 2},
      car.look.colour, Decal::kVehicleFront);
  // The front face carries the headlights; a second, thin box at the back the tail lights.
  std::uint8_t lights = car.headlights ? 1 : 0;
  if (car.left_indicator && blink) lights |= 2;
  if (car.right_indicator && blink) lights |= 4;
  parts_[body].lights = lights;
  AddBox(parts_, X, {bx - p.body_length_m / 2 - 0.001, 0, (p.body_clearance_m + deck) / 2},
         {0.001, p.body_width_m / 2 - p.wheel_width_m, (deck - p.body_clearance_m) / 2},
         car.look.colour, Decal::kVehicleRear);
  parts_.back().lights = lights;
  // The LIDAR and its mast up to the plate.
  const double plate_bottom = car.look.tag_height_m - 0.003;
  if (plate_bottom > deck) {
    AddBox(parts_, X, {bx, 0, (deck + plate_bottom) / 2}, {0.035, 0.035, (plate_bottom - deck) / 2},
           kLidarColour);
  }
  // Wheels.
  for (int k = 0; k < 4; ++k) {
    const double wx = k < 2 ? p.wheelbase_m : 0.0;
    const double wy = (k % 2 == 0 ? 1 : -1) * (p.track_width_m / 2);
    AddBox(parts_, X, {wx, wy, p.wheel_radius_m},
           {p.wheel_radius_m, p.wheel_width_m / 2, p.wheel_radius_m}, kWheelColour);
  }
  // The roof tag on its plate.
  if (car.look.tag) {
    const TagBitmap& bitmap = scene.Tag(*car.look.tag);
    const double plate = car.look.tag->size_m * bitmap.total / bitmap.at_border;
    const Eigen::Isometry3d X_MT = VehicleTagPose(car);
    RenderPart& part = parts_.emplace_back();
    part.R_MB = X_MT.linear();
    part.p_MB = X_MT * Eigen::Vector3d(0, 0, -0.0015);
    part.half = {plate / 2, plate / 2, 0.0015};
    part.colour = kPlateColour;
    part.decal = Decal::kTag;
    part.tag = &bitmap;
  }
}

// A background object's parts: a dark underbody (its wheels), a body with its lamps at both
// ends, and for a car a shorter cabin in the roof's colour; they fill the box that the LIDARs
// and the physics take for it.
void FrameScene::AddTraffic(const RenderTraffic& o, bool blink, bool far) {
  const double L = o.size_m.x(), W = o.size_m.y(), H = o.size_m.z();
  const Eigen::Isometry3d& X = o.X_MO;
  if (o.shape == TrafficShape::kBlock || far) {
    AddBox(parts_, X, {0, 0, H / 2}, {L / 2, W / 2, H / 2}, far ? o.roof : o.body);
    return;
  }
  std::uint8_t lights = o.brake ? 8 : 0;
  if (o.left_indicator && blink) lights |= 2;
  if (o.right_indicator && blink) lights |= 4;
  const double clearance = 0.15 * H;
  const double top = o.shape == TrafficShape::kCar ? 0.6 * H : H;
  AddBox(parts_, X, {0, 0, clearance / 2}, {0.42 * L, 0.46 * W, clearance / 2}, kUnderbody);
  AddBox(parts_, X, {0, 0, (clearance + top) / 2}, {L / 2, W / 2, (top - clearance) / 2}, o.body,
         Decal::kTrafficEnds);
  parts_.back().lights = lights;
  if (o.shape == TrafficShape::kCar) {
    AddBox(parts_, X, {-0.05 * L, 0, (top + H) / 2}, {0.27 * L, 0.43 * W, (H - top) / 2}, o.roof);
  }
}

void FrameScene::SetLamps(std::span<const HeadLamps> lamps) {
  std::fill(lamp_state_.begin(), lamp_state_.end(), 0);
  for (const HeadLamps& l : lamps) {
    const auto it = std::lower_bound(head_ids_.begin(), head_ids_.end(), l.head);
    const auto i = static_cast<std::size_t>(it - head_ids_.begin());
    if (it != head_ids_.end() && *it == l.head) {
      lamp_state_[i] =
          static_cast<std::uint8_t>((l.red ? 1 : 0) | (l.yellow ? 2 : 0) | (l.green ? 4 : 0));
    }
  }
}

}  // namespace autodrive::vehicle_sim::internal
