#include "vehicle_sim/render/ground.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "common/error.h"

namespace autodrive::vehicle_sim::internal {

namespace {

constexpr int kStrip = 16;  ///< rows of the ground drawn at a time (their remap stays in cache)

}  // namespace

GroundFrame MakeGroundFrame(const GroundPyramid& g, const Eigen::Isometry3d& X_MC, float fx,
                            float fy) {
  const Eigen::Matrix3f R = X_MC.linear().cast<float>();
  const Eigen::Vector3f c = X_MC.translation().cast<float>();
  GroundFrame f{};
  f.height = c.z();
  f.inv_texel = static_cast<float>(1.0 / g.texel_m);
  // The footprint's area in level-0 texels (for a ray (x, y, 1) of solid angle 1 / (fx fy |r|^3)
  // per pixel, meeting the ground at range t = h / -d_z along it) is
  // A = h^2 / (fx fy texel^2 (-d_z)^3): level k from A >= 4^k / 2 (the nearest power of two).
  f.a_num = f.height * f.height * f.inv_texel * f.inv_texel / (fx * fy);
  const int top_level = std::min(7, static_cast<int>(g.levels.size()) - 1);
  f.thresholds.fill(std::numeric_limits<float>::infinity());
  for (int k = 1; k <= top_level; ++k) {
    f.thresholds[static_cast<std::size_t>(k)] = std::ldexp(0.5f, 2 * k);
  }
  f.x0 = static_cast<float>(g.x0_m);
  f.y1 = static_cast<float>(g.y1_m);
  // Level k's place in the atlas from s = 2^-k alone (no table, so that the loop vectorises):
  // level 0 at (0, 0) of W x H texels; level k >= 1 at (W, H - 2 H s), W s x H s.
  f.W0 = static_cast<float>(g.levels[0].w);
  f.H0 = static_cast<float>(g.levels[0].h);
  f.r00 = R(0, 0), f.r01 = R(0, 1), f.r02 = R(0, 2);
  f.r10 = R(1, 0), f.r11 = R(1, 1), f.r12 = R(1, 2);
  f.r20 = R(2, 0), f.r21 = R(2, 1), f.r22 = R(2, 2);
  f.ccx = c.x();
  f.ccy = c.y();
  f.min_dz = f.height > 0 ? -1e-6f : -std::numeric_limits<float>::infinity();
  f.walls = static_cast<std::uint32_t>(kLabWalls.r) |
            (static_cast<std::uint32_t>(kLabWalls.g) << 8) |
            (static_cast<std::uint32_t>(kLabWalls.b) << 16);
  f.atlas = reinterpret_cast<const std::uint32_t*>(g.atlas32.data);
  f.stride = g.atlas32.cols;
  return f;
}

void DrawGroundAvx2(const GroundFrame& f, const CameraRays& rays, std::uint8_t* target) {
#if AUTODRIVE_RENDER_AVX2
  for (int v = 0; v < rays.h; ++v) {
    GroundRowAvx2(f, rays.distorted ? rays.table_x.data() + rays.Index(0, v) : rays.column_x.data(),
                  rays.distorted ? rays.table_y.data() + rays.Index(0, v) : nullptr,
                  (static_cast<float>(v) - rays.cy) / rays.fy, rays.w,
                  target + rays.Index(0, v) * 3);
  }
#else
  (void)f;
  (void)rays;
  (void)target;
  AUTODRIVE_CHECK(false, "the AVX2 ground sampler is not built in (AUTODRIVE_RENDER_AVX2)");
#endif
}

GroundRemap::GroundRemap(int width)
    : row_y_(static_cast<std::size_t>(width)),
      row_ax_(static_cast<std::size_t>(width)),
      row_ay_(static_cast<std::size_t>(width)) {
  map_xy_.create(kStrip, width, CV_16SC2);
  map_frac_.create(kStrip, width, CV_16UC1);
}

void GroundRemap::Draw(const GroundPyramid& g, const GroundFrame& f, const CameraRays& rays,
                       std::uint8_t* target) {
  // Locals, so that the compiler vectorises the loop below (the int stores could otherwise
  // change a member).
  const float r00 = f.r00, r01 = f.r01, r02 = f.r02;
  const float r10 = f.r10, r11 = f.r11, r12 = f.r12;
  const float r20 = f.r20, r21 = f.r21, r22 = f.r22;
  const float ccx = f.ccx, ccy = f.ccy, height = f.height, min_dz = f.min_dz, a_num = f.a_num;
  const float x0 = f.x0, y1 = f.y1, inv_texel = f.inv_texel, W0 = f.W0, H0 = f.H0;
  const float t1 = f.thresholds[1], t2 = f.thresholds[2], t3 = f.thresholds[3];
  const float t4 = f.thresholds[4], t5 = f.thresholds[5], t6 = f.thresholds[6];
  const float t7 = f.thresholds[7];
  constexpr float kTab = static_cast<float>(static_cast<int>(cv::INTER_TAB_SIZE));
  const float walls_x = g.walls.x() * kTab + 0.5f, walls_y = g.walls.y() * kTab + 0.5f;
  constexpr int kMask = cv::INTER_TAB_SIZE - 1;
  const int width = rays.w, h = rays.h;
  const bool distorted = rays.distorted;
  const float cy = rays.cy, fy = rays.fy;
  for (int v0 = 0; v0 < h; v0 += kStrip) {
    const int rows = std::min(kStrip, h - v0);
    auto* m1 = reinterpret_cast<std::int16_t*>(map_xy_.data);
    auto* m2 = reinterpret_cast<std::uint16_t*>(map_frac_.data);
    for (int v = v0; v < v0 + rows; ++v) {
      const float yn_row = (static_cast<float>(v) - cy) / fy;
      const float* xs = distorted ? rays.table_x.data() + rays.Index(0, v) : rays.column_x.data();
      if (!distorted) std::fill(row_y_.begin(), row_y_.end(), yn_row);
      const float* ys = distorted ? rays.table_y.data() + rays.Index(0, v) : row_y_.data();
      std::int16_t* o1 = m1 + 2 * static_cast<std::size_t>(v - v0) * rays.W();
      std::uint16_t* o2 = m2 + static_cast<std::size_t>(v - v0) * rays.W();
      int* pax = row_ax_.data();
      int* pay = row_ay_.data();
      // Branch-free, so that the compiler vectorises it: rays that miss the ground (or NaN
      // rays beyond a lens' fold) select the walls' texel.
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
    cv::Mat out(rows, width, CV_8UC3, target + rays.Index(0, v0) * 3);
    cv::remap(g.atlas, out, map_xy_.rowRange(0, rows), map_frac_.rowRange(0, rows),
              cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  }
}

}  // namespace autodrive::vehicle_sim::internal
