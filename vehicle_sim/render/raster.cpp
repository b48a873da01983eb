#include "vehicle_sim/render/raster.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace autodrive::vehicle_sim::internal {

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

// A signal head's lamps on its +x face: lit ones emit (unshaded).
inline void DrawLamps(const RenderPart& part, const PartHit& hit, std::uint8_t lit, Rgb& c,
                      float& shade) {
  if (hit.face != 0) return;
  static constexpr std::array<Rgb, 3> kOn{Rgb{255, 40, 30}, Rgb{255, 190, 20}, Rgb{40, 255, 90}};
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

// A vehicle's or a background object's lamps on its front or back face.
inline void DrawVehicleLamps(const RenderPart& part, const PartHit& hit, Rgb& c, float& shade) {
  const bool front =
      part.decal == Decal::kTrafficEnds ? hit.face == 0 : part.decal == Decal::kVehicleFront;
  if (hit.face != (front ? 0 : 1)) return;
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
}

}  // namespace

// ---- Light ----------------------------------------------------------------------------------

Light::Light(const FilmOptions& film)
    : direction(std::cos(film.light_elevation_rad) * std::cos(film.light_azimuth_rad),
                std::cos(film.light_elevation_rad) * std::sin(film.light_azimuth_rad),
                std::sin(film.light_elevation_rad)),
      ambient(film.ambient),
      intensity(film.light_intensity),
      ground_shade(film.ambient + film.light_intensity * std::max(0.0, direction.z())) {}

float Light::Shade(const Eigen::Vector3d& n) const {
  return static_cast<float>((ambient + intensity * std::max(0.0, n.dot(direction))) /
                            std::max(1e-6, ground_shade));
}

// ---- Raster ---------------------------------------------------------------------------------

Raster::Raster(const StaticScene& scene, const camera::Intrinsics& intrinsics,
               const FilmOptions& film)
    : scene_(&scene), light_(film), rays_(intrinsics), remap_(intrinsics.width_px) {
  const std::size_t n = rays_.W() * static_cast<std::size_t>(rays_.h);
  depth_.resize(n);
  ground_depth_.assign(n, std::numeric_limits<float>::infinity());
  frame_parts_.reserve(256);
}

void Raster::DrawGround(const Eigen::Isometry3d& X_MC, std::uint8_t* target) {
  const std::size_t n = rays_.W() * static_cast<std::size_t>(rays_.h);
  const bool same_pose = X_MC.matrix() == last_pose_;
  last_pose_ = X_MC.matrix();
  if (same_pose && cache_valid_) {
    std::memcpy(target, cached_colour_.data(), n * 3);
    return;
  }
  const GroundPyramid& g = scene_->ground();
  const GroundFrame frame = MakeGroundFrame(g, X_MC, rays_.fx, rays_.fy);
  if (g.avx2) {
    DrawGroundAvx2(frame, rays_, target);
  } else {
    remap_.Draw(g, frame, rays_, target);
  }
  target_ = target;
  DrawTerrain(X_MC);
  cache_valid_ = same_pose;
  if (cache_valid_) cached_colour_.assign(target, target + n * 3);
}

bool Raster::Prepare(FramePart& fp, const Eigen::Isometry3d& X_MC) const {
  const RenderPart& part = *fp.part;
  for (int k = 0; k < 6; ++k) {
    fp.shade[static_cast<std::size_t>(k)] =
        light_.Shade(part.R_MB.col(k / 2) * (k % 2 == 0 ? 1.0 : -1.0));
  }
  const Eigen::Matrix3d R_BM = part.R_MB.transpose();
  fp.Q = (R_BM * X_MC.linear()).cast<float>();
  fp.o = (R_BM * (X_MC.translation() - part.p_MB)).cast<float>();
  fp.rect = rays_.Bound(part, X_MC);
  return !fp.rect.empty();
}

