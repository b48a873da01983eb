#pragma once
/// @file
/// A camera's rays for the renderer's raster (internal to vehicle_sim/renderer.cpp): each
/// pixel's ray through the lens model, computed once per camera, and the pyramids of its
/// 16 x 16-pixel tiles for finding which pixels a part may cover.

#include <array>
#include <cstddef>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/camera/camera_model.h"

namespace autodrive::vehicle_sim::internal {

struct RenderPart;

/// Pixels of a tile's side.
inline constexpr int kTile = 16;

/// A rectangle of pixels [x0, x1) x [y0, y1); empty when x1 <= x0 or y1 <= y0.
struct PixelRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  [[nodiscard]] bool empty() const { return x1 <= x0 || y1 <= y0; }
};

/// Each pixel's ray in the camera frame C is (x, y, 1), x and y its undistorted normalised
/// coordinates: for a camera without distortion x = (u - cx) / fx and y = (v - cy) / fy,
/// computed as needed; with distortion, from a table (NaN beyond the lens model's fold). Ranges
/// along rays are in units of this ray, the same for the ground and every part. Immutable once
/// built; copyable and movable as a value.
struct CameraRays {
  /// @throws InputError when the intrinsics are invalid.
  explicit CameraRays(const camera::Intrinsics& intrinsics);

  [[nodiscard]] std::size_t W() const { return static_cast<std::size_t>(w); }
  [[nodiscard]] std::size_t Index(int u, int v) const {
    return static_cast<std::size_t>(v) * W() + static_cast<std::size_t>(u);
  }
  [[nodiscard]] Eigen::Vector3f Ray(int u, int v) const {
    if (!distorted) {
      return {column_x[static_cast<std::size_t>(u)], (static_cast<float>(v) - cy) * inv_fy, 1.0f};
    }
    const std::size_t i = Index(u, v);
    return {table_x[i], table_y[i], 1.0f};
  }
  /// Whether a sphere (centre in the camera frame) may be seen: in front of the camera and not
  /// wholly outside one of the image's planes. As permissive as `Bound`'s test of a part's
  /// corners, so no part of an object it keeps would have been dropped by that test alone.
  [[nodiscard]] bool SphereInView(const Eigen::Vector3d& centre_C, double radius) const;
  /// The pixels where the part may be seen from `X_MC` (a superset; empty when it is out of
  /// view).
  [[nodiscard]] PixelRect Bound(const RenderPart& part, const Eigen::Isometry3d& X_MC) const;

  camera::CameraModel model;
  int w = 0, h = 0;
  bool distorted = false;
  float fx = 1, fy = 1, cx = 0, cy = 0;
  float inv_fy = 1.0f;
  float f_px = 1.0f;                    ///< sqrt(fx fy)
  std::vector<float> table_x, table_y;  ///< with distortion: each pixel's x and y
  std::vector<float> column_x;          ///< without distortion: x of each column
  // Tiles of kTile x kTile pixels: the inward normals of the four planes through the camera's
  // centre and the tile's corner rays.
  int tw = 0, th = 0;
  std::vector<std::array<Eigen::Vector3f, 4>> tile_planes;
  std::array<Eigen::Vector3f, 4> image_planes;       ///< the same for the whole image
  std::array<Eigen::Vector3d, 4> image_planes_unit;  ///< `image_planes` of unit length

 private:
  // The inward normals of the four planes through the camera's centre and the rays of the
  // corners of the image rectangle [u0, u1] x [v0, v1].
  [[nodiscard]] std::array<Eigen::Vector3f, 4> PyramidPlanes(double u0, double v0, double u1,
                                                             double v1) const;
};

}  // namespace autodrive::vehicle_sim::internal
