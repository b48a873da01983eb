#pragma once
/// @file
/// For the Eye's tests on data sets that `autodrive-sim render` writes (docs/camera.md,
/// "Offline data sets"): their ground truth, their camera and the poses `autodrive-eye
/// localize` wrote, read from the files alone, and whether a car's roof tag is wholly in view.

#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "common/camera/camera_model.h"
#include "common/camera/roof_tag.h"

namespace autodrive::eye::testing {

/// A car in a frame as the CSV files give it: the centre of its roof tag and its heading.
struct RowPose {
  double x_m = 0.0;
  double y_m = 0.0;
  double yaw_rad = 0.0;
};

/// (frame, vehicle name).
using RowKey = std::pair<int, std::string>;

/// The rows of the CSV file at `path` after its header, each split at its commas; a test
/// failure when the header is not `header`.
[[nodiscard]] std::vector<std::vector<std::string>> ReadCsv(const std::filesystem::path& path,
                                                            const std::string& header);

/// The data set's `ground_truth.csv` (frame,stamp_s,vehicle,tag_id,x_m,y_m,yaw_rad).
[[nodiscard]] std::map<RowKey, RowPose> ReadGroundTruth(const std::filesystem::path& data_set);

/// The poses `autodrive-eye localize` wrote (frame,stamp_s,vehicle,tag_id,x_m,y_m,yaw_rad,
/// camera); the cameras of each row in `cameras` when given.
[[nodiscard]] std::map<RowKey, RowPose> ReadLocalizedPoses(
    const std::filesystem::path& csv, std::map<RowKey, std::string>* cameras = nullptr);

/// The data set's camera: `camera.yaml` (intrinsics) and `camera_pose.yaml`
/// (`X_parent_optical`).
[[nodiscard]] camera::Camera LoadDataSetCamera(const std::filesystem::path& data_set);

/// Whether the whole plate of the roof tag of a car at `car` (its tag's centre and its
/// heading), mounted as `mount` says, lies at least 5 px inside the camera's image (tag36h11:
/// the plate is 10/8 of the tag's side).
[[nodiscard]] bool TagFullyVisible(const camera::Camera& cam, const RowPose& car,
                                   const camera::RoofTagMount& mount = {},
                                   double tag_size_m = 0.0762, double tag_height_m = 0.257);

/// Poses compared with the ground truth.
struct Comparison {
  int compared = 0;  ///< rows of both
  double rms_position_m = 0.0, max_position_m = 0.0;
  double rms_heading_rad = 0.0, max_heading_rad = 0.0;
  int false_rows = 0;  ///< poses of a car in a frame the truth does not have
  /// Per car: the frames where its tag was wholly in view of a camera, and of those the frames
  /// it was localised in.
  std::map<std::string, std::pair<int, int>> localised_of_visible;
};

/// Compares `estimate` with `truth`, row by row; a car's tag is in view when it is wholly in
/// one of `cameras`' images, mounted as `mounts` says (by the car's name; the default mounting
/// for a car not in it).
[[nodiscard]] Comparison CompareWithTruth(
    const std::map<RowKey, RowPose>& truth, const std::map<RowKey, RowPose>& estimate,
    const std::vector<camera::Camera>& cameras,
    const std::map<std::string, camera::RoofTagMount>& mounts = {});

}  // namespace autodrive::eye::testing
