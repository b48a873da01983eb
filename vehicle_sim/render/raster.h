#pragma once
/// @file
/// The renderer's raster core (internal to vehicle_sim/renderer.cpp): one camera's rays tested
/// against the scene. The ground first (the flat ground by a sampler of ground.h, then the
/// raised and sloping tiles; kept while the camera does not move), then the solid parts, each
/// within its pixel rectangle, nearest first by a depth buffer. Lighting is the faces' shade
/// relative to the ground's; everything after (exposure, blur, noise) is the film's (film.h).

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "vehicle_sim/render/camera_rays.h"
#include "vehicle_sim/render/ground.h"
#include "vehicle_sim/render/scene.h"

namespace autodrive::vehicle_sim::internal {

/// The light (ambient plus one directional light) as the raster shades faces with it.
struct Light {
  explicit Light(const FilmOptions& film);
  /// The shade of a face of outward normal `n` (map frame) relative to the ground's.
  [[nodiscard]] float Shade(const Eigen::Vector3d& n) const;

  Eigen::Vector3d direction;  ///< towards the light, unit
  double ambient = 0.6;
  double intensity = 0.4;
  double ground_shade = 1.0;  ///< the ground's (which the map's picture shows as is)
};

/// A part as one frame's camera sees it: the camera's rays map into the part's frame by Q,
/// the camera's centre is at o.
struct FramePart {
  const RenderPart* part = nullptr;
  Eigen::Matrix3f Q;
  Eigen::Vector3f o;
  std::array<float, 6> shade{};  ///< faces +x, -x, +y, -y, +z, -z
  PixelRect rect;                ///< where its rays are tested
};

/// Draws one camera's frames of one static scene. Holds the camera's rays and its buffers; one
/// thread at a time. Neither copied nor moved (it keeps pointers to the scene and its buffers).
class Raster {
 public:
  /// `scene` must outlive this. @throws InputError when the intrinsics are invalid.
  Raster(const StaticScene& scene, const camera::Intrinsics& intrinsics, const FilmOptions& film);
  Raster(const Raster&) = delete;
  Raster& operator=(const Raster&) = delete;

  [[nodiscard]] const CameraRays& rays() const { return rays_; }

  /// Draws the ground seen from `X_MC` into `target` (rgb, the camera's size): reused as it
  /// was when the last frame's pose is this one's and its ground was kept.
  void DrawGround(const Eigen::Isometry3d& X_MC, std::uint8_t* target);
  /// Draws the static parts and `frame`'s over the ground drawn into `target` by
  /// `DrawGround`. Adds to `stats`' parts_drawn and pixels_tested.
  void DrawParts(const Eigen::Isometry3d& X_MC, const FrameScene& frame, std::uint8_t* target,
                 RenderStats& stats);

 private:
  /// Sets the part's shade and rectangle; false when it has no pixels.
  bool Prepare(FramePart& fp, const Eigen::Isometry3d& X_MC) const;
  void DrawTerrain(const Eigen::Isometry3d& X_MC);
  void DrawPart(const FramePart& fp, float* depth_buffer);
  void DrawPixel(const FramePart& fp, int u, int v, const Eigen::Vector3f& r,
                 const Eigen::Vector3f& d, float* depth_buffer);
  [[nodiscard]] Rgb TagColour(const FramePart& fp, int u, int v, const Eigen::Vector3f& r) const;
  [[nodiscard]] Rgb SampleGround(float x, float y, float area_texels) const;

  const StaticScene* scene_;
  Light light_;
  CameraRays rays_;
  GroundRemap remap_;
  std::vector<float> depth_;  ///< range of the nearest part, valid inside the parts' rectangles
  /// The range of the raised and sloping ground, infinity where there is none (drawn with the
  /// ground, and kept with it while a camera does not move); parts start from it.
  std::vector<float> ground_depth_;
  std::vector<PixelRect> terrain_rects_;  ///< where ground_depth_ is not infinite
  std::vector<FramePart> frame_parts_;
  // The ground of a camera that does not move is drawn once: when a frame's pose is the last
  // frame's, the ground is kept and reused while the pose stays.
  Eigen::Matrix4d last_pose_ = Eigen::Matrix4d::Zero();
  bool cache_valid_ = false;
  std::vector<std::uint8_t> cached_colour_;
  // This pass's: where it draws (rgb, w x h) and the lamps lit.
  std::uint8_t* target_ = nullptr;
  const std::vector<std::uint8_t>* lamp_state_ = nullptr;
};

}  // namespace autodrive::vehicle_sim::internal
