#include "eye/tag_pose.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>

#include "eye/detector.h"
#include "eye/testing/synthetic_scene.h"

namespace autodrive::eye {
namespace {

using testing::DrawScene;
using testing::FlatTagPose;
using testing::OverheadCamera;

// A detection whose corners are the exact projections of a flat tag's corners.
TagDetection ExactDetection(const camera::Camera& cam, const Eigen::Isometry3d& X_MT, double size) {
  TagDetection d;
  const auto corners = TagCorners(size);
  for (std::size_t k = 0; k < 4; ++k) d.corners_px[k] = *cam.ProjectFromParent(X_MT * corners[k]);
  return d;
}

TEST(TagPose, ExactCornersGiveTheExactPoseWithAndWithoutDistortion) {
  camera::Camera cam = OverheadCamera(2.5, 2.5, 3.0, 626.0, 1920, 1080);
  for (const std::vector<double>& distortion :
       {std::vector<double>{}, std::vector<double>{-0.05, 0.01, 0.001, -0.002, 0.0}}) {
    camera::Intrinsics k = cam.model.intrinsics();
    k.distortion = distortion;
    cam.model = camera::CameraModel(k);
    for (const auto& [x, y, yaw] :
         std::vector<std::array<double, 3>>{{2.5, 2.5, 0.0}, {0.8, 4.3, 2.9}, {4.1, 0.6, -1.2}}) {
      const auto pose = LocateHorizontalTag(
          cam, ExactDetection(cam, FlatTagPose(x, y, 0.257, yaw), 0.0762), 0.0762, 0.257, 0.25);
      ASSERT_TRUE(pose);
      EXPECT_NEAR(pose->p_M.x(), x, 1e-9);
      EXPECT_NEAR(pose->p_M.y(), y, 1e-9);
      EXPECT_NEAR(std::remainder(pose->yaw_rad - yaw, 2 * kPi), 0.0, 1e-9);
      EXPECT_LT(pose->rms_px, 1e-6);
      // A covariance: symmetric, positive, and millimetres for a quarter-pixel corner noise.
      EXPECT_TRUE(pose->covariance.isApprox(pose->covariance.transpose()));
      EXPECT_GT(pose->covariance.determinant(), 0.0);
      EXPECT_LT(std::sqrt(pose->covariance(0, 0)), 0.002);
    }
  }
}

TEST(TagPose, CornerNoiseGivesErrorsTheCovarianceAccountsFor) {
  const camera::Camera cam = OverheadCamera(2.5, 2.5, 3.0, 626.0, 1920, 1080);
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.25);
  double chi2 = 0;
  constexpr int kN = 2000;
  for (int i = 0; i < kN; ++i) {
    const Eigen::Isometry3d X_MT = FlatTagPose(1.0 + 0.001 * i, 2.0, 0.257, 0.3);
    TagDetection d = ExactDetection(cam, X_MT, 0.0762);
    for (auto& c : d.corners_px) c += Eigen::Vector2d(noise(rng), noise(rng));
    const auto pose = LocateHorizontalTag(cam, d, 0.0762, 0.257, 0.25);
    ASSERT_TRUE(pose);
    const Eigen::Vector3d e(pose->p_M.x() - X_MT.translation().x(),
                            pose->p_M.y() - X_MT.translation().y(),
                            std::remainder(pose->yaw_rad - 0.3, 2 * kPi));
    chi2 += e.dot(pose->covariance.inverse() * e);
  }
  // The mean of a chi-squared with 3 degrees of freedom is 3 (the 2000-sample mean's standard
  // deviation is 0.055): the covariance is neither over- nor under-confident.
  std::cout << "[ measured ] mean normalised squared error " << chi2 / kN << " (3 expected)\n";
  EXPECT_NEAR(chi2 / kN, 3.0, 0.3);
}

TEST(TagPose, ATagDrawnAndDetectedIsLocatedWithinAMillimetre) {
  const camera::Camera cam = OverheadCamera(2.5, 2.5, 3.0, 626.0, 1920, 1080);
  const std::vector<testing::PlacedTag> tags{
      {"tag36h11", 1, 0.0762, FlatTagPose(1.2, 3.1, 0.257, 0.4)},
      {"tag36h11", 2, 0.0762, FlatTagPose(3.6, 1.7, 0.257, -2.0)}};
  const cv::Mat image = DrawScene(cam, tags);
  TagDetector detector(DetectorConfig{});
  const auto found = detector.Detect(image);
  ASSERT_EQ(found.size(), 2u);
  for (const TagDetection& d : found) {
    const auto& truth = tags[static_cast<std::size_t>(d.id - 1)].X_MT;
    const auto pose = LocateHorizontalTag(cam, d, 0.0762, 0.257, 0.25);
    ASSERT_TRUE(pose);
    const double yaw = std::atan2(truth.linear()(1, 0), truth.linear()(0, 0));
    std::cout << "[ measured ] tag " << d.id << ": position error "
              << (pose->p_M - truth.translation().head<2>()).norm() * 1e3 << " mm, yaw error "
              << std::remainder(pose->yaw_rad - yaw, 2 * kPi) * 180 / kPi << " deg, residual "
              << pose->rms_px << " px\n";
    EXPECT_LT((pose->p_M - truth.translation().head<2>()).norm(), 0.001);
    EXPECT_LT(std::abs(std::remainder(pose->yaw_rad - yaw, 2 * kPi)), 0.5 * kPi / 180);
  }
}

TEST(TagPose, ATagAtAnotherHeightThanConfiguredLeavesAResidual) {
  // What the localiser's geometric check rests on: a tag lying on the floor, read as a roof
  // tag, meets the roof's plane as a smaller square; the corners of the configured square are
  // then pixels off (2.5 px from 2 m up).
  const camera::Camera cam = OverheadCamera(2.5, 2.5, 2.0, 626.0, 1920, 1080);
  const TagDetection floor = ExactDetection(cam, FlatTagPose(2.0, 2.2, 0.0, 0.0), 0.0762);
  const auto right = LocateHorizontalTag(cam, floor, 0.0762, 0.0, 0.25);
  const auto wrong = LocateHorizontalTag(cam, floor, 0.0762, 0.257, 0.25);
  ASSERT_TRUE(right && wrong);
  EXPECT_LT(right->rms_px, 1e-6);
  EXPECT_GT(wrong->rms_px, 1.5);
}

}  // namespace
}  // namespace autodrive::eye
