#pragma once
/// @file
/// AprilTag detection in a grey image or in regions of it, with the checks that keep false
/// tags out. Corners are in OpenCV's pixel convention (docs/camera.md): the AprilTag library
/// puts a pixel's centre at +0.5, so 0.5 is subtracted from what it reports.

#include <array>
#include <memory>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "eye/eye_config.h"

namespace autodrive::eye {

/// One tag found in an image.
struct TagDetection {
  int id = 0;
  /// The black square's corners, px, in the order of `TagCorners` (the tag frame's
  /// (-s/2, -s/2), (s/2, -s/2), (s/2, s/2), (-s/2, s/2)).
  std::array<Eigen::Vector2d, 4> corners_px;
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();
  double decision_margin = 0.0;
  int hamming = 0;
};

/// What a detection pass did.
struct DetectionStats {
  int regions = 0;       ///< regions searched (1 for a full frame)
  long long pixels = 0;  ///< pixels searched
  int found = 0;         ///< tags accepted
  int refused = 0;       ///< tags the library found that the checks refused
};

/// The corners of a tag's black square of side `size_m` in its frame T (z = 0), in the order
/// the AprilTag library reports them (`det->p`).
[[nodiscard]] std::array<Eigen::Vector3d, 4> TagCorners(double size_m);

/// An AprilTag 3 detector for one family with its parameters. One per thread: not thread-safe
/// (the library's detector keeps working memory); it runs on the calling thread only.
/// Movable, not copyable.
class TagDetector {
 public:
  /// @throws InputError if the configuration is not valid (unknown family).
  explicit TagDetector(const DetectorConfig& config);
  ~TagDetector();
  TagDetector(TagDetector&&) noexcept;
  TagDetector& operator=(TagDetector&&) noexcept;
  TagDetector(const TagDetector&) = delete;
  TagDetector& operator=(const TagDetector&) = delete;

  /// The tags in `grey` (CV_8UC1, any stride). No copy of the image is made.
  [[nodiscard]] std::vector<TagDetection> Detect(const cv::Mat& grey,
                                                 DetectionStats* stats = nullptr);
  /// The tags in the regions `rois` of `grey` (clipped to it; overlapping regions should have
  /// been merged: a tag seen in two regions is reported twice). Corners in the whole image's
  /// pixels.
  [[nodiscard]] std::vector<TagDetection> Detect(const cv::Mat& grey,
                                                 const std::vector<cv::Rect>& rois,
                                                 DetectionStats* stats = nullptr);

  [[nodiscard]] const DetectorConfig& config() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Merges overlapping (or touching) rectangles into their bounding rectangles until none
/// overlap; the result covers every input.
[[nodiscard]] std::vector<cv::Rect> MergeRects(std::vector<cv::Rect> rects);

}  // namespace autodrive::eye
