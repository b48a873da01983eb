#include "eye/testing/synthetic_scene.h"

#include <apriltag/apriltag.h>

#include <opencv2/imgproc.hpp>

#include "common/camera/tag_family.h"
#include "common/error.h"

namespace autodrive::eye::testing {

Eigen::Isometry3d FlatTagPose(double x, double y, double z, double yaw_rad) {
  return Eigen::Translation3d(x, y, z) * Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ());
}

camera::Camera OverheadCamera(double x, double y, double height_m, double f_px, int width_px,
                              int height_px) {
  camera::Intrinsics k;
  k.width_px = width_px;
  k.height_px = height_px;
  k.fx_px = k.fy_px = f_px;
  k.cx_px = (width_px - 1) / 2.0;
  k.cy_px = (height_px - 1) / 2.0;
  return {"overhead", "overhead", "map", camera::CameraModel(k),
          camera::CameraPoseFromMount({x, y, height_m}, {0.0, kPi / 2, kPi / 2})};
}

cv::Mat DrawScene(const camera::Camera& camera, const std::vector<PlacedTag>& tags) {
  const camera::Intrinsics& in = camera.model.intrinsics();
  AUTODRIVE_CHECK(in.distortion.empty(), "DrawScene draws through a pinhole camera only");
  constexpr int kS = 4;
  cv::Mat big(in.height_px * kS, in.width_px * kS, CV_8UC1, cv::Scalar(150));
  for (const PlacedTag& tag : tags) {
    const camera::TagFamily family(tag.family);
    family.CheckId(tag.id);
    image_u8_t* bits = apriltag_to_image(family.get(), tag.id);
    const int n = bits->width;
    // The bitmap scaled up so that warping it samples well.
    constexpr int kBit = 16;
    cv::Mat bitmap(n * kBit, n * kBit, CV_8UC1);
    for (int r = 0; r < n * kBit; ++r) {
      for (int c = 0; c < n * kBit; ++c) {
        bitmap.at<std::uint8_t>(r, c) = bits->buf[(r / kBit) * bits->stride + c / kBit];
      }
    }
    image_u8_destroy(bits);
    // The whole bitmap's corners in T: the black square is `size_m`, the bitmap n / border of it.
    const double half = tag.size_m * n / family.width_at_border() / 2;
    // Bitmap (column, row) corners: top-left is T's (-half, +half).
    // Outer edges, OpenCV's pixel centres at integers.
    const float e = static_cast<float>(n * kBit) - 0.5f;
    const std::vector<cv::Point2f> from{{-0.5f, -0.5f}, {e, -0.5f}, {e, e}, {-0.5f, e}};
    const std::vector<Eigen::Vector3d> corners{
        {-half, half, 0}, {half, half, 0}, {half, -half, 0}, {-half, -half, 0}};
    std::vector<cv::Point2f> to;
    bool ok = true;
    for (const Eigen::Vector3d& c : corners) {
      const auto px = camera.ProjectFromParent(tag.X_MT * c);
      if (!px) {
        ok = false;
        break;
      }
      // Pixel centres at integers: the big image's pixel (i, j) covers [i, i+1) / kS - 0.5.
      to.emplace_back(static_cast<float>((px->x() + 0.5) * kS - 0.5),
                      static_cast<float>((px->y() + 0.5) * kS - 0.5));
    }
    if (!ok) continue;
    // Warped into the quad's bounding box only.
    const cv::Rect box = cv::boundingRect(to) & cv::Rect(0, 0, big.cols, big.rows);
    if (box.area() == 0) continue;
    for (cv::Point2f& p : to)
      p -= cv::Point2f(static_cast<float>(box.x), static_cast<float>(box.y));
    const cv::Mat H = cv::getPerspectiveTransform(from, to);
    cv::Mat mask(bitmap.size(), CV_8UC1, cv::Scalar(255));
    cv::Mat warped, warped_mask;
    cv::warpPerspective(bitmap, warped, H, box.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT);
    cv::warpPerspective(mask, warped_mask, H, box.size(), cv::INTER_NEAREST, cv::BORDER_CONSTANT);
    cv::Mat target = big(box);
    warped.copyTo(target, warped_mask);
  }
  cv::Mat out;
  cv::resize(big, out, cv::Size(in.width_px, in.height_px), 0, 0, cv::INTER_AREA);
  return out;
}

}  // namespace autodrive::eye::testing
