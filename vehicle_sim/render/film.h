#pragma once
/// @file
/// The renderer's film (internal to vehicle_sim/renderer.cpp): what happens to the light after
/// the raster has drawn it. Motion blur (the frame averaged over sub-frames spread over the
/// exposure time, the vehicles, the traffic and the camera moved by their velocities), then
/// Gaussian blur, exposure and Gaussian noise (from a block drawn once per camera, offset by
/// each frame's seed, so that a run is reproducible).

#include <chrono>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "vehicle_sim/renderer.h"

namespace autodrive::vehicle_sim::internal {

/// Motion blur's sub-frames: where the moving things are at an offset from the frame's
/// instant, and the average of the sub-frames' pictures. Its buffers are kept from frame to
/// frame. Copyable and movable as a value.
class MotionBlur {
 public:
  /// The offset of sub-frame `s` of `n` from the frame's instant, over an exposure of
  /// `exposure` centred on it.
  [[nodiscard]] static std::chrono::duration<double> Offset(std::chrono::duration<double> exposure,
                                                            int s, int n);
  /// `X` moved rigidly for `dt` at velocity `v` and angular velocity `w` (map frame).
  [[nodiscard]] static Eigen::Isometry3d Shift(const Eigen::Isometry3d& X, const Eigen::Vector3d& v,
                                               const Eigen::Vector3d& w,
                                               std::chrono::duration<double> dt);

  /// Starts a frame of `bytes` bytes whose moving things are `frame`'s.
  void Begin(const FrameState& frame, std::size_t bytes);
  /// `frame` (the one given to `Begin`) at offset `dt`: its vehicles and traffic moved (they
  /// live in this object until the next call).
  [[nodiscard]] FrameState SubFrame(const FrameState& frame, std::chrono::duration<double> dt);
  /// Adds a sub-frame's picture.
  void Add(const std::vector<std::uint8_t>& picture);
  /// The average of the `n` sub-frames added, rounded, into `out` (its size already right).
  void Average(int n, std::vector<std::uint8_t>& out) const;

 private:
  std::vector<std::uint16_t> accumulator_;
  std::vector<RenderVehicle> moved_;
  std::vector<RenderTraffic> moved_traffic_;
};

/// The film of one camera: Gaussian blur, exposure and noise applied to a drawn picture.
/// Immutable once made; copyable and movable as a value.
class Film {
 public:
  /// For pictures of `width_px` x `height_px`.
  Film(const FilmOptions& options, int width_px, int height_px);

  [[nodiscard]] const FilmOptions& options() const { return options_; }
  /// Develops `image` (the camera's size) in place: blur, exposure, then the noise of
  /// `noise_seed`.
  void Develop(Image& image, std::uint64_t noise_seed) const;

 private:
  FilmOptions options_;
  int w_ = 0;
  int h_ = 0;
  cv::Mat noise_;  ///< a block of Gaussian noise (CV_8S), offset at random per frame
};

}  // namespace autodrive::vehicle_sim::internal
