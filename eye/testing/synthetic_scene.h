#pragma once
/// @file
/// For the Eye's tests: a scene of AprilTags seen by a pinhole camera, drawn here independently
/// of the simulator's renderer. Each tag's bitmap (the AprilTag library's, white border
/// included) is warped by the homography of its corners into a 4x larger image on a grey
/// floor, which is then averaged down, so edges fall within a small fraction of a pixel.

#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "common/camera/camera_model.h"

namespace autodrive::eye::testing {

/// A tag placed in the map: its family, id, black-square side and pose (its frame T in M).
struct PlacedTag {
  std::string family = "tag36h11";
  int id = 0;
  double size_m = 0.0762;
  Eigen::Isometry3d X_MT = Eigen::Isometry3d::Identity();
};

/// The pose of a flat tag at (x, y, z) with yaw `yaw_rad` (T's x from M's x).
[[nodiscard]] Eigen::Isometry3d FlatTagPose(double x, double y, double z, double yaw_rad);

/// A camera over the map looking straight down from `height_m` above (x, y), the image's top
/// to the north, with fx = fy = `f_px`, the principal point in the middle and no distortion.
[[nodiscard]] camera::Camera OverheadCamera(double x, double y, double height_m, double f_px,
                                            int width_px, int height_px);

/// The grey image `camera` sees of `tags` (CV_8UC1, floor 150). The camera must have no
/// distortion.
[[nodiscard]] cv::Mat DrawScene(const camera::Camera& camera, const std::vector<PlacedTag>& tags);

}  // namespace autodrive::eye::testing
