#include "vehicle_sim/render/camera_rays.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "vehicle_sim/render/scene.h"

namespace autodrive::vehicle_sim::internal {

CameraRays::CameraRays(const camera::Intrinsics& intrinsics) : model(intrinsics) {
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
  column_x.resize(W());
  for (int k = 0; k < w; ++k) {
    column_x[static_cast<std::size_t>(k)] = (static_cast<float>(k) - cx) / fx;
  }
  inv_fy = 1.0f / fy;
}

std::array<Eigen::Vector3f, 4> CameraRays::PyramidPlanes(double u0, double v0, double u1,
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

bool CameraRays::SphereInView(const Eigen::Vector3d& centre_C, double radius) const {
  if (centre_C.z() + radius <= 1e-3) return false;
  for (const Eigen::Vector3d& n : image_planes_unit) {
    if (n.dot(centre_C) < -radius) return false;
  }
  return true;
}

PixelRect CameraRays::Bound(const RenderPart& part, const Eigen::Isometry3d& X_MC) const {
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
  if (all_behind) return {};
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
  if (!visible_in(image_planes)) return {};  // outside the view
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
  if (bx1 <= bx0) return {};
  PixelRect rect{bx0 * kTile, by0 * kTile, std::min(w, bx1 * kTile), std::min(h, by1 * kTile)};
  if (exact) {
    rect.x0 = std::max(rect.x0, (*exact)[0]);
    rect.y0 = std::max(rect.y0, (*exact)[1]);
    rect.x1 = std::min(rect.x1, (*exact)[2]);
    rect.y1 = std::min(rect.y1, (*exact)[3]);
  }
  return rect;
}

}  // namespace autodrive::vehicle_sim::internal