void Raster::DrawParts(const Eigen::Isometry3d& X_MC, const FrameScene& frame, std::uint8_t* target,
                       RenderStats& stats) {
  target_ = target;
  lamp_state_ = &frame.lamp_state();
  frame_parts_.clear();
  const auto add = [&](const RenderPart& part) {
    FramePart& fp = frame_parts_.emplace_back();
    fp.part = &part;
    if (!Prepare(fp, X_MC)) frame_parts_.pop_back();
  };
  for (const RenderPart& part : scene_->parts()) add(part);
  for (const RenderPart& part : frame.parts()) add(part);
  // The flat ground lies under every part (the camera above it), so only parts and the raised
  // ground compete for a pixel: the depth buffer is needed inside the parts' rectangles only.
  for (const FramePart& fp : frame_parts_) {
    for (int v = fp.rect.y0; v < fp.rect.y1; ++v) {
      const auto at = static_cast<std::ptrdiff_t>(rays_.Index(fp.rect.x0, v));
      std::copy_n(ground_depth_.begin() + at, fp.rect.x1 - fp.rect.x0, depth_.begin() + at);
    }
  }
  for (const FramePart& fp : frame_parts_) {
    DrawPart(fp, depth_.data());
    stats.pixels_tested +=
        static_cast<std::int64_t>(fp.rect.x1 - fp.rect.x0) * (fp.rect.y1 - fp.rect.y0);
  }
  stats.parts_drawn += static_cast<int>(frame_parts_.size());
}

void Raster::DrawTerrain(const Eigen::Isometry3d& X_MC) {
  for (const PixelRect& r : terrain_rects_) {
    for (int v = r.y0; v < r.y1; ++v) {
      std::fill_n(ground_depth_.begin() + static_cast<std::ptrdiff_t>(rays_.Index(r.x0, v)),
                  r.x1 - r.x0, std::numeric_limits<float>::infinity());
    }
  }
  terrain_rects_.clear();
  for (const RenderPart& part : scene_->terrain()) {
    FramePart fp;
    fp.part = &part;
    if (!Prepare(fp, X_MC)) continue;
    DrawPart(fp, ground_depth_.data());
    terrain_rects_.push_back(fp.rect);
  }
}

void Raster::DrawPart(const FramePart& fp, float* depth_buffer) {
  // Rays that miss the part's bounding sphere (centre 0, radius |half| in the part's frame) are
  // rejected with a few products and no division: o + t d meets it for some t > 0 only if
  // c = |o|^2 - R^2 <= 0 (the camera inside) or b = o.d < 0 and b^2 >= |d|^2 c.
  const float c = fp.o.squaredNorm() - fp.part->half.cast<float>().squaredNorm();
  const auto misses = [&](const Eigen::Vector3f& d) {
    if (c <= 0) return false;
    const float b = fp.o.dot(d);
    return b >= 0 || b * b < d.squaredNorm() * c;
  };
  const PixelRect& rect = fp.rect;
  if (!rays_.distorted) {
    // d = Q (x_u, y_v, 1): per row e = Q (0, y_v, 1), per pixel d = e + x_u Q_0.
    const Eigen::Vector3f q0 = fp.Q.col(0);
    for (int v = rect.y0; v < rect.y1; ++v) {
      const float y = (static_cast<float>(v) - rays_.cy) * rays_.inv_fy;
      const Eigen::Vector3f e = fp.Q.col(1) * y + fp.Q.col(2);
      for (int u = rect.x0; u < rect.x1; ++u) {
        const float x = rays_.column_x[static_cast<std::size_t>(u)];
        const Eigen::Vector3f d = e + x * q0;
        if (misses(d)) continue;
        DrawPixel(fp, u, v, Eigen::Vector3f(x, y, 1.0f), d, depth_buffer);
      }
    }
    return;
  }
  for (int v = rect.y0; v < rect.y1; ++v) {
    for (int u = rect.x0; u < rect.x1; ++u) {
      const Eigen::Vector3f r = rays_.Ray(u, v);
      if (std::isnan(r.x())) continue;  // beyond the lens' fold
      const Eigen::Vector3f d = fp.Q * r;
      if (misses(d)) continue;
      DrawPixel(fp, u, v, r, d, depth_buffer);
    }
  }
}

