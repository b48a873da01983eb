#pragma once
/// @file
/// A camera's pose in the map from the reference tags fixed on the ground (PnP over all their
/// corners, refined), the check that it has not moved since, and the pose file.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "common/camera/camera_model.h"
#include "eye/detector.h"
#include "eye/eye_config.h"

namespace autodrive::eye {

/// A camera's registration to the map.
struct Registration {
  Eigen::Isometry3d X_MC = Eigen::Isometry3d::Identity();  ///< its optical frame C in M
  double rms_px = 0.0;       ///< reference-tag corners reprojected, RMS
  double max_px = 0.0;       ///< ... their largest error
  std::vector<int> tag_ids;  ///< the reference tags used
  int frames = 0;            ///< frames whose corners were averaged
};

/// The corners of the reference tags in `frames` (the detections of each frame of a camera
/// that did not move), averaged per tag over the frames that saw it, matched to the tags' map
/// corners and solved for the camera's pose (OpenCV's SQPnP, then Levenberg-Marquardt on the
/// reprojection error, with the lens' distortion). Tags not in `references` are ignored.
/// `std::nullopt`, with the reason in `why`, when fewer than 2 reference tags were seen or the
/// solution reprojects worse than `max_rms_px`.
[[nodiscard]] std::optional<Registration> RegisterCamera(
    const camera::CameraModel& model, const std::vector<std::vector<TagDetection>>& frames,
    const std::vector<ReferenceTagConfig>& references, double max_rms_px, std::string* why);

/// The reference tags' corners in `detections` reprojected through `camera` (pose in M): the
/// median error, px; `std::nullopt` when no reference tag was seen.
[[nodiscard]] std::optional<double> ReferenceReprojectionError(
    const camera::Camera& camera, const std::vector<TagDetection>& detections,
    const std::vector<ReferenceTagConfig>& references);

/// Watches a registered camera: after `moved_after_checks` checks in a row whose reference
/// tags reproject worse than the threshold, the camera has moved. A check without reference
/// tags neither counts nor resets. Copyable.
class MoveDetector {
 public:
  explicit MoveDetector(const RegistrationConfig& config) : config_(config) {}
  /// Feeds one check (a median error, px). True exactly once: at the check that makes it
  /// moved; then false until `Reset`.
  bool Check(double median_error_px);
  [[nodiscard]] bool moved() const { return moved_; }
  void Reset();

 private:
  RegistrationConfig config_;
  int bad_in_a_row_ = 0;
  bool moved_ = false;
};

/// Writes `registration` of camera `name` (frame `frame_id`) to `path` as YAML: `camera`,
/// `frame_id`, `parent_frame: map`, `X_parent_optical` (4 x 4, row by row), `rms_px`,
/// `tag_ids`. The simulator's data sets write `camera_pose.yaml` in the same layout.
/// @throws InputError if the file cannot be written.
void SavePose(const std::filesystem::path& path, const std::string& name,
              const std::string& frame_id, const Registration& registration);

/// Reads `X_parent_optical` from a pose file (`SavePose`'s or a data set's `camera_pose.yaml`);
/// `parent_frame` must be `map`. Other keys are ignored.
/// @throws ConfigError naming the file and what was wrong.
[[nodiscard]] Eigen::Isometry3d LoadPose(const std::filesystem::path& path);

}  // namespace autodrive::eye
