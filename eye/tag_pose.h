#pragma once
/// @file
/// The pose of a tag lying flat at a known height (a car's roof tag) from its four corners in
/// one camera's image: its centre (x, y) and yaw in the map frame, with a covariance.

#include <optional>

#include <Eigen/Core>

#include "common/camera/camera_model.h"
#include "eye/detector.h"

namespace autodrive::eye {

/// A horizontal tag's pose in the map frame M.
struct PlanarTagPose {
  Eigen::Vector2d p_M = Eigen::Vector2d::Zero();  ///< the black square's centre, m
  double yaw_rad = 0.0;                           ///< from M's x to the tag frame's x
  /// Covariance of (x, y, yaw), m² and rad², from the corner noise assumed.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  double rms_px = 0.0;  ///< the corners' reprojection residual, RMS, px (undistorted)
};

/// The pose of a tag of side `size_m` lying flat at height `height_m` in M, seen as `detection`
/// by `camera` (whose `X_PC` is its optical frame's pose in M): the corners' rays meet the
/// plane, a rigid fit of the tag's square gives a first pose, and Gauss-Newton on the
/// reprojection error of the four corners refines (x, y, yaw). The covariance is
/// `corner_sigma_px`² (JᵀJ)⁻¹ at the solution. `std::nullopt` when a corner's ray does not
/// meet the plane in front of the camera or lies beyond the lens model.
[[nodiscard]] std::optional<PlanarTagPose> LocateHorizontalTag(const camera::Camera& camera,
                                                               const TagDetection& detection,
                                                               double size_m, double height_m,
                                                               double corner_sigma_px);

}  // namespace autodrive::eye
