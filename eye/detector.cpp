#include "eye/detector.h"

#include <apriltag/apriltag.h>

#include <algorithm>
#include <utility>

#include "common/camera/tag_family.h"
#include "common/error.h"

namespace autodrive::eye {

std::array<Eigen::Vector3d, 4> TagCorners(double size_m) {
  const double h = size_m / 2;
  return {Eigen::Vector3d(-h, -h, 0), Eigen::Vector3d(h, -h, 0), Eigen::Vector3d(h, h, 0),
          Eigen::Vector3d(-h, h, 0)};
}

struct TagDetector::Impl {
  DetectorConfig config;
  camera::TagFamily family;
  apriltag_detector_t* detector = nullptr;

  explicit Impl(const DetectorConfig& c) : config(c), family(c.family) {
    config.Validate();
    detector = apriltag_detector_create();
    AUTODRIVE_CHECK(detector != nullptr, "apriltag_detector_create failed");
    apriltag_detector_add_family_bits(detector, family.get(), config.max_hamming);
    detector->nthreads = 1;
    detector->quad_decimate = static_cast<float>(config.decimate);
    detector->quad_sigma = static_cast<float>(config.blur_sigma);
    detector->refine_edges = config.refine_edges;
  }
  ~Impl() {
    if (detector != nullptr) apriltag_detector_destroy(detector);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  // The checks against false positives: margin, bit errors, a convex quad with sides long
  // enough and opposite sides alike.
  [[nodiscard]] bool Accept(const TagDetection& d) const {
    if (d.decision_margin < config.min_decision_margin) return false;
    if (d.hamming > config.max_hamming) return false;
    std::array<double, 4> side{};
    double cross_sign = 0;
    for (std::size_t k = 0; k < 4; ++k) {
      const Eigen::Vector2d e = d.corners_px[(k + 1) % 4] - d.corners_px[k];
      const Eigen::Vector2d f = d.corners_px[(k + 2) % 4] - d.corners_px[(k + 1) % 4];
      side[k] = e.norm();
      const double c = e.x() * f.y() - e.y() * f.x();
      if (k == 0) cross_sign = c;
      if (c == 0 || (c > 0) != (cross_sign > 0)) return false;  // not convex
    }
    if (*std::min_element(side.begin(), side.end()) < config.min_side_px) return false;
    const auto ratio = [](double a, double b) {
      return std::max(a, b) / std::max(1e-9, std::min(a, b));
    };
    return ratio(side[0], side[2]) <= config.max_side_ratio &&
           ratio(side[1], side[3]) <= config.max_side_ratio;
  }

  void DetectIn(const cv::Mat& grey, const cv::Rect& roi, std::vector<TagDetection>& out,
                DetectionStats* stats) {
    const cv::Mat view = grey(roi);
    image_u8_t image{view.cols, view.rows, static_cast<int32_t>(view.step[0]),
                     const_cast<uint8_t*>(view.ptr<uint8_t>(0))};
    zarray_t* found = apriltag_detector_detect(detector, &image);
    for (int i = 0; i < zarray_size(found); ++i) {
      apriltag_detection_t* det = nullptr;
      zarray_get(found, i, &det);
      TagDetection d;
      d.id = det->id;
      d.hamming = det->hamming;
      d.decision_margin = static_cast<double>(det->decision_margin);
      for (std::size_t k = 0; k < 4; ++k) {
        d.corners_px[k] = {det->p[k][0] - 0.5 + roi.x, det->p[k][1] - 0.5 + roi.y};
      }
      d.centre_px = {det->c[0] - 0.5 + roi.x, det->c[1] - 0.5 + roi.y};
      if (Accept(d)) {
        out.push_back(d);
        if (stats != nullptr) ++stats->found;
      } else if (stats != nullptr) {
        ++stats->refused;
      }
    }
    apriltag_detections_destroy(found);
    if (stats != nullptr) {
      ++stats->regions;
      stats->pixels += static_cast<long long>(roi.area());
    }
  }
};

TagDetector::TagDetector(const DetectorConfig& config) : impl_(std::make_unique<Impl>(config)) {}
TagDetector::~TagDetector() = default;
TagDetector::TagDetector(TagDetector&&) noexcept = default;
TagDetector& TagDetector::operator=(TagDetector&&) noexcept = default;

const DetectorConfig& TagDetector::config() const { return impl_->config; }

std::vector<TagDetection> TagDetector::Detect(const cv::Mat& grey, DetectionStats* stats) {
  return Detect(grey, {cv::Rect(0, 0, grey.cols, grey.rows)}, stats);
}

std::vector<TagDetection> TagDetector::Detect(const cv::Mat& grey,
                                              const std::vector<cv::Rect>& rois,
                                              DetectionStats* stats) {
  AUTODRIVE_THROW_UNLESS(
      grey.type() == CV_8UC1,
      "TagDetector: the image must be 8-bit grey (CV_8UC1), got type " << grey.type());
  std::vector<TagDetection> out;
  const cv::Rect whole(0, 0, grey.cols, grey.rows);
  for (const cv::Rect& r : rois) {
    const cv::Rect roi = r & whole;
    // The library needs a few pixels around a quad; tiny regions hold no tag.
    if (roi.width < 8 || roi.height < 8) continue;
    impl_->DetectIn(grey, roi, out, stats);
  }
  return out;
}

std::vector<cv::Rect> MergeRects(std::vector<cv::Rect> rects) {
  bool merged = true;
  while (merged) {
    merged = false;
    for (std::size_t i = 0; i < rects.size() && !merged; ++i) {
      for (std::size_t j = i + 1; j < rects.size(); ++j) {
        const cv::Rect& a = rects[i];
        const cv::Rect& b = rects[j];
        const bool touch = a.x <= b.x + b.width && b.x <= a.x + a.width && a.y <= b.y + b.height &&
                           b.y <= a.y + a.height;
        if (touch) {
          rects[i] = a | b;
          rects.erase(rects.begin() + static_cast<std::ptrdiff_t>(j));
          merged = true;
          break;
        }
      }
    }
  }
  return rects;
}

}  // namespace autodrive::eye