void Raster::DrawPixel(const FramePart& fp, int u, int v, const Eigen::Vector3f& r,
                       const Eigen::Vector3f& d, float* depth_buffer) {
  const std::size_t i = rays_.Index(u, v);
  const RenderPart& part = *fp.part;
  const PartHit hit = Intersect(part, fp.o, d, depth_buffer[i]);
  if (!(hit.t < depth_buffer[i])) return;
  depth_buffer[i] = hit.t;
  std::uint8_t* px = target_ + 3 * i;
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
    const GroundPyramid& g = scene_->ground();
    const float cos_incidence = std::abs(d.z() - part.a * d.x() - part.b * d.y()) /
                                (d.norm() * std::sqrt(1.0f + part.a * part.a + part.b * part.b));
    const float texel = static_cast<float>(g.texel_m);
    const float area =
        hit.t * hit.t /
        (rays_.fx * rays_.fy * r.norm() * std::max(cos_incidence, 1e-3f) * texel * texel);
    c = SampleGround(static_cast<float>(part.p_MB.x()) + hit.p.x(),
                     static_cast<float>(part.p_MB.y()) + hit.p.y(), area);
    shade = 1.0f;
  }
  switch (part.decal) {
    case Decal::kNone:
      break;
    case Decal::kTag:
      if (hit.face == 4) c = TagColour(fp, u, v, r);
      break;
    case Decal::kLamps:
      DrawLamps(part, hit, (*lamp_state_)[static_cast<std::size_t>(part.head)], c, shade);
      break;
    case Decal::kVehicleFront:
    case Decal::kVehicleRear:
    case Decal::kTrafficEnds:
      DrawVehicleLamps(part, hit, c, shade);
      break;
    case Decal::kSign:
      if (hit.face == 0) {
        const float radius = static_cast<float>(std::min(part.half.y(), part.half.z()));
        if (InDisc(hit.p.y(), hit.p.z(), 0, 0, radius * 0.95f)) c = part.decal_colour;
      }
      break;
  }
  Put(px, c, shade);
}

// A tag's pixel, supersampled 4 x 4 over the pixel: the sub-pixel rays (exact without
// distortion, else interpolated between the pixel's ray and its neighbours'), each met with the
// face's plane.
Rgb Raster::TagColour(const FramePart& fp, int u, int v, const Eigen::Vector3f& r) const {
  const RenderPart& part = *fp.part;
  const TagBitmap& tag = *part.tag;
  const float half = static_cast<float>(part.half.x());
  const float cell = 2 * half / static_cast<float>(tag.total);
  Eigen::Vector3f du(1.0f / rays_.fx, 0, 0), dv(0, 1.0f / rays_.fy, 0);
  if (rays_.distorted) {
    const int un = u + 1 < rays_.w ? u + 1 : u - 1, vn = v + 1 < rays_.h ? v + 1 : v - 1;
    du = (rays_.Ray(un, v) - r) * static_cast<float>(un - u);
    dv = (rays_.Ray(u, vn) - r) * static_cast<float>(vn - v);
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
  return {static_cast<std::uint8_t>(kTagBlack.r + k * (kPlateColour.r - kTagBlack.r)),
          static_cast<std::uint8_t>(kTagBlack.g + k * (kPlateColour.g - kTagBlack.g)),
          static_cast<std::uint8_t>(kTagBlack.b + k * (kPlateColour.b - kTagBlack.b))};
}

Rgb Raster::SampleGround(float x, float y, float area_texels) const {
  const GroundPyramid& g = scene_->ground();
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

}  // namespace autodrive::vehicle_sim::internal
