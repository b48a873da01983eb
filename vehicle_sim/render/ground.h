#pragma once
/// @file
/// The renderer's flat ground (internal to vehicle_sim/renderer.cpp): each pixel's ray meets
/// the plane z = 0 and samples the ground's mip pyramid (scene.h) bilinearly at the level of
/// its footprint. Two samplers draw the same picture (to within a level or two): the portable
/// one (every platform: one `cv::remap` per strip of rows) and, on x86-64 built with
/// AUTODRIVE_RENDER_AVX2, eight pixels at a time with AVX2 (ground_avx2.cpp).

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "vehicle_sim/render/camera_rays.h"
#include "vehicle_sim/render/scene.h"

namespace autodrive::vehicle_sim::internal {

/// What the ground's samplers need for one frame: the camera's rotation rows and position,
/// the level thresholds and the atlas.
struct GroundFrame {
  float r00, r01, r02, r10, r11, r12, r20, r21, r22;
  float ccx, ccy, height, min_dz, a_num;
  std::array<float, 8> thresholds;
  float x0, y1, inv_texel, W0, H0;
  std::uint32_t walls;
  const std::uint32_t* atlas;  ///< `GroundPyramid::atlas32` (the AVX2 sampler's)
  int stride;                  ///< texels per atlas row
};

/// The frame's constants for a camera at `X_MC` of focal lengths `fx`, `fy` (px).
[[nodiscard]] GroundFrame MakeGroundFrame(const GroundPyramid& g, const Eigen::Isometry3d& X_MC,
                                          float fx, float fy);

/// Draws the ground with the AVX2 sampler into `target` (rgb, the camera's size). Only when
/// `g.avx2` (otherwise aborts: it is not built in or the CPU lacks it).
void DrawGroundAvx2(const GroundFrame& f, const CameraRays& rays, std::uint8_t* target);

#if AUTODRIVE_RENDER_AVX2
/// A row of the ground, 8 pixels at a time with AVX2, the tail one by one. `xs`, `ys`: the
/// row's undistorted coordinates (ys null: all `y`). Requires a CPU with AVX2 and FMA.
void GroundRowAvx2(const GroundFrame& f, const float* xs, const float* ys, float y, int width,
                   std::uint8_t* out);
#endif

/// The portable sampler and its buffers for one camera (no allocation per frame): each
/// pixel's point on the ground as a position in the atlas at its level, in OpenCV's
/// fixed-point map format (1/32 texel), then one bilinear `cv::remap` per strip of rows, so
/// that the map never leaves the cache. Copyable and movable as a value.
class GroundRemap {
 public:
  /// For images `width` pixels wide.
  explicit GroundRemap(int width);
  /// Draws the ground into `target` (rgb, the camera's size).
  void Draw(const GroundPyramid& g, const GroundFrame& f, const CameraRays& rays,
            std::uint8_t* target);

 private:
  std::vector<float> row_y_;  ///< a row's y, repeated
  std::vector<int> row_ax_, row_ay_;
  cv::Mat map_xy_, map_frac_;  ///< a strip of the remap, CV_16SC2 and CV_16UC1
};

}  // namespace autodrive::vehicle_sim::internal
